"""A link that hands every reply over byte by byte, or late: a mixed session (a stream of every
kind of line with status polls alongside, moves, settings) gives the same transcript as on a
clean link, and under a delay longer than a call's timeout the timeout holds and the link stays
in step.
"""

from __future__ import annotations

import time

import pytest
from fault_harness import (
    Spawn,
    emulator_stats,
    finishes_within,
    monitor,
    output_mark,
    stop,
    wire_quiet,
)
from waiting import wait_until

from mirobot_async import (
    Mirobot,
    MirobotTimeoutError,
    MotionRefusedError,
    State,
    StatusReport,
)
from mirobot_async.testing import EmulatorProcess

pytestmark = [
    pytest.mark.timeout(60),
    pytest.mark.usefixtures("no_leftover_tasks"),
    pytest.mark.emulator_process,  # faults on the wire: the emulator's control channel
]

SESSION_LINES = 1000  # every kind of line still occurs (M99 20x, G90 X170 10x, $G twice)


def session_lines(count: int = SESSION_LINES) -> list[str]:
    """A deterministic mix: outputs, joint moves (absolute, relative), dwell, modal words, comments,
    a refused move, unsupported codes, ``$G`` (exclusive), lower case."""
    lines: list[str] = []
    for i in range(count):
        k = i % 10
        if k == 0:
            lines.append(f"M3 S{i % 1000}")
        elif k == 1:
            lines.append(f"G90 G1 X{(i % 40) - 20} Y{(i % 30) / 10:.1f} F3000")
        elif k == 2:
            lines.append("G4 P0 (dwell)")
        elif k == 3:
            lines.append(f"M4 E{i % 1000}")
        elif k == 4:
            lines.append("G91 G0 Z" + ("0.5" if i % 20 < 10 else "-0.5"))
        elif k == 5:
            lines.append("M99" if i % 50 == 5 else "G90")
        elif k == 6:
            lines.append(f"G0 A{(i % 60) - 30} B{-(i % 20)} C{i % 90}")
        elif k == 7:
            lines.append("$G" if i % 500 == 7 else ("M21 F2000" if i % 100 == 17 else "F2000"))
        elif k == 8:
            lines.append("G90 X170" if i % 100 == 8 else f"X{i % 7}")
        else:
            lines.append("m3s1 ; lower case")
    return lines


async def mixed_session(arm: Mirobot, spawn: Spawn, poll_interval: float = 0.2) -> list[str]:
    """Stream + concurrent status polls (``poll_interval`` apart) + moves + settings; return
    what is deterministic. Status calls wait as long as the arm's ``status_timeout``."""
    patience = arm.status_timeout
    await arm.unlock()
    reports: list[StatusReport] = []
    watch = spawn(monitor(arm, reports, poll_interval, timeout=patience))  # amid the stream
    try:
        result = await arm.stream(
            session_lines(), continue_on_error=True, timeout=40, validate=False
        )
        await wait_until(lambda: len(reports) >= 2, 10, "2 status reports")
    finally:
        await stop(watch)
    transcript = [
        f"{r.number} {r.line!r} {r.output!r} {type(r.error).__name__}: {r.error}"
        for r in result.errors
    ]
    transcript.append(f"sent={result.sent} ack={result.acknowledged} stopped={result.stopped}")
    transcript.append((await arm.status(timeout=patience)).to_line())
    for move in (
        arm.move_joints(0, 10, 10, 0, -30, 0, speed=2500),
        arm.move_joints(j1=15, j4=5, relative=True),
        arm.move_pose(z=-10, relative=True, linear=True, speed=3000),
        arm.move_pose(x=5, rz=2, relative=True),
    ):
        report = await move
        assert report is not None and report.state is State.IDLE
        transcript.append(report.to_line())
    transcript.append(repr(await arm.send("$I")))
    transcript.append(repr(sorted((await arm.settings()).items())))
    assert all(report.state is State.IDLE for report in reports)
    assert arm.corrupted_status_count == 0
    assert arm.stats.protocol_violations == arm.stats.replies_lost == 0
    transcript.append(
        f"lines sent={arm.stats.lines_sent} acknowledged={arm.stats.lines_acknowledged} "
        f"rejected={arm.stats.lines_rejected} refused={arm.stats.lines_refused}"
    )
    return transcript


