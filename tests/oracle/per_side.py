"""Realtime bytes sent to each side at its own instant: the oracle and our emulator run on
independent clocks (the oracle at about 4-7x real time depending on the host's load, ours at a
fixed scale), so a ``?`` sent to both once both have answered can find one side still moving and
the other at rest. Sent to each side the moment its own reply is complete, it lands at the same
point of the motion on both (a few tens of simulated milliseconds after the reply)."""

from __future__ import annotations

import time

from .harness import Device, Exchange, HarnessError, Pair, Until, is_terminal, lines_of, pump_both


def end_of_replies(data: bytes, count: int) -> int | None:
    """Offset just after the ``count``-th ok/error line in ``data`` (None before it arrived)."""
    offset, seen = 0, 0
    for line in lines_of(data):
        offset = data.index(b"\n", offset) + 1
        seen += is_terminal(line)
        if seen >= count:
            return offset
    return None


def status_on_reply(
    pair: Pair, data: bytes, *, replies: int = 1, timeout: float = 90.0, note: str = ""
) -> None:
    """Send ``data`` to both; on each side, the moment it has printed ``replies`` ok/error
    lines, send it ``?``. Records two exchanges: ``data`` up to its replies (compared exactly)
    and the ``?`` (its status compared by format, as during motion)."""
    sides: tuple[Device, Device] = (pair.oracle, pair.ours)
    for device in sides:
        device.write(data)
    split: dict[str, int] = {}
    deadline = time.monotonic() + timeout
    while len(split) < len(sides):
        if time.monotonic() > deadline:
            said = pair.oracle.pending()
            raise HarnessError(f"no reply to {data!r} within {timeout} s; the oracle: {said!r}")
        pump_both(pair.oracle, pair.ours, 0.005)
        for device in sides:
            end = None if device.name in split else end_of_replies(device.pending(), replies)
            if end is not None:
                device.write(b"?")
                split[device.name] = device.mark + end
    answers = []
    for device in sides:
        answers.append(bytes(device.received[device.mark : split[device.name]]))
        device.mark = split[device.name]
    pair.exchanges.append(Exchange(data, answers[0], answers[1], note=note))
    for device in sides:
        if not device.read_until(Until(statuses=1).met, 20.0):
            raise HarnessError(f"{device.name}: no status after {data!r}")
    pair.exchanges.append(
        Exchange(b"?", pair.oracle.take(), pair.ours.take(), moving=True, note=f"? ({note})")
    )
