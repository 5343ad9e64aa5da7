"""Lines the firmware holds until queued motion has ended (GRBL 0.9j's synchronised spindle and
coolant changes: the Mirobot's pump ``M3 S``, valve ``M4 E`` and ``M5``), and lines it does not.

Each case sends a 1.6 s joint move and the line behind it at once. A line that waits is answered
when the arm stops: a ``?`` sent the moment the move's ``ok`` arrives finds the arm running with
the PWMs the line left before its wait (the old ones while an output was on), and a ``?`` sent the
moment the line's own ``ok`` arrives finds it at rest, exact. A line that does not wait is
answered at once: a ``?`` sent when both ``ok`` lines are in finds the arm running."""

from __future__ import annotations

import pytest

from .harness import Pair, Until
from .per_side import status_on_reply

# 30 degrees at F300: 6 s of motion, so the ? sent on the first reply finds the arm still
# moving however late a loaded host sends it
MOVE = "M21 G90 X30 F300"

# (lines before the move, the line behind it)
WAITS: list[tuple[tuple[str, ...], str]] = [
    ((), "M3 S1000"),  # the status shows 1000 during the wait: S is set before it (M5 was on)
    ((), "M3 S0"),
    ((), "M3"),
    ((), "M4"),
    ((), "M4 E65"),
    (("M3 S1000",), "M3 S500"),  # the status shows 1000 during the wait, 500 after it
    (("M3 S1000",), "S0"),
    (("M3 S1000",), "E40"),
    (("M3 S1000",), "M4 E65"),
    (("M3 S1000",), "M4 E40 S500"),
    (("M3 S1000",), "M5"),  # the pump PWM stays 1000 in the status
    (("M4 E65",), "M4 E40"),
    (("M4 E65",), "S500"),
    (("M4 E65",), "M3 S1000"),
    (("M4 E65",), "M5"),
    ((), "M8"),
    (("M8",), "M9"),
    ((), "M2"),
]

ANSWERED_AT_ONCE: list[tuple[tuple[str, ...], str]] = [
    ((), "M5"),
    ((), "S500"),  # the new PWM shows at once
    ((), "E40"),
    ((), "M9"),
    ((), "M7"),  # error: Unsupported command
    (("M3 S1000",), "M3 S1000"),
    (("M3 S1000",), "M3"),
    (("M4 E65",), "M4"),
    (("M4 E65",), "E65"),
    (("M4 E65",), "M4 S0"),
    (("M8",), "M8"),
    ((), "M1"),
    ((), "M20"),
    ((), "M50"),
    ((), "T1"),
    ((), "F500"),
    ((), "G92 X0"),
    ((), "G10 L2 P1 X0"),
    ((), "G28.1"),
    ((), "$20=0"),
    ((), "$X"),
    ((), "$G"),
    ((), "$#"),
    ((), "$N"),
    ((), "$I"),
]


def _name(case: tuple[tuple[str, ...], str]) -> str:
    before, line = case
    return " then ".join([*before, line])


# Seen in two CI runs (passed in others and alone): the oracle reported Idle to the ? sent on
# the move's ok, ours Run; what makes the firmware's move end early there is not found yet.
_UNSETTLED = {(("M3 S1000",), "M4 E40 S500")}


@pytest.mark.parametrize(
    "case",
    [
        pytest.param(
            case,
            marks=pytest.mark.xfail(
                strict=False,
                reason="sometimes the oracle's arm is Idle at the ? sent on the move's ok",
            ),
        )
        if case in _UNSETTLED
        else case
        for case in WAITS
    ],
    ids=_name,
)
def test_waits_for_motion(pair: Pair, case: tuple[tuple[str, ...], str]) -> None:
    before, line = case
    pair.lines("M50", *before)
    status_on_reply(pair, f"{MOVE}\n{line}\n".encode(), note="during the wait")
    pair.send(b"", Until(terminals=1), note="the held line's reply")
    pair.status()  # at rest, exact: the arm stopped before the reply
    pair.settle()
    pair.status()
    pair.check()


@pytest.mark.parametrize("case", ANSWERED_AT_ONCE, ids=_name)
def test_answered_at_once(pair: Pair, case: tuple[tuple[str, ...], str]) -> None:
    before, line = case
    pair.lines("M50", *before)
    status_on_reply(pair, f"{MOVE}\n{line}\n".encode(), replies=2, note="both replies")
    pair.settle()
    pair.status()
    pair.check()


def test_output_line_with_motion(pair: Pair) -> None:
    """The wait comes first; the line's own move follows it (relative to the position ``M21``
    read before the wait: ``M21 G91 X1 M3 S1000`` ends near J1 1, not 31; the step it then
    reads depends on the instant, so this compares an absolute target)."""
    pair.lines("M50")
    status_on_reply(pair, f"{MOVE}\nM21 G90 X5 M3 S1000\n".encode(), note="during the wait")
    pair.send(b"", Until(terminals=1), note="the held line's reply")
    pair.settle()
    pair.status()
    pair.check()
