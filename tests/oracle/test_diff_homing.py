"""Homing: ``$H``, ``$HH`` and the single-axis forms, with ``?`` during each phase."""

from __future__ import annotations

import time

import pytest

from .harness import Device, Exchange, HarnessError, Pair, Until, is_terminal, lines_of, pump_both


def _end_of_first_reply(data: bytes) -> int | None:
    """Offset just after the first ok/error line in ``data`` (None before it has arrived)."""
    offset = 0
    for line in lines_of(data):
        offset = data.index(b"\n", offset) + 1
        if is_terminal(line):
            return offset
    return None


def status_at_homing_end(pair: Pair, timeout: float = 90.0) -> None:
    """``?`` during the switch search, then a second ``?`` to each side the moment its own
    homing ``ok`` arrives: two exchanges, the first compared exactly, the second by format.

    The two processes run on independent clocks (the oracle at 4-7x real time depending on the
    host's load, ours at a fixed scale), so the ``?`` of a plain :meth:`Pair.status` sent after
    both ``ok`` lines can land after one side's ~2.3 s return move has already ended
    (``Idle`` against ``Run``). Sent on each side's own ``ok`` it lands at the same point of
    the motion on both (a few tens of simulated milliseconds into the return move)."""
    sides: tuple[Device, Device] = (pair.oracle, pair.ours)
    for device in sides:
        device.write(b"?")
    split: dict[str, int] = {}
    deadline = time.monotonic() + timeout
    while len(split) < len(sides):
        if time.monotonic() > deadline:
            raise HarnessError(f"no homing ok within {timeout} s: {pair.oracle.pending()!r}")
        pump_both(pair.oracle, pair.ours, 0.005)
        for device in sides:
            end = None if device.name in split else _end_of_first_reply(device.pending())
            if end is not None:
                device.write(b"?")
                split[device.name] = device.mark + end
    first = []
    for device in sides:
        first.append(bytes(device.received[device.mark : split[device.name]]))
        device.mark = split[device.name]
    pair.exchanges.append(Exchange(b"?", first[0], first[1], note="? during the search, to ok"))
    for device in sides:
        if not device.read_until(Until(statuses=1).met, 20.0):
            raise HarnessError(f"{device.name}: no status after the homing ok")
    pair.exchanges.append(
        Exchange(b"?", pair.oracle.take(), pair.ours.take(), True, "? at the homing ok")
    )


@pytest.mark.timeout(240)  # the oracle slows down on a loaded host
@pytest.mark.parametrize("command", ["$H", "$HH", "$H1"])
def test_homing_phases(pair: Pair, command: str) -> None:
    """``?`` during the switch search (answered only when it ends, on the oracle), ``?`` during
    the return to zero (``Run``), then at rest; the parser state after homing."""
    pair.send(command + "\n", Until(quiet=0.2), note="homing starts")
    status_at_homing_end(pair)
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
