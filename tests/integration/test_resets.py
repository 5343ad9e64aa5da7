"""Resets while lines are in flight, asked for (``reset()``) or spontaneous (the robot resets by
itself), and the hard-limit alarm only a reset clears: every line gets exactly one outcome (not
run, or what the robot did with a line that reached it after the reset; lines still waiting to
be sent fail as not sent), nothing is resent, nothing at all is written while the arm needs a
reset or while a reset awaits its banner (two overlapping ``reset()`` share one banner, a later
one waits for its own), and the arm is usable again after unlocking or homing.
"""

from __future__ import annotations

import asyncio
import contextlib
import re
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

import pytest
from fault_harness import (
    QUICK_LIVENESS,
    SLOW_MOVES,
    Spawn,
    emulator_stats,
    finishes_within,
    monitor,
    wire_settled,
)
from waiting import wait_until

from mirobot_async import (
    LineResult,
    Mirobot,
    MirobotAlarmError,
    MirobotOutcomeUnknownError,
    MirobotResetError,
    MotionRefusedError,
    State,
    StatusReport,
)
from mirobot_async.testing import EmulatorProcess, WireSpy

pytestmark = [pytest.mark.timeout(60), pytest.mark.usefixtures("no_leftover_tasks")]

FAST_HOMING = ("--homing-seconds", "0.2")
# A line's final reply: ok or an error; 2024: "Info,E100..E110" and "Error,E111..", but not its
# refusals "Error,E118"/"Error,E119"/"Error,A1nn" (their ok follows: docs/2024-profile.md)
FINAL_REPLY = re.compile(rb"ok|error: .*|Error, E\d+,.*|Error,E(?!118|119)\d+,.*|Info,E\d+,.*")
# Once what needs real-time motion has been checked, the rest (homing, recovery moves) runs this
# much faster than real time (the emulator's ``time-scale`` control command).
FAST_SCALE = "time-scale 50"


