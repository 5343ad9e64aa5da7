"""``stream(wait=True)``: the stream ends when the arm has stopped (a ``G4 P0`` barrier), against
the real emulator process over its pty."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Awaitable, Callable

import pytest

from mirobot_async import Mirobot, MirobotAlarmError, MirobotResetError, State
from mirobot_async.testing import EmulatorProcess, WireSpy

pytestmark = [pytest.mark.timeout(60), pytest.mark.usefixtures("no_leftover_tasks")]

MOVES = ["M21 G90 G1 X20 Y0 Z0 A0 B0 C0 F2000", "M21 G90 G1 X10 Y5 Z0 A0 B0 C0 F2000"]
"""Two joint moves, about 1.2 s of motion at real time (0.3 s at the tests' time scale 4)."""


async def motion_ends(emu: EmulatorProcess) -> list[float]:
    """The emulator's last ends of motion (``time.monotonic()`` instants)."""
    words = (await emu.control("motion-ends")).split()
    return [float(word) for word in words[2:]]


@pytest.mark.mirobot_emulator(time_scale=4)
@pytest.mark.emulator_process
async def test_stream_wait_returns_once_the_arm_has_stopped_at_the_last_line(
    emu: EmulatorProcess, ready_arm: Mirobot, wire_spy: WireSpy
) -> None:
    arm = ready_arm
    mark = len(wire_spy.writes)
    before = await motion_ends(emu)
    result = await arm.stream(MOVES, wait=True)
    returned = time.monotonic()
    assert result.ok and result.sent == result.acknowledged == len(MOVES)
    ends = [t for t in await motion_ends(emu) if t not in before]
    assert ends and ends[-1] <= returned  # the arm had stopped when the stream returned
    report = await arm.status()
    assert report.state is State.IDLE
    assert report.joints[:2] == pytest.approx((10.0, 5.0), abs=0.05)
    assert wire_spy.lines(mark)[-1] == b"G4 P0\n"  # the barrier, written after the last line


@pytest.mark.mirobot_emulator(time_scale=1)  # 1.2 s of motion: a loaded machine cannot miss it
async def test_stream_without_wait_returns_while_the_arm_still_moves(
    ready_arm: Mirobot, wire_spy: WireSpy
) -> None:
    """The control case of the test above: the replies come as the lines enter the planner."""
    arm = ready_arm
    mark = len(wire_spy.writes)
    result = await arm.stream(MOVES)
    assert result.ok
    assert (await arm.status()).state is State.RUN
    assert b"G4 P0\n" not in wire_spy.lines(mark)
    # (not waited for: the arm is closed moving, as a renewed or new emulator starts at rest)


async def test_stream_wait_after_a_failed_line_returns_its_result_and_stays_in_step(
    ready_arm: Mirobot,
) -> None:
    """A failed line ends the stream without waiting for the motion; a barrier already
    written (the lines are pipelined) is answered later and that reply is not misplaced."""
    arm = ready_arm
    # The firmware refuses an unreachable pose (the envelope is off by default).
    lines = ["M21 G90 G1 X5 F2000", "M20 G90 G0 X900 Y0 Z100 A0 B0 C0", "M21 G90 X0 Y0 Z0 A0 B0 C0"]
    result = await arm.stream(lines, wait=True)
    assert not result.ok and [r.number for r in result.errors] == [2]
    await arm.wait_idle()
    assert arm.pending_count == 0
    assert await arm.send("M3 S500") == ()
    assert (await arm.status()).pump_pwm == 500


async def test_stream_wait_continues_past_errors_when_asked_and_then_waits(
    ready_arm: Mirobot, wire_spy: WireSpy
) -> None:
    arm = ready_arm
    mark = len(wire_spy.writes)
    lines = ["M20 G90 G1 X900 Y0 Z100 A0 B0 C0 F2000", "M21 G90 G1 X5 Y0 Z0 A0 B0 C0 F2000"]
    result = await arm.stream(lines, wait=True, continue_on_error=True)
    assert [r.number for r in result.errors] == [1] and result.acknowledged == 1
    assert wire_spy.lines(mark)[-1] == b"G4 P0\n"
    report = await arm.status()
    assert report.state is State.IDLE and report.joints[0] == pytest.approx(5.0, abs=0.05)


# The vendor's firmware differs with some host timings: a % during motion makes it print
# 'ALARM: Abort during cycle' before its banner (and the dwell's ok after it), so on a loaded host
# the stream's G4 P0 failed with MirobotAlarmError there, not MirobotResetError.
@pytest.mark.mirobot_emulator(time_scale=1)
async def test_a_reset_while_a_stream_waits_for_the_motion_fails_it(
    ready_arm: Mirobot, first_status: Callable[..., Awaitable[None]]
) -> None:
    arm = ready_arm
    stream = asyncio.create_task(arm.stream(["M21 G90 G1 X60 F300"], wait=True).run())
    try:
        await first_status(arm, State.RUN, limit=10.0)
        assert not stream.done()
        await arm.reset()
        with pytest.raises(MirobotResetError):
            await asyncio.wait_for(stream, 5.0)
    finally:
        stream.cancel()
        with contextlib.suppress(BaseException):
            await stream
    assert arm.pending_count == 0


@pytest.mark.mirobot_emulator(time_scale=1)
@pytest.mark.emulator_process
async def test_a_hard_limit_while_a_stream_waits_for_the_motion_fails_it_at_once(
    emu: EmulatorProcess, ready_arm: Mirobot, first_status: Callable[..., Awaitable[None]]
) -> None:
    arm = ready_arm
    stream = asyncio.create_task(arm.stream(["M21 G90 G1 X60 F300"], wait=True).run())
    try:
        await first_status(arm, State.RUN, limit=10.0)
        await emu.control("hard-limit")
        with pytest.raises(MirobotAlarmError, match="Hard limit"):
            await asyncio.wait_for(stream, 3.0)
    finally:
        stream.cancel()
        with contextlib.suppress(BaseException):
            await stream
    await arm.reset()
