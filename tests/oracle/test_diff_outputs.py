"""Lines the firmware holds until queued motion has ended (GRBL 0.9j's synchronised spindle and
coolant changes: the Mirobot's pump ``M3 S``, valve ``M4 E`` and ``M5``), and lines it does not.

Each case sends a 1.6 s joint move and the line behind it at once. A line that waits is answered
when the arm stops: a ``?`` that reaches the firmware 2 ms after the held line finds the arm
running with the PWMs the line left before its wait (the old ones while an output was on), and a
``?`` sent the moment the line's own ``ok`` arrives finds it at rest, exact. A ``?`` that
reaches it while the held line is still parsed finds the move queued but not started (``Idle``
at the start pose). A line that does not wait is answered at once: a ``?`` sent when both
``ok`` lines are in finds the arm running."""

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


STATUS_AFTER_THE_PARSE = b" " * 20 + b"?"
"""Behind the held line in the same write: 20 filtered bytes, so the ``?`` reaches the firmware
2 ms (simulated: 0.1 ms a byte on both sides) after the line's last byte, when the line waits
and the queued move has started (the latest wait measured, ``M4 E40 S500``'s, comes 0.5-0.6 ms
after that byte on the oracle).

Not a ``?`` sent when the move's ``ok`` arrives: that one raced the held line's parse. GRBL
prints a requested report before it starts queued blocks, so the oracle answers ``Idle`` at
the start pose to a ``?`` that arrives before the held line's synchronisation, ``Run`` after
it. That instant is 0.3-0.4 ms (simulated) after the move's ``ok`` is printed, while the ``?``
reaches the simulator after the host's reaction, in wall time at 5-7x (MIROBOT_ORACLE_REPORT
of 20 runs of ``M3 S1000 then M4 E40 S500`` alone: 8 oracle ``Idle`` with angles 0.000, 12
``Run``; the longest line, so the widest window; probes at fixed instants: ``Idle`` for a ``?``
up to 3.4 ms after the write, ``Run`` from 3.5 ms, every time). Our emulator answered ``Run``
in that window until it modelled the order (:func:`test_status_before_the_held_line_starts_the_move`
compares the window itself at fixed instants)."""


@pytest.mark.parametrize("case", WAITS, ids=_name)
def test_waits_for_motion(pair: Pair, case: tuple[tuple[str, ...], str]) -> None:
    before, line = case
    pair.lines("M50", *before)
    data = f"{MOVE}\n{line}\n".encode() + STATUS_AFTER_THE_PARSE
    pair.send(data, Until(terminals=1, statuses=1), moving=True, note="during the wait")
    pair.send(b"", Until(terminals=1), note="the held line's reply")
    pair.status()  # at rest, exact: the arm stopped before the reply
    pair.settle()
    pair.status()
    pair.check()


# (lines before the move, the held line, filtered bytes between it and the ``?``): the ``?``
# arrives 0.2-0.3 ms before the oracle's held line reaches its synchronisation (the last
# ``Idle`` of a sweep in 0.1 ms steps: pads 4, 8, 7, 11; ours 3, 8, 7, 12)
BEFORE_THE_START = [
    (("M3 S1000",), "M4 E40 S500", 2),
    (("M3 S1000",), "M4 E65", 6),
    (("M3 S1000",), "M3 S500", 5),
    (("M3 S1000",), "M5", 9),
]


@pytest.mark.parametrize(
    "case", BEFORE_THE_START, ids=lambda case: f"{_name(case[:2])} pad {case[2]}"
)
def test_status_before_the_held_line_starts_the_move(
    pair: Pair, case: tuple[tuple[str, ...], str, int]
) -> None:
    """A ``?`` that arrives while the held line is parsed is answered before the queued move
    starts: ``Idle`` at the start pose with the old PWMs, exact (the move starts once the
    report is out, 12.5 ms later on the oracle; the reply comes that much later)."""
    before, line, pad = case
    pair.lines("M50", *before)
    data = f"{MOVE}\n{line}\n".encode() + b" " * pad + b"?"
    pair.send(data, Until(terminals=1, statuses=1), note="before the start")
    pair.send(b"", Until(terminals=1), note="the held line's reply")
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
