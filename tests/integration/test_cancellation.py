"""Cancelled calls and timeouts cost only the call itself: a call cancelled mid-reply leaves
every other call its own reply (its reply is discarded), one cancelled before its line is
written sends nothing, one that times out while the robot is busy lets the next call get its own
reply; and a timeout that is no timeout (not a number, negative, NaN, a bool) is refused before
anything is written.
"""

from __future__ import annotations

import asyncio
import math
from typing import Any

import pytest
from waiting import wait_until

from mirobot_async import (
    Mirobot,
    MirobotCommandError,
    MirobotTimeoutError,
    MirobotUsageError,
)
from mirobot_async.testing import WireSpy

pytestmark = [pytest.mark.timeout(60), pytest.mark.usefixtures("no_leftover_tasks")]


@pytest.mark.mirobot_emulator(time_scale=1)
async def test_cancelling_one_call_mid_reply_leaves_the_others_their_replies(
    ready_arm: Mirobot, profile: str
) -> None:
    arm = ready_arm
    slow = asyncio.create_task(arm.send("G4 P0.4"))  # its ok comes after the dwell
    m20 = asyncio.create_task(arm.send("M20"))
    bad = asyncio.create_task(arm.send("M99", validate=False))
    m50 = asyncio.create_task(arm.send("M50"))
    await wait_until(lambda: arm.pending_count == 4, 10, "4 calls pending")
    slow.cancel()
    with pytest.raises(asyncio.CancelledError):
        await slow
    info = {"classic": "", "2021": "Info, ", "2024": "Info,"}[profile]
    assert await m20 == (() if profile == "classic" else (f"{info}M20: Cartesian mode start.",))
    with pytest.raises(MirobotCommandError, match="Unsupported command"):
        await bad
    assert await m50 == (f"{info}M50: Unlock each axis.",)
    assert arm.stats.replies_discarded == 1
    assert arm.pending_count == 0
    assert (await arm.status()).motion_mode == 1


@pytest.mark.mirobot_emulator(time_scale=1)
async def test_cancelling_a_call_before_its_line_is_written_sends_nothing(
    ready_arm: Mirobot,
) -> None:
    arm = ready_arm
    dwell = asyncio.create_task(arm.send("G4 P0.3"))
    settings = asyncio.create_task(arm.send("$$"))  # waits: "$" lines need an idle link
    await wait_until(lambda: arm.pending_count == 1, 10, "one call pending")
    sent = arm.stats.lines_sent
    settings.cancel()
    with pytest.raises(asyncio.CancelledError):
        await settings
    assert await dwell == ()
    assert arm.stats.lines_sent == sent
    assert arm.stats.replies_discarded == 0


@pytest.mark.mirobot_emulator(time_scale=1)
async def test_timeout_while_busy_then_the_reply_is_discarded(ready_arm: Mirobot) -> None:
    arm = ready_arm
    with pytest.raises(MirobotTimeoutError) as info:
        await arm.send("G4 P0.5", timeout=0.1)
    assert info.value.command == "G4 P0.5"
    assert info.value.timeout == 0.1
    assert await arm.send("M3 S4") == ()  # queued behind the dwell, gets its own ok
    assert arm.stats.replies_discarded == 1


BAD_TIMEOUTS: list[Any] = ["x", -1, math.nan, -math.inf, True]


@pytest.mark.parametrize("bad", BAD_TIMEOUTS, ids=repr)
async def test_bad_timeouts_are_refused_before_anything_is_written(
    ready_arm: Mirobot, wire_spy: WireSpy, bad: Any
) -> None:
    arm = ready_arm
    mark = wire_spy.mark()
    for call in (arm.hold, arm.resume, arm.reset, arm.status, arm.wait_idle, arm.settings):
        with pytest.raises(MirobotUsageError, match="timeout"):
            await call(timeout=bad)
    with pytest.raises(MirobotUsageError, match="timeout"):
        await arm.send("M3 S0", timeout=bad)
    with pytest.raises(MirobotUsageError, match="timeout"):
        await arm.stream(["M3 S0"], timeout=bad)
    with pytest.raises(MirobotUsageError, match="timeout"):
        await anext(aiter(arm.statuses(timeout=bad)))
    assert wire_spy.since(mark) == []
    assert (await arm.status()).state is not None  # still usable
