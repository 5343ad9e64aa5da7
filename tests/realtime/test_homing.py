"""Homing at the arm's own speed (emulator ``--time-scale 1``, both profiles): the firmware
answers no ``?`` during its switch search (8-10 s for ``$H``, 29 s for the classic ``$HH``), and
every surface of the client waits through it (ARCHITECTURE.md, "Timeouts and liveness")."""

from __future__ import annotations

import asyncio
import contextlib
import time

import pytest
from waiting import wait_until

from mirobot_async import (
    Mirobot,
    MirobotLinkLostError,
    MirobotResetError,
    MirobotTimeoutError,
    State,
    StatusReport,
)
from mirobot_async.testing import EmulatorProcess

SEARCH = {"2021": 10.0, "classic": 8.15}
"""The emulator's homing search (seconds): the time the firmware answers nothing."""


def at_zero(report: StatusReport) -> bool:
    return report.state is State.IDLE and all(abs(j) < 0.05 for j in report.joints)


async def homing_started(arm: Mirobot) -> None:
    """Returns once the client has written the homing line (it is silent from then on)."""
    await wait_until(lambda: arm.homing is not None, 30, "the homing line written")


async def test_home_waits_through_the_silent_search(arm: Mirobot, profile: str) -> None:
    if profile == "2024":
        pytest.skip(
            "the 2024 family answers '?' during the search (its Home reports: "
            "tests/integration/test_newer_dialect.py)"
        )
    started = time.monotonic()
    report = await arm.home()
    assert at_zero(report), report
    assert time.monotonic() - started >= SEARCH[profile]  # it really ran at the arm's speed
    assert arm.homing is None
    assert (await arm.status(fresh=True)).state is State.IDLE
    await arm.move_joints(j1=10, speed=2000)  # the arm works right after
    assert abs((await arm.status()).joints[0] - 10) < 0.05


@pytest.mark.timeout(150)
@pytest.mark.parametrize("profile", ["classic"])
async def test_sequential_home_waits_29_seconds_on_classic(arm: Mirobot, profile: str) -> None:
    started = time.monotonic()
    report = await arm.home(sequential=True)
    assert at_zero(report), report
    assert time.monotonic() - started >= 29.0


async def test_send_home_line_waits_for_its_reply(arm: Mirobot, profile: str) -> None:
    output = await arm.send("$H")
    assert any("hom" in line for line in output), output  # "in homeing moving..." (sic)
    assert at_zero(await arm.wait_idle())


async def test_a_home_line_with_a_comment_waits_like_the_bare_one(
    arm: Mirobot, profile: str
) -> None:
    # The firmware drops the comment: "(x)$H" homes as "$H" does, silent through the search,
    # so the call waits for its reply instead of taking the silence for a dead link.
    output = await arm.send("(x)$H")
    assert any("hom" in line for line in output), output
    assert at_zero(await arm.wait_idle())


async def test_streamed_home_then_a_move(arm: Mirobot, profile: str) -> None:
    result = await arm.stream(["$H", "M21 G90 G0 X10 F2000"], wait=True)
    assert result.ok, result
    report = await arm.status(fresh=True)
    assert report.state is State.IDLE and abs(report.joints[0] - 10) < 0.05, report


async def test_status_during_homing_names_homing_or_waits(arm: Mirobot, profile: str) -> None:
    if profile == "2024":
        pytest.skip(
            "the 2024 family answers '?' during the search (its Home reports: "
            "tests/integration/test_newer_dialect.py)"
        )
    homing = asyncio.create_task(arm.home())
    try:
        await homing_started(arm)
        with pytest.raises(MirobotTimeoutError, match="homing"):
            await arm.status()  # 2 s: the search lasts longer
        report = await arm.status(timeout=60)  # the report printed when the search ends
        assert report.state in (State.HOME, State.RUN, State.IDLE), report
        assert at_zero(await homing)
    finally:
        homing.cancel()
        with contextlib.suppress(BaseException):
            await homing


async def test_a_statuses_consumer_survives_homing(arm: Mirobot, profile: str) -> None:
    states: list[State] = []
    after_homing = asyncio.Event()

    async def consume() -> None:
        async with contextlib.aclosing(arm.statuses(interval=0.1)) as reports:
            async for report in reports:
                states.append(report.state)
                if after_homing.is_set() and report.state is State.IDLE:
                    return

    consumer = asyncio.create_task(consume())
    try:
        await asyncio.sleep(0)  # one loop turn: the consumer has started
        assert at_zero(await arm.home())
        after_homing.set()
        async with asyncio.timeout(30):
            await consumer  # it never raised: it paused through the search
    finally:
        consumer.cancel()
        with contextlib.suppress(BaseException):
            await consumer
    assert State.HOME in states, states  # the report printed when the search ended


async def test_a_link_that_dies_while_homing_fails_at_once(
    arm: Mirobot, emu: EmulatorProcess, profile: str
) -> None:
    homing = asyncio.create_task(arm.home())
    await homing_started(arm)
    await asyncio.sleep(1.0)  # well into the silent search
    emu.kill()
    async with asyncio.timeout(20):  # far less than the homing bound (45 s)
        with pytest.raises(MirobotLinkLostError):
            await homing


async def test_a_silent_link_past_the_homing_bound_names_homing(arm: Mirobot, profile: str) -> None:
    if profile == "2024":
        pytest.skip(
            "the 2024 family answers '?' during the search (its Home reports: "
            "tests/integration/test_newer_dialect.py)"
        )
    arm.homing_bounds["$H"] = 3.0  # shorter than the search: the silence outlasts it
    with pytest.raises(MirobotTimeoutError, match="homing") as raised:
        await arm.home()
    assert "'$H'" in str(raised.value)


async def test_reset_while_homing_fails_home_at_once(arm: Mirobot, profile: str) -> None:
    homing = asyncio.create_task(arm.home())
    try:
        await homing_started(arm)
        banner = await arm.reset()  # "%" is the one thing the firmware reads while homing
        assert banner
        assert arm.homing is None
        with pytest.raises(MirobotResetError):
            await homing
    finally:
        homing.cancel()
        with contextlib.suppress(BaseException):
            await homing
    assert (await arm.status()).state in (State.ALARM, State.IDLE)  # answering again at once


@pytest.mark.timeout(150)
@pytest.mark.parametrize("profile", ["classic"])
async def test_send_sequential_home_gets_the_homing_timeout(arm: Mirobot, profile: str) -> None:
    """``$HH`` answers after 29 s of silence: send()'s default gives it HOME_TIMEOUT."""
    await arm.send("$HH")
    assert at_zero(await arm.wait_idle())
