"""Homing: ``$H``, ``$HH`` and the single-axis forms, with ``?`` during each phase."""

from __future__ import annotations

import pytest

from .harness import Pair, Until
from .per_side import status_on_reply


@pytest.mark.timeout(240)  # the oracle slows down on a loaded host
@pytest.mark.parametrize("command", ["$H", "$HH", "$H1"])
def test_homing_phases(pair: Pair, command: str) -> None:
    """``?`` during the switch search (answered only when it ends, on the oracle), ``?`` during
    the return to zero (``Run``), then at rest; the parser state after homing."""
    pair.send(command + "\n", Until(quiet=0.2), note="homing starts")
    # ``?`` during the switch search (answered when it ends, before the ok), then ``?`` on
    # each side's own ok: the return move has just begun on both (see .per_side)
    status_on_reply(pair, b"?", note="? during the switch search, to the ok")
    pair.settle()
    pair.status()
    pair.send("$G\n")
    pair.lines("M21 G90 G1 X10", "M21 G90 X5 F2000")
    pair.settle()
    pair.status()
    pair.check()


def test_homing_unlocks_after_reset(pair: Pair) -> None:
    pair.send("$H\n", Until(terminals=1), timeout=60)
    pair.settle()
    pair.reset()
    pair.lines("M21 G90 X5 F2000")
    pair.settle()
    pair.status()
    pair.check()


def test_reset_during_homing(pair: Pair) -> None:
    pair.send("$H\n", Until(quiet=0.3))
    pair.reset()
    pair.status()
    pair.lines("M21 G90 X5 F2000", "$X")
    pair.status()
    pair.check()