@pytest.mark.emulator_process
@pytest.mark.mirobot_emulator(time_scale=1, extra_args=FAST_HOMING)
@pytest.mark.parametrize("recover", ["home", "unlock"])
async def test_spontaneous_reset_mid_stream_fails_pending_lines_and_resends_nothing(
    emu: EmulatorProcess, ready_arm: Mirobot, recover: str, spawn: Spawn
) -> None:
    arm = ready_arm
    # The stream's lines are in doubt after the reset (they may run after it): the client settles
    # them by a "?" written a reply grace after the banner, at its next liveness check; checking
    # often keeps that well inside the 2 s below on a loaded machine.
    arm.liveness_interval = QUICK_LIVENESS
    lines_before = arm.stats.lines_sent
    # a wait=True move, then a stream queued behind it: the move waits for the arm to be Idle
    move = spawn(arm.move_joints(j1=40, speed=3000))
    await wait_until(lambda: arm.stats.lines_sent == lines_before + 1, 10, "the move to be sent")
    stream_task = spawn(arm.stream(SLOW_MOVES))
    await wait_until(
        lambda: arm.pending_count >= 4 and arm.stats.lines_sent >= 20,
        10,
        "20 lines sent and 4 pending",
    )
    # The robot's planner is full: a line is written only when a block ends (~1 s apart). Reset
    # only once every written line has wholly reached the robot (a "?" written after it was
    # answered): a line cut in two by the reset would run its tail as a line of its own (an
    # empty line gets "ok"), a reply the client could not tell from one to the line itself.
    written = -1
    while written != arm.stats.lines_sent:
        written = arm.stats.lines_sent
        await arm.status(fresh=True)
    status = spawn(arm.status())
    before = await emulator_stats(emu)
    await emu.control("reset")

    result = await finishes_within(5.0, stream_task)
    # at least what the wait above saw written (the planner's 17 blocks bound the rest)
    assert result.stopped and 20 - lines_before - 1 <= result.sent < len(SLOW_MOVES)
    # not run (lost with the robot's buffer), or what the robot did with a line that reached it
    # after it reset (2021: Alarm lock; classic: locked, refused); unknown for a line the reset
    # caught on its way (the wait above makes that unlikely)
    after_reset = (
        MirobotResetError | MirobotAlarmError | MotionRefusedError | MirobotOutcomeUnknownError
    )
    assert result.errors and all(isinstance(r.error, after_reset) for r in result.errors)
    # the first lines were acknowledged, every later one failed (those not yet written too)
    assert [r.number for r in result.errors] == list(
        range(result.acknowledged + 1, result.acknowledged + 1 + len(result.errors))
    )
    assert result.acknowledged + len(result.errors) >= result.sent
    # the move waiting for the arm to stop fails with the reset, or with the alarm the reset
    # printed ("Abort during cycle": the arm was moving)
    error = await finishes_within(5.0, move)
    assert isinstance(error, MirobotResetError | MirobotAlarmError), error
    assert isinstance(await finishes_within(5.0, status), StatusReport | MirobotResetError)
    await wait_until(
        lambda: arm.stats.resets >= 1 and arm.pending_count == 0,
        10,
        "the reset to end every pending call",
    )

    # nothing resent: the robot received the move's line and the stream's written lines, once
    # each, and nothing else
    assert (await arm.status()).state in (State.IDLE, State.ALARM)  # a "?" is no line
    stats = await wire_settled(emu, arm)
    assert stats["lines_in"] == arm.stats.lines_sent == lines_before + 1 + result.sent
    assert stats["resets_in"] == before["resets_in"] == 0  # the client never sent "%"

    # usable again after home() or unlock() (no longer in real time)
    await emu.control(FAST_SCALE)
    if recover == "home":
        homed = await arm.home(timeout=20)
        assert homed.state is State.IDLE
        assert homed.joints == pytest.approx((0.0,) * 6, abs=0.01)
    else:
        await arm.unlock()
    moved = await arm.move_joints(j1=5, speed=3000)
    assert moved is not None and moved.joints[0] == pytest.approx(5, abs=0.05)
    again = await arm.stream(["M3 S1", "M21 G90 G0 X6", "M3 S2"])
    assert again.ok
    stats = await wire_settled(emu, arm)
    assert stats["lines_in"] == arm.stats.lines_sent


@pytest.mark.emulator_process
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


@pytest.mark.emulator_process
async def test_lines_run_after_a_spontaneous_reset_are_reported_as_run(
    ready_arm: Mirobot, emu: EmulatorProcess, wire_spy: WireSpy
) -> None:
    """13.10: the robot resets by itself while its output is held up, and the client writes
    lines after the reset, before the banner arrives: the robot runs them. They used to be
    failed as "not run" (MirobotResetError), and their replies became protocol violations."""
    arm = ready_arm
    release = asyncio.Event()

    async def program() -> AsyncIterator[str]:
        for i in range(1, 4):
            yield f"M3 S{i}"
        await release.wait()
        for i in range(4, 40):
            yield f"M3 S{i}"

    progress: list[LineResult] = []
    stream = asyncio.create_task(arm.stream(program(), on_progress=progress.append).run())
    try:
        await wait_until(lambda: len(progress) == 3, 5, "3 line results")
        await emu.control("stall 0.5")  # the banner will be held up...
        await emu.control("reset")  # ...by the robot resetting now
        mark = wire_spy.mark()
        release.set()
        await wait_until(
            lambda: len(wire_spy.lines(mark)) >= 5, 5, "5 lines written after the reset"
        )
        result = await asyncio.wait_for(stream, 10)
    finally:
        release.set()
        stream.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await stream
    written = wire_spy.lines(mark)
    after_reset = progress[3 : 3 + len(written)]
    for late in progress[3 + len(written) :]:  # waited to be sent when the banner came
        assert isinstance(late.error, MirobotResetError) and "not sent" in str(late.error)
    received = b"".join(wire_spy.received)
    # the banner's last line: 2024's is its one line (docs/2024-profile.md)
    banner_end = max(received.rfind(b"Using reset pos!"), received.rfind(b"started successfully"))
    replies_after = [
        line for line in received[banner_end:].splitlines()[1:] if FINAL_REPLY.fullmatch(line)
    ]
    assert result.stopped  # a stream always stops at a reset
    assert len(after_reset) == len(written) == len(replies_after) >= 5
    assert not any(isinstance(r.error, MirobotResetError) for r in after_reset), after_reset
    assert arm.stats.protocol_violations == 0
    if all(r.ok for r in after_reset):  # (the 2021 firmware refuses them: Alarm lock)
        report = await arm.status(fresh=True)
        assert report.pump_pwm == int(after_reset[-1].line.split("S")[1])


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


