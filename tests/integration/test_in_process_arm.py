"""The in-process virtual arm: the client over the pure firmware model, no pty, no subprocess."""

from __future__ import annotations

import asyncio
import time

import pytest

from mirobot_async import Mirobot
from mirobot_async._core.replies import State
from mirobot_async.errors import (
    MirobotConnectionError,
    MirobotError,
    MirobotUsageError,
    MotionRefusedError,
)
from mirobot_async.testing import InProcessArm, start_emulator

PROFILES = ("2021", "classic", "2024")


@pytest.mark.parametrize("firmware", PROFILES)
async def test_home_move_and_stream_at_time_scale_0(firmware: str) -> None:
    async with (
        start_emulator(firmware=firmware, time_scale=0, in_process=True) as url,
        Mirobot.connect(url) as arm,
    ):
        assert url.startswith("virtual://")
        await arm.home()
        await arm.move_joints(j1=30)
        assert (await arm.status()).joints[0] == pytest.approx(30, abs=0.02)
        lines = ["M21 G90 G0 X0 F2000"] + [f"G0 X{i % 20}" for i in range(1, 100)]
        result = await arm.stream(lines, wait=True)
        assert result.ok, result
        status = await arm.status()
        assert status.state is State.IDLE
        assert status.joints[0] == pytest.approx(99 % 20, abs=0.02)


async def test_locked_at_power_on_like_the_process() -> None:
    async with (
        start_emulator(firmware="classic", time_scale=0, in_process=True) as url,
        Mirobot.connect(url) as arm,
    ):
        with pytest.raises(MotionRefusedError, match="Locked"):
            await arm.move_joints(j1=10)


async def test_real_time_motion_takes_the_arms_time() -> None:
    """At time scale 1 a 2-degree J1 move at F2000 lasts what it lasts on the arm (lower
    bound only: a loaded machine may make it longer, never shorter)."""
    arm_model = InProcessArm("classic", time_scale=1)
    with arm_model:
        async with Mirobot.connect(arm_model.url) as arm:
            await arm.send("M50")
            started = time.monotonic()
            await arm.move_joints(j1=2, speed=2000)
            elapsed = time.monotonic() - started
            assert (await arm.status()).joints[0] == pytest.approx(2, abs=0.02)
    # 2 * sqrt(2 / 50) = 0.4 s of motion on the model (accelerating at 50 deg/s^2, never
    # reaching F2000); never instant at real time
    assert elapsed >= 0.2


async def test_one_client_at_a_time_and_state_survives_reconnect() -> None:
    with InProcessArm("2021", time_scale=0) as model:
        async with Mirobot.connect(model.url) as arm:
            await arm.home()
            await arm.move_joints(j1=20)
            with pytest.raises(MirobotConnectionError, match="busy"):
                await Mirobot.connect(model.url)
        async with Mirobot.connect(model.url) as again:  # the cable plugged in again
            assert (await again.status()).joints[0] == pytest.approx(20, abs=0.02)
        assert model.joints[0] == pytest.approx(20, abs=0.02)


async def test_closing_the_arm_fails_the_pending_call_promptly() -> None:
    model = InProcessArm("classic", time_scale=1)
    model.open()
    arm = await Mirobot.connect(model.url)
    try:
        await arm.send("M50")
        await arm.move_joints(j1=60, speed=200, wait=False)  # accepted: the arm runs ~10 s
        waiting = asyncio.create_task(arm.wait_idle())
        assert model.state == "Run"
        model.close()
        with pytest.raises(MirobotError):
            await asyncio.wait_for(waiting, 5)
    finally:
        await arm.close()


async def test_unknown_or_closed_url_fails_to_connect() -> None:
    model = InProcessArm()
    url = model.open()
    model.close()
    with pytest.raises(MirobotConnectionError, match="no virtual Mirobot"):
        await Mirobot.connect(url, timeout=1)


async def test_process_options_are_refused_in_process() -> None:
    with pytest.raises(MirobotUsageError, match="in_process"):
        async with start_emulator(in_process=True, extra_args=("--baud", "115200")):
            pass
    with pytest.raises(MirobotUsageError):
        InProcessArm("2019")
    with pytest.raises(MirobotUsageError):
        InProcessArm(time_scale=-1)


@pytest.mark.mirobot_emulator(firmware="classic", time_scale=0)
async def test_the_plugin_fixture_lends_an_in_process_arm(mirobot_virtual_arm: str) -> None:
    """As a user's own test would: the plugin's fixture, the marker's profile, no process."""
    assert mirobot_virtual_arm.startswith("virtual://")
    async with Mirobot.connect(mirobot_virtual_arm) as arm:
        assert await arm.detect_firmware() == "classic"
        await arm.home()
        lines = ["M21 G90 G21 G0 X0 F2000"] + [f"G0 X{i % 20}" for i in range(1, 100)]
        assert (await arm.stream(lines, wait=True)).ok
        assert (await arm.status()).joints[0] == pytest.approx(19, abs=0.02)


async def test_the_client_asks_for_reports_back_to_back_in_process() -> None:
    """No serial line: the in-process link tells the client that two ``?`` need no gap (a
    report is printed the instant its ``?`` arrives), so a status costs no 2 ms wait; a
    process's pty keeps the serial arm's gap."""
    async with InProcessArm("classic") as virtual, Mirobot.connect(virtual.url) as arm:
        assert arm.status_min_gap == 0
        reports = [await arm.status() for _ in range(20)]
        assert all(report.state is State.IDLE for report in reports)
        assert arm.stats.status_retries == 0
    async with start_emulator(firmware="classic") as url, Mirobot.connect(url) as arm:
        assert arm.status_min_gap == 0.002
