"""Ends of motion (``Firmware.motion_ends``) at block ends the clock lands on or near, and
between moves separated by ``G4 P0``; the planner's counters on the public ``planner``."""

from __future__ import annotations

import math

from mirobot_emulator.firmware import Firmware
from mirobot_emulator.motion import SNAP_SECONDS


def _unlocked(profile: str = "classic") -> Firmware:
    fw = Firmware(profile, homing_seconds=0.0)
    fw.receive(b"M50\n")
    fw.advance(1.0)
    fw.read_output()
    return fw


def test_an_advance_ending_just_short_of_the_block_end_records_the_end() -> None:
    fw = _unlocked()
    fw.receive(b"M21 G90 X10 F2000\n")
    while fw.planner.running is None:  # the line is parsed, then the cycle starts
        fw.advance(0.001)
    deadline = fw.next_deadline()
    assert deadline is not None
    assert fw.motion_ends == 0
    fw.advance(deadline - fw.now - SNAP_SECONDS / 2)
    assert fw.motion_ends == 1
    assert not fw.planner.busy
    assert fw.state == "Idle"


def test_g4_p0_between_buffered_moves_ends_the_motion_twice() -> None:
    fw = _unlocked()
    fw.receive(b"M21 G90 X5 F2000\nG4 P0\nM21 G90 X0 F2000\n")
    fw.advance(math.inf)
    assert fw.motion_ends == 2
    first, second = list(fw.motion_end_times)[-2:]
    assert first < second
    assert fw.read_output().count(b"ok") == 3


def test_the_planner_counters_are_public() -> None:
    fw = _unlocked()
    fw.receive(b"M21 G90 X5 F2000\n")
    fw.advance(math.inf)
    assert fw.planner.run_outs >= 1
    assert fw.planner.starvations == 0
    fw.advance(0.5)
    fw.receive(b"M21 G90 X0 F2000\n")
    fw.advance(math.inf)
    assert fw.planner.starvations == 1
    assert fw.planner.starved_seconds >= 0.5