_BASELINES: dict[str, list[str]] = {}


async def baseline(profile: str, spawn: Spawn) -> list[str]:
    """The mixed session's transcript without faults (computed once per profile)."""
    if profile not in _BASELINES:
        emu = await EmulatorProcess.start(profile, 0.0)
        async with emu, Mirobot.connect(emu.url) as arm:
            _BASELINES[profile] = await mixed_session(arm, spawn)
    return _BASELINES[profile]


def test_the_session_exercises_errors_refusals_and_outputs() -> None:
    lines = session_lines()
    assert len(lines) == SESSION_LINES
    assert sum(line == "M99" for line in lines) == 20
    assert sum(line == "G90 X170" for line in lines) == 10
    assert sum(line == "$G" for line in lines) == 2


@pytest.mark.mirobot_emulator(extra_args=("--fault", "split-bytes"))
async def test_single_byte_reads_change_nothing(
    emu: EmulatorProcess, arm: Mirobot, profile: str, spawn: Spawn
) -> None:
    # Every byte of a reply is a round trip between two processes: on a loaded machine a status
    # report (~150 bytes) can take seconds, which is not what this test is about; and polls
    # every 0.2 s would then carry more bytes than the stream (the slower, the more polls).
    arm.status_timeout = 20
    # The power-on output is never faulted (it happened "before"): whether the client's flush at
    # open dropped all of it depends on timing, so count the bytes of the session alone. The
    # connect probe's report came after it: nothing of it is still on its way.
    before = await emulator_stats(emu)
    mark = await output_mark(emu, arm)
    expected = await baseline(profile, spawn)
    transcript = await mixed_session(arm, spawn, poll_interval=1.0)
    assert transcript == expected
    assert len(transcript) == 20 + 10 + 1 + 1 + 4 + 2 + 1  # errors, summary, reports, $I, $$...
    # (the report to a liveness "?" asked during a slow "$$" follows its reply)
    stats = await wire_quiet(emu, arm, mark)
    # every byte written to the client in the session was written on its own, and it got them
    written = stats["bytes_out"] - before["bytes_out"]
    assert stats["split_writes"] - before["split_writes"] == written > 4_000  # 1000 oks at least


@pytest.mark.mirobot_emulator(extra_args=("--fault", "delay:20"))
@pytest.mark.parametrize("profile", ["2021"])  # 6 s a profile: the 20 ms round trips add up
async def test_delayed_replies_change_nothing_and_timeouts_hold(
    emu: EmulatorProcess, arm: Mirobot, profile: str, spawn: Spawn
) -> None:
    expected = await baseline(profile, spawn)
    start = time.monotonic()
    report = await arm.status(timeout=1.0)
    assert time.monotonic() - start >= 0.019  # the delay is there
    # a status timeout shorter than the delay is kept (no report can come in 5 ms), and the
    # late reply confuses nothing
    start = time.monotonic()
    with pytest.raises(MirobotTimeoutError):
        await arm.status(timeout=0.005)
    assert time.monotonic() - start < 1.5  # no hang (the exception shows the timeout kept)
    assert (await arm.status(timeout=1.0)).joints == report.joints

    transcript = await mixed_session(arm, spawn)
    assert transcript == expected

    # a longer delay: a call's timeout holds too, and the link stays in step afterwards
    assert await emu.control("delay 200") == "ack delay 200"  # twice the timeouts below
    start = time.monotonic()
    with pytest.raises(MirobotTimeoutError) as info:
        await arm.send("M3 S21", timeout=0.1)
    assert 0.09 <= time.monotonic() - start < 1.5  # the exception shows the timeout kept
    assert info.value.command == "M3 S21"
    with pytest.raises(MirobotTimeoutError):
        await arm.status(timeout=0.1)
    assert await arm.send("M3 S22", timeout=5) == ()
    assert (await arm.status(timeout=5)).pump_pwm == 22
    assert arm.stats.replies_lost == 0
    assert isinstance(await finishes_within(3.0, arm.send("M3 S23")), tuple)
    with pytest.raises(MotionRefusedError):
        await arm.send("M21 G90 X170", validate=False)  # soft limit: refused, with the delay
