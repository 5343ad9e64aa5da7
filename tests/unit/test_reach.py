"""Cartesian targets the arm cannot reach (:mod:`mirobot_async._safety.reach`), against the
emulator's pure firmware model (the same inverse kinematics): a target is flagged exactly when
the firmware drops it (unreachable, or a soft limit for a joint out of range), and only where
the program gives all six coordinates."""

from __future__ import annotations

import itertools

import pytest

from mirobot_async._core.modal import HOMED
from mirobot_async._safety.reach import unreachable_targets

Firmware = pytest.importorskip("mirobot_emulator.firmware").Firmware

TARGETS = [
    "X500 Y0 Z200 A0 B0 C0",  # beyond the reach
    "X200 Y0 Z200 A0 B0 C0",
    "X200 Y0 Z200 A0 B100 C0",  # J5 out of its range: a soft limit
    "X200 Y0 Z200 A0 B-100 C0",
    "X150 Y120 Z120 A0 B0 C30",
    "X0 Y0 Z500 A0 B0 C0",
    "X-300 Y0 Z100 A0 B0 C0",
]
DROPPED = ("GOAL OUT OF WORKSPACE", "Soft limit", "angle out of limit")


def _dropped(firmware: str, line: str) -> bool:
    """Whether the firmware model, homed, drops ``line`` (``ok`` with a refusal text)."""
    fw = Firmware(firmware, homing_seconds=0.0)
    fw.receive(b"$H\n")
    for _ in range(2000):
        fw.advance(0.05)
        if fw.state == "Idle":
            break
    fw.read_output()
    fw.receive(line.encode() + b"\n")
    out = ""
    for _ in range(2000):
        fw.advance(0.05)
        out += fw.read_output().decode("latin-1")
        if "ok" in out or "rror" in out:
            break
    assert "rror" not in out, out  # accepted by the parser: only the motion is judged
    return any(text in out for text in DROPPED)


@pytest.mark.parametrize(
    ("firmware", "target"), list(itertools.product(["classic", "2021"], TARGETS))
)
def test_a_target_is_flagged_exactly_when_the_firmware_drops_it(firmware: str, target: str) -> None:
    line = f"M20 G90 G0 {target}"
    flagged = unreachable_targets([line], firmware=firmware, start=HOMED)
    assert bool(flagged) == _dropped(firmware, line), flagged


def test_relative_targets_after_a_known_pose_and_nothing_where_unknown() -> None:
    program = [
        "M20 G90 G0 X500",  # the other five coordinates unknown: nothing said
        "G91 X10",  # still unknown
        "G90 X200 Y0 Z200 A0 B0 C0",  # known from here
        "G91 X300",  # X500: unreachable
        "G91 X-300",  # from a dropped target: unknown again (the parser's pose, not the arm's)
        "G90 X200 Y0 Z200 A0 B0 C0",
        "M21 G90 G0 X10",  # a joint move: the tool's pose unknown
        "M20 G91 G0 X400",
    ]
    found = unreachable_targets(program)
    assert [number for number, _ in found] == [4]
    assert "X500 Y0 Z200 A0 B0 C0 is unreachable" in found[0][1]
    assert "GOAL OUT OF WORKSPACE" in found[0][1]


def test_a_line_the_firmware_refuses_or_an_offset_stops_the_judgement() -> None:
    assert unreachable_targets(["M20 G90 G1 X500 Y0 Z200 A0 B0 C0"], start=HOMED) == []  # no F
    assert unreachable_targets(["G92 X0", "M20 G90 G0 X500 Y0 Z200 A0 B0 C0"]) == []
    assert unreachable_targets(["$41=10", "M20 G90 G0 X500 Y0 Z200 A0 B0 C0"]) == []