async def test_overlapping_resets_share_one_reset_and_its_banner(
    ready_arm: Mirobot, wire_spy: WireSpy
) -> None:
    """13.9: two overlapping reset() calls wrote two "%", both returned on the first banner and
    the second banner then failed the next line although the robot ran it."""
    arm = ready_arm
    resets = arm.stats.resets
    mark = wire_spy.mark()
    first, second = await asyncio.gather(arm.reset(timeout=5), arm.reset(timeout=5))
    assert first == second
    assert wire_spy.since(mark).count(b"%") == 1
    await arm.unlock(timeout=5)  # (a second banner would fail these lines)
    assert await arm.send("M3 S5", timeout=5) == ()
    assert (await arm.status(fresh=True)).pump_pwm == 5
    assert arm.stats.resets == resets + 1


# The vendor's firmware differs here (when B's % reaches it before A's banner has ended: host
# timing): a % that arrives while the firmware prints its banner cuts that banner off mid-line (a
# few garbled bytes, no 'Using reset pos!') and prints one new banner; the client then ends reset
# A on it, sends the held M50 (answered ok, not failed) and reset B waits for a second banner
# that never comes (MirobotTimeoutError after 5 s). The emulator prints A's banner whole, then B's.
async def test_no_line_is_written_while_a_second_concurrent_reset_awaits_its_banner(
    ready_arm: Mirobot, wire_spy: WireSpy
) -> None:
    """Reset A's banner starts; reset B is called then (it needs a banner of its own): A ends
    first, and a line sent then must wait for B's banner instead of being lost to B's reset."""
    arm = ready_arm
    loop = asyncio.get_running_loop()
    second: list[asyncio.Task[tuple[str, ...]]] = []

    def on_receive(chunk: bytes) -> None:
        if not second and arm.stats.resets > resets_before:  # A's banner has started
            second.append(loop.create_task(arm.reset(timeout=5.0)))

    percent_written = 0
    b_wrote_its_reset = asyncio.Event()

    def on_write(chunk: bytes) -> None:
        nonlocal percent_written
        percent_written += chunk == b"%"
        if percent_written == 2:
            b_wrote_its_reset.set()

    resets_before = arm.stats.resets
    wire_spy.receive_hooks.append(on_receive)
    wire_spy.write_hooks.append(on_write)
    await arm.reset(timeout=5.0)
    assert second
    reset_b = second[0]
    try:
        async with asyncio.timeout(5):
            await b_wrote_its_reset.wait()  # B started after A's banner had: its own "%"
        assert not reset_b.done()  # B still waits for its banner: nothing may be written
        mark = wire_spy.mark()
        # Held back until B's banner, then failed as documented for lines waiting for their turn.
        with pytest.raises(MirobotResetError, match="not sent"):
            await arm.send("M50", timeout=5.0)
        assert wire_spy.lines(mark) == []
        await reset_b
        await arm.send("M50", timeout=5.0)
        assert wire_spy.lines(mark) == [b"M50\n"]
    finally:  # a failure above leaves no task behind with an unread exception
        reset_b.cancel()
        await asyncio.gather(reset_b, return_exceptions=True)


