"""Unreachable, edge and singular Cartesian targets: ``G0`` and ``G1``, soft limits on and off,
absolute and relative. Every reply and the position at rest after each line, byte for byte.

With soft limits off the oracle harness's range-end switches on J1..J3 stay (until homing), so
that grid leaves out the targets whose joints pass them (test_diff_motion.py::test_hard_limit
covers those); J4..J6 have no switch and go beyond their ranges."""

from __future__ import annotations

import pytest

from .harness import Pair

START = "M20 G90 G0 X200 Y0 Z170 A0 B0 C0"

# Absolute targets (pose words after ``M20 G90 G0``/``G1``), soft limits on.
ABSOLUTE: list[str] = [
    "X300 Y0 Z180 A0 B0 C0",  # too far: no J3
    "X280 Y0 Z180 A0 B0 C0",  # near the edge of reach
    "X290 Y0 Z230 A0 B0 C0",
    "X200 Y0 Z400 A0 B0 C0",  # too high
    "X0 Y0 Z300 A0 B0 C0",  # on the base axis, above
    "X0 Y0 Z182 A0 B0 C0",
    "X1 Y5 Z182 A0 B0 C0",  # near the base axis
    "X200 Y0 Z170 A0 B90 C0",  # J5 beyond its range
    "X200 Y0 Z170 A0 B-90 C0",
    "X200 Y0 Z170 A90 B0 C0",
    "X200 Y0 Z170 A0 B0 C180",  # J6 at its end
    "X200 Y0 Z170 A180 B0 C0",
    "X200 Y0 Z-100 A0 B0 C0",  # below: J2 beyond its range
    "X-100 Y0 Z180 A0 B0 C0",  # behind: J1 beyond its range
    "X0 Y200 Z180 A0 B0 C0",
    "X100 Y-200 Z180 A0 B0 C0",
    "X202 Y0 Z181 A0 B0 C0",  # the start pose (J5 = 0: wrist singular)
    "X50 Y0 Z100 A0 B0 C0",  # only over the back (J1 = 180): no THETA3 on the firmware
    "X60 Y0 Z130 A0 B0 C0",  # J2 beyond its range
]

# Soft limits off: only targets whose J1..J3 stay inside the switches.
ABSOLUTE_SOFT_OFF: list[str] = [
    "X300 Y0 Z180 A0 B0 C0",
    "X280 Y0 Z180 A0 B0 C0",
    "X200 Y0 Z400 A0 B0 C0",
    "X0 Y0 Z300 A0 B0 C0",
    "X200 Y0 Z170 A0 B90 C0",
    "X200 Y0 Z170 A0 B0 C180",
    "X200 Y0 Z170 A90 B0 C0",
    "X202 Y0 Z181 A0 B0 C0",
]

# Relative increments (after ``M20 G91 G0``/``G1``), each from START.
RELATIVE: list[str] = [
    "X100",  # too far
    "Z200",  # too high
    "X-200",  # onto the base axis
    "X-199 Y5",
    "B60",  # wrist out
    "B-60",
    "Z-250",  # below
    "Y300",
    "A90",
    "C-200",
    "X20 Y20 Z20",
    "X60 Z40",
]

RELATIVE_SOFT_OFF: list[str] = ["X100", "Z200", "B60", "C-200", "A90", "X60 Z40"]


CASES: list[tuple[bool, str]] = [
    *((True, f"M20 G90 {{motion}} {target}") for target in ABSOLUTE),
    *((False, f"M20 G90 {{motion}} {target}") for target in ABSOLUTE_SOFT_OFF),
    *((True, f"M20 G91 {{motion}} {step}") for step in RELATIVE),
    *((False, f"M20 G91 {{motion}} {step}") for step in RELATIVE_SOFT_OFF),
]


# An unreachable target leaves the joints of the last target (a joint line's, or the IK of a
# Cartesian one even when the soft limits refused it) and the soft limits check those: the
# workspace text, then a soft-limit line, then ok.
SEQUENCES: dict[str, list[str]] = {
    "after-soft-limit": [
        "M20 G90 G0 X100 Y0 Z50 A0 B0 C0",
        "M20 G90 G0 X50 Y0 Z100 A0 B0 C0",
        "M20 G90 G1 X300 Y0 Z180 A0 B0 C0 F2000",
    ],
    "after-joint-line": [
        "M20 G90 G0 X100 Y0 Z50 A0 B0 C0",
        "M21 G90 X10 F2000",
        "M20 G90 G0 X300 Y0 Z180 A0 B0 C0",
    ],
    "after-refused-joint-line": ["M21 G90 Y80", "M20 G90 G0 X300 Y0 Z180 A0 B0 C0"],
    "after-wrist-out": [
        "M20 G90 G0 X200 Y0 Z170 A0 B90 C0",
        "M20 G90 G0 X300 Y0 Z180 A0 B0 C0",
        "M20 G91 G0 X150",
        "M20 G90 G0 X200 Y0 Z170 A0 B0 C0",
        "M20 G90 G1 X40 Y30 Z110 A0 B0 C0 F2000",
    ],
}


@pytest.mark.timeout(180)
@pytest.mark.parametrize("name", SEQUENCES)
def test_sequence(pair: Pair, name: str) -> None:
    pair.lines("M50")
    for line in SEQUENCES[name]:
        pair.lines(line)
        pair.send("G4 P0\n", timeout=60.0, note="settle")
        pair.status()
    pair.check()


def _case_id(case: tuple[bool, str]) -> str:
    soft, line = case
    return f"{'soft-on' if soft else 'soft-off'} {line.replace(' {motion}', '')}"


@pytest.mark.timeout(180)
@pytest.mark.parametrize("motion", ["G0", "G1 F2000"])
@pytest.mark.parametrize("case", CASES, ids=_case_id)
def test_target(pair: Pair, case: tuple[bool, str], motion: str) -> None:
    """One target from a settled arm (relative ones from START): the reply, the position at
    rest and the parser's modes."""
    soft, line = case
    pair.lines("M50", *([] if soft else ["$20=0"]))
    if " G91 " in line:
        pair.lines(START)
        pair.settle()
    pair.lines(line.format(motion=motion))
    pair.send("G4 P0\n", timeout=60.0, note="settle")  # a wrist turn at F2000 takes 8 s
    pair.status()
    pair.send("$G\n")
    pair.check()
