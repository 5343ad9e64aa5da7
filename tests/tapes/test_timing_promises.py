"""The timing the client relies on, proven by the firmware's tapes (simulated time, no flakes).

Each promise names the tapes that show it. A promise holds when every one of its tapes that is
not a known difference (``known.py``, with the reason) replays equal (every line within the
suite's instant tolerance) and its own measure holds: a program's duration within 2 % of the
firmware's, the reply to a line held behind motion within the tolerance of the firmware's, a
burst that overflows the 127-byte receive ring losing the same bytes (every later reply equal),
and the homing search's silence and its end.
"""

from __future__ import annotations

import pytest
from known import KNOWN_DIFFERENCES
from tapes import index, load

from mirobot_async._tapes.format import Printed, Written
from mirobot_async._tapes.replay import INSTANT_TOLERANCE, ReplayReport, replay

PROMISES: dict[str, tuple[str, ...]] = {
    "program durations": ("test_diff_timing.py::test_program_time[",),
    "lines held behind motion": (
        "test_status_before_the_held_line_starts_the_move[",
        "test_pump_line_right_behind_a_long_move_is_answered_when_it_ends",
        "test_pump_line_behind_more_than_30_seconds_of_motion",
        "test_dwell_behind_a_move_runs_in_idle_and_is_not_given_up",
    ),
    "bursts that overflow the receive ring": (
        "test_overflowing_burst[",
        "test_diff_motion.py::test_burst[",
        "scenarios-s4/status_burst_motion#",
    ),
    "the homing search": (
        "test_diff_homing.py::test_homing_phases[",
        "test_diff_homing.py::test_homing_unlocks_after_reset#",
        "test_diff_homing.py::test_reset_during_homing#",
        "test_client.py::test_home_then_moves[classic]#",
        "test_sync.py::test_a_plain_script_drives_the_arm[classic]#",
        "test_sequential_home_on_the_real_firmware",
        "test_home_on_the_real_firmware",
        "scenarios-s4/homing_from_pose#",
        "scenarios-s4/homing_seq_from_pose#",
    ),
}


def _tapes_of(promise: str) -> list[str]:
    """The tapes that prove ``promise``: those that show it, less the known differences."""
    found = [i for i in sorted(index()) if any(p in i for p in PROMISES[promise])]
    return [i for i in found if i not in KNOWN_DIFFERENCES]


@pytest.mark.parametrize("promise", sorted(PROMISES))
def test_every_promise_is_proven_by_tapes(promise: str) -> None:
    assert len(_tapes_of(promise)) >= 4, _tapes_of(promise)


def _replayed(tape_id: str) -> tuple[ReplayReport, list[Printed], list[Written]]:
    tape = load(tape_id)
    report = replay(tape, "classic")
    printed = [e for e in tape.events if isinstance(e, Printed)]
    written = [e for e in tape.events if isinstance(e, Written) and not e.dropped]
    return report, printed, written


@pytest.mark.parametrize("tape_id", _tapes_of("program durations"))
def test_a_program_takes_as_long_as_on_the_firmware(tape_id: str) -> None:
    report, printed, written = _replayed(tape_id)
    assert report.equal, str(report.difference)
    start = next(w.t for w in written if w.t > printed[0].t and w.data not in (b"?",))
    _event, firmware_end, emulator_end = report.pairs[-1]
    assert emulator_end is not None
    firmware = firmware_end - start
    emulator = emulator_end - start
    assert abs(emulator - firmware) <= 0.02 * firmware, (firmware, emulator)


@pytest.mark.parametrize("tape_id", _tapes_of("lines held behind motion"))
def test_a_line_held_behind_motion_is_answered_when_the_firmware_answers_it(tape_id: str) -> None:
    report, _printed, _written = _replayed(tape_id)
    assert report.equal, str(report.difference)
    assert all(abs(e - f) <= INSTANT_TOLERANCE for _k, f, e in report.pairs if e is not None)


@pytest.mark.parametrize("tape_id", _tapes_of("bursts that overflow the receive ring"))
def test_a_burst_loses_the_bytes_the_firmware_loses(tape_id: str) -> None:
    report, printed, _written = _replayed(tape_id)
    assert report.equal, str(report.difference)
    assert report.lines == len(printed)  # every reply after the overflow compared


@pytest.mark.parametrize("tape_id", _tapes_of("the homing search"))
def test_the_homing_search_is_silent_and_ends_when_the_firmware_s_does(tape_id: str) -> None:
    report, printed, written = _replayed(tape_id)
    assert report.equal, str(report.difference)
    homing = next(w.t for w in written if w.data in (b"H", b"$H\n") or w.data.startswith(b"$H"))
    replies = [f for _k, f, _e in report.pairs if f > homing]
    assert replies, "no reply after the homing line"
    assert report.lines == len(printed)