@pytest.mark.emulator_process
@pytest.mark.mirobot_emulator(time_scale=1, extra_args=FAST_HOMING)
async def test_hard_limit_fails_everything_and_nothing_is_sent_until_reset(
    emu: EmulatorProcess, ready_arm: Mirobot, spawn: Spawn, profile: str
) -> None:
    arm = ready_arm
    reports: list[StatusReport] = []
    move = spawn(arm.move_joints(j1=30, speed=600))
    stream = spawn(arm.stream(SLOW_MOVES))
    watch = spawn(monitor(arm, reports, interval=0.2))  # status polls amid the stream
    await wait_until(
        lambda: arm.pending_count > 3 and len(reports) >= 2,
        10,
        "4 calls pending and 2 status reports",
    )
    await emu.control("hard-limit")

    error = await finishes_within(5.0, move)
    assert isinstance(error, MirobotAlarmError) and "Hard limit" in str(error)
    result = await finishes_within(5.0, stream)
    assert result.stopped
    assert isinstance(result.errors[0].error, MirobotAlarmError)
    assert isinstance(await finishes_within(3.0, watch), MirobotAlarmError)
    await wait_until(lambda: arm.needs_reset, 10, "the client to need a reset")
    # 2024: "Error,A101,Hard limit:<axis>" (docs/2024-profile.md), J1's switch: X
    assert arm.alarm == ("Hard limit:X" if profile == "2024" else "Hard limit")

    # Nothing more goes out, not even "?": every call fails at once.
    sent = arm.stats.bytes_sent
    stats = await wire_settled(emu, arm)
    calls: dict[str, Callable[[], Awaitable[Any]]] = {
        "move_joints": lambda: arm.move_joints(j1=0),
        "move_pose": lambda: arm.move_pose(z=-5, relative=True),
        "send": lambda: arm.send("M3 S0"),
        "set_pump": lambda: arm.set_pump(0),
        "status": lambda: arm.status(),
        "unlock": lambda: arm.unlock(),
        "clear_alarm": lambda: arm.clear_alarm(),
        "home": lambda: arm.home(),
        "hold": lambda: arm.hold(),
        "resume": lambda: arm.resume(),
        "settings": lambda: arm.settings(),
        "set_setting": lambda: arm.set_setting(20, 1),
        "stream": lambda: arm.stream(["M3 S1"]),
        "wait_idle": lambda: arm.wait_idle(),
    }
    for name, call in calls.items():
        outcome = await finishes_within(1.5, call())  # at once: not after a 2 s status timeout
        assert isinstance(outcome, MirobotAlarmError), (name, outcome)
        assert "Hard limit" in str(outcome), (name, outcome)
    assert arm.stats.bytes_sent == sent
    assert (await emulator_stats(emu))["bytes_in"] == stats["bytes_in"] == sent

    # reset() clears it, leaving the arm locked; unlocking, or homing, makes the arm usable
    # (no longer in real time)
    await emu.control(FAST_SCALE)
    await arm.reset()
    assert not arm.needs_reset
    assert arm.pending_count == 0  # the lines lost in the robot's buffer were failed by it
    assert (await arm.status()).state is State.ALARM
    await arm.unlock()
    report = await arm.move_joints(j1=0, speed=3000)
    assert report is not None and report.state is State.IDLE
    homed = await arm.home(timeout=20)
    assert homed.state is State.IDLE
    moved = await arm.move_joints(j1=8, speed=3000)
    assert moved is not None and moved.joints[0] == pytest.approx(8, abs=0.05)
    stats = await wire_settled(emu, arm)
    assert stats["resets_in"] == 1
    assert stats["lines_in"] == arm.stats.lines_sent
