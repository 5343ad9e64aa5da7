"""The client under adversity, driven through the emulator's fault-injection channel.

Dropped ``ok``, corrupted status, ignored ``?``, stalls, hard limits, resets (asked for and
spontaneous), the emulator killed or the port closed mid-stream, cancellation mid-reply.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import logging
import time
from typing import Any

import psutil
import pytest
from waiting import wait_for, wait_until

from mirobot_async import (
    LineResult,
    Mirobot,
    MirobotAlarmError,
    MirobotCommandError,
    MirobotConnectionError,
    MirobotLinkLostError,
    MirobotOutcomeUnknownError,
    MirobotResetError,
    MirobotTimeoutError,
    MotionRefusedError,
    State,
)
from mirobot_async.testing import EmulatorProcess

pytestmark = [
    pytest.mark.timeout(60),
    pytest.mark.usefixtures("no_leftover_tasks"),
    pytest.mark.emulator_process,  # faults on the wire: the emulator's control channel
]

SLOW_MOVES = [f"M21 G90 G1 X{10 + (i % 2) * 10} F600" for i in range(60)]  # ~1 s each
# A lost reply is found by a liveness check: after this long without progress (the client's
# default is 1 s), not before the reply grace (0.5 s, kept) after the line was written.
QUICK_LIVENESS = 0.1


# ---- lost and garbled replies -------------------------------------------------------------------


async def test_dropped_ok_times_out_naming_the_line_and_later_calls_work(
    emu: EmulatorProcess, ready_arm: Mirobot
) -> None:
    arm = ready_arm
    arm.liveness_interval = QUICK_LIVENESS
    await emu.control("drop-ok")
    start = time.monotonic()
    with pytest.raises(MirobotTimeoutError) as info:
        await arm.send("M3 S5")
    assert time.monotonic() - start < 5
    assert info.value.command == "M3 S5"
    assert "M3 S5" in str(info.value)
    assert arm.stats.replies_lost == 1
    assert await arm.send("M3 S6") == ()
    assert (await arm.status()).pump_pwm == 6
    assert arm.pending_count == 0


async def test_a_lost_reply_whose_caller_left_costs_one_call_then_all_is_in_step(
    emu: EmulatorProcess, ready_arm: Mirobot
) -> None:
    arm = ready_arm
    arm.liveness_interval = QUICK_LIVENESS
    await emu.control("drop-ok")
    first = asyncio.create_task(arm.send("M3 S1"))
    await wait_until(lambda: arm.pending_count == 1, 10, "one call pending")
    first.cancel()  # the caller leaves; its ok never comes
    with pytest.raises(asyncio.CancelledError):
        await first
    # The next line's ok is taken for the lost one (the robot's replies carry no line
    # identity): that call is the one that times out, then the link is in step again.
    with pytest.raises(MirobotTimeoutError) as info:
        await arm.send("M3 S2")
    assert info.value.command == "M3 S2"
    assert arm.stats.replies_lost == 1
    assert await arm.send("M3 S3") == ()
    assert (await arm.status()).pump_pwm == 3
    assert arm.pending_count == 0


async def test_corrupted_status_is_dropped_counted_and_polled_again(
    emu: EmulatorProcess, arm: Mirobot
) -> None:
    await emu.control("corrupt-status 3")
    report = await arm.status()
    assert report.joints == (0.0,) * 6
    assert arm.corrupted_status_count == 3
    assert arm.stats.status_corrupted == 3
    # monitoring carries on through more corruption
    await emu.control("corrupt-status 2")
    seen = 0
    async with contextlib.aclosing(arm.statuses(interval=0.0)) as reports:
        async for _ in reports:
            seen += 1
            if seen == 5:
                break
    assert arm.corrupted_status_count == 5


async def test_ignored_status_request_is_retried_within_the_timeout(
    emu: EmulatorProcess, arm: Mirobot
) -> None:
    await emu.control("ignore-status")
    start = time.monotonic()
    report = await arm.status(timeout=2)
    assert report.joints == (0.0,) * 6
    assert arm.stats.status_retries >= 1
    assert time.monotonic() - start < 1.5  # asked again after 0.25 s, well before the 2 s timeout
    await emu.control("ignore-status 100")
    with pytest.raises(MirobotTimeoutError, match="status"):
        await arm.status(timeout=0.3)  # asked again after 0.25 s, ignored again


async def test_stall_delays_but_loses_nothing(emu: EmulatorProcess, ready_arm: Mirobot) -> None:
    arm = ready_arm
    await emu.control("stall 0.6")
    start = time.monotonic()
    assert await arm.send("M3 S11") == ()
    assert time.monotonic() - start >= 0.5
    assert (await arm.status()).pump_pwm == 11


async def test_a_robot_that_stops_answering_status_fails_the_wait(
    emu: EmulatorProcess, ready_arm: Mirobot
) -> None:
    arm = ready_arm
    arm.liveness_interval = QUICK_LIVENESS
    arm.status_timeout = 0.3
    await emu.control("stall 1.0")  # outlasts the check (~0.4 s) with a margin for a busy box
    with pytest.raises(MirobotTimeoutError, match="status reply") as info:
        await arm.send("M3 S12")
    assert info.value.waited_for.startswith("a status reply")
    # once the stall is over, the late reply is consumed by its slot and all is in step
    await wait_until(lambda: arm.pending_count == 0, 5, "no call pending")
    assert await arm.send("M3 S13") == ()
    assert (await arm.status()).pump_pwm == 13


# ---- alarms -------------------------------------------------------------------------------------


@pytest.mark.mirobot_emulator(time_scale=1)
async def test_hard_limit_fails_pending_calls_and_nothing_is_sent_until_reset(
    emu: EmulatorProcess, ready_arm: Mirobot
) -> None:
    arm = ready_arm
    move = asyncio.create_task(arm.move_joints(j1=30, speed=600))
    stream = asyncio.ensure_future(arm.stream(SLOW_MOVES))
    await wait_until(lambda: arm.pending_count > 3, 10, "4 calls pending")
    await emu.control("hard-limit")
    with pytest.raises(MirobotAlarmError, match="Hard limit"):
        await move
    result = await stream
    assert result.stopped
    assert isinstance(result.errors[0].error, MirobotAlarmError)
    assert arm.needs_reset and arm.alarm == "Hard limit"
    sent = arm.stats.bytes_sent
    for call in (
        arm.move_joints(j1=0),
        arm.send("M3 S0"),
        arm.set_pump(0),
        arm.unlock(),
        arm.home(),
        arm.status(),
        arm.hold(),
        arm.settings(),
    ):
        with pytest.raises(MirobotAlarmError, match="Hard limit"):
            await call
    with pytest.raises(MirobotAlarmError):
        await arm.stream(["M3 S1"])
    assert arm.stats.bytes_sent == sent  # not a byte, not even "?"
    await arm.reset()
    assert not arm.needs_reset
    assert (await arm.status()).state is State.ALARM
    await arm.unlock()
    report = await arm.move_joints(j1=0, speed=3000)
    assert report is not None and report.state is State.IDLE


# ---- resets -------------------------------------------------------------------------------------


@pytest.mark.mirobot_emulator(time_scale=10)  # real time from the full planner on
@pytest.mark.parametrize("how", ["reset()", "spontaneous"])
async def test_reset_mid_stream(emu: EmulatorProcess, ready_arm: Mirobot, how: str) -> None:
    arm = ready_arm
    # after a spontaneous reset the lines in doubt are settled at the next liveness check
    arm.liveness_interval = QUICK_LIVENESS
    progress: list[LineResult] = []
    stream = asyncio.ensure_future(arm.stream(SLOW_MOVES, on_progress=progress.append))
    # the planner (18 blocks) is full and lines wait in the robot's receive buffer
    await wait_until(
        lambda: len(progress) >= 18 and arm.pending_count >= 4, 10, "18 results and 4 calls pending"
    )
    await emu.control("time-scale 1")
    # A line is written only when a block ends (~1 s apart). Reset only once every written line
    # has wholly reached the robot (a "?" written after it was answered): a line cut in two by
    # a spontaneous reset would run its tail as a line of its own (an empty line gets "ok").
    written = -1
    while written != arm.stats.lines_sent:
        written = arm.stats.lines_sent
        await arm.status(fresh=True)
    waiting = arm.pending_count
    if how == "reset()":
        await arm.reset()
    else:
        await emu.control("reset")
    result = await stream
    assert result.stopped and 18 <= result.sent < len(SLOW_MOVES)
    # Not run (lost with the robot's buffer); or, for a line that reached the robot only after
    # it reset by itself, what the robot did with it (locked after a reset: refused), or unknown
    # for a line the reset caught on its way (the wait above makes that unlikely).
    after_reset = (
        (MotionRefusedError, MirobotAlarmError, MirobotOutcomeUnknownError)
        if how == "spontaneous"
        else ()
    )
    assert all(isinstance(r.error, (MirobotResetError, *after_reset)) for r in result.errors)
    assert len(result.errors) >= waiting
    assert result.acknowledged >= 18
    # in order, each line once
    assert [r.number for r in progress] == list(range(1, len(progress) + 1))
    assert all(r.ok for r in progress[: result.acknowledged])
    sent = arm.stats.lines_sent
    await wait_until(
        lambda: arm.stats.resets >= 1 and not arm.pending_count,
        10,
        "the reset to end every pending call",
    )
    assert arm.stats.lines_sent == sent  # nothing resent silently
    # usable again after unlocking (a reset relocks the axes); no longer in real time
    await emu.control("time-scale 50")
    await arm.unlock()
    report = await arm.move_joints(j1=5, speed=3000)
    assert report is not None and abs(report.joints[0] - 5) < 0.05


@pytest.mark.mirobot_emulator(time_scale=1)
async def test_reset_during_a_waited_move_raises_reset_error(ready_arm: Mirobot) -> None:
    arm = ready_arm
    move = asyncio.create_task(arm.move_joints(j1=30, speed=600))
    await wait_until(
        lambda: arm.last_status is not None and arm.last_status.state is State.RUN,
        10,
        "a status in Run",
    )
    await arm.reset()
    with pytest.raises(MirobotResetError, match="reset"):
        await move


async def test_reset_fails_lines_still_waiting_to_be_sent(ready_arm: Mirobot) -> None:
    arm = ready_arm
    await arm.reset()
    assert (await arm.status()).state in (State.IDLE, State.ALARM)
    await arm.unlock()
    assert await arm.send("M3 S3") == ()


# ---- the link goes away -------------------------------------------------------------------------


@pytest.mark.mirobot_emulator(time_scale=1)
@pytest.mark.parametrize("how", ["kill", "close"])
async def test_link_lost_mid_stream_fails_every_pending_call_within_a_second(
    emu: EmulatorProcess, ready_arm: Mirobot, how: str
) -> None:
    arm = ready_arm

    async def monitor() -> None:
        async with contextlib.aclosing(arm.statuses(interval=0.01)) as reports:
            async for _ in reports:
                pass

    stream = asyncio.ensure_future(arm.stream(SLOW_MOVES))
    await wait_until(lambda: arm.pending_count > 3, 10, "4 calls pending")
    calls = [
        stream,
        asyncio.ensure_future(arm.send("M3 S1")),
        asyncio.ensure_future(arm.settings()),
        asyncio.ensure_future(arm.wait_idle()),
        asyncio.ensure_future(arm.move_joints(j1=1)),
        asyncio.create_task(monitor()),
    ]
    await asyncio.sleep(0)  # one loop turn: every call above has started
    start = time.monotonic()
    if how == "kill":
        emu.kill()
    else:
        await emu.control("close")
    # each would otherwise wait for moves of ~1 s each, or time out (a MirobotTimeoutError,
    # not the MirobotConnectionError asserted): 3 s leaves room for a loaded machine
    done, pending = await asyncio.wait(calls, timeout=3.0)
    elapsed = time.monotonic() - start
    for task in pending:
        task.cancel()
    assert not pending, f"still pending after {elapsed:.2f} s: {pending}"
    for task in done:
        with pytest.raises(MirobotConnectionError):
            task.result()
    assert arm.closed
    with pytest.raises(MirobotLinkLostError):
        await arm.send("M3 S2")
    with pytest.raises(MirobotLinkLostError):
        await arm.status()


def process_gone(pid: int) -> bool:
    """True once process ``pid`` has exited (a zombie not reaped yet has closed its pty end)."""
    try:
        return psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


@pytest.mark.mirobot_emulator(time_scale=1)  # G4 P5 takes 5 s: its reply is owed
@pytest.mark.parametrize("implementation", ["fast", "original"])
@pytest.mark.parametrize("noticed_by", ["read", "write"])
async def test_a_lost_link_reaches_no_exception_handler_and_is_reported_once(
    emu: EmulatorProcess,
    implementation: Any,
    noticed_by: str,
    caplog: pytest.LogCaptureFixture,
) -> None:
    """Killing the emulator: the calls fail with MirobotLinkLostError, and that is all.

    Nothing reaches the event loop's exception handler: no "Fatal write error on serial
    transport" (a write that hits the dead pty first), no "Task exception was never retrieved
    ... 'NoneType' object has no attribute 'connection_lost'" (the serial transport's clean-up
    run twice), and the client logs no WARNING for a loss that a waiting call reports.
    """
    loop = asyncio.get_running_loop()
    reported: list[dict[str, Any]] = []
    previous = loop.get_exception_handler()
    loop.set_exception_handler(lambda _loop, context: reported.append(context))
    try:
        with caplog.at_level(logging.DEBUG, logger="mirobot_async"):
            async with Mirobot.connect(emu.url, implementation=implementation) as arm:
                await arm.unlock()
                if noticed_by == "read":
                    call = asyncio.ensure_future(arm.send("G4 P5"))  # owed a reply
                    await wait_until(lambda: arm.pending_count == 1, 10, "one call pending")
                    emu.kill()
                    with pytest.raises(MirobotLinkLostError, match="was lost"):
                        await asyncio.wait_for(call, 2)
                else:
                    emu.kill()
                    # blocking: the event loop must not see the hangup yet
                    wait_for(lambda: process_gone(emu.pid), 5, "the emulator to exit")
                    with pytest.raises(MirobotLinkLostError, match="was lost"):
                        await asyncio.wait_for(arm.send("M3 S1"), 2)
                with pytest.raises(MirobotLinkLostError):
                    await arm.send("M3 S2")
        # Let the transport's clean-up tasks finish, then collect: a task that failed
        # unretrieved reports itself when it is garbage-collected.
        others = asyncio.all_tasks() - {asyncio.current_task()}
        if others:
            await asyncio.wait(others, timeout=2)
        gc.collect()
        await asyncio.sleep(0)  # one loop turn: the exception handler's callbacks run
    finally:
        loop.set_exception_handler(previous)
    assert reported == []
    loud = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert loud == [], [r.getMessage() for r in loud]


# ---- cancellation -------------------------------------------------------------------------------


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
    info = "Info, " if profile == "2021" else ""
    assert await m20 == ((f"{info}M20: Cartesian mode start.",) if profile == "2021" else ())
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


@pytest.mark.mirobot_emulator(time_scale=1)
async def test_link_lost_with_the_original_pyserial_asyncio(emu: EmulatorProcess) -> None:
    async with Mirobot.connect(emu.url, implementation="original") as arm:
        await arm.unlock()
        dwell = asyncio.ensure_future(arm.send("G4 P5"))
        await wait_until(lambda: arm.pending_count == 1, 10, "one call pending")
        emu.kill()
        start = time.monotonic()
        with pytest.raises(MirobotLinkLostError):
            await asyncio.wait_for(dwell, 3.0)
        assert time.monotonic() - start < 3.0  # the dwell alone would take 5 s
