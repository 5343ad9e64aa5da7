"""The host's bytes on their way to the UART: each arrives one byte time after the previous.

The oracle's UART takes a byte every ~100 us (a 20-byte line written at once is answered 2.0 ms
later, a 16-byte one 1.6 ms; 115200 baud would be 86.8 us), so a host that writes more than the
receive ring holds loses only what arrives while the ring is full (oracle: 25 of 40 lines
written at once are answered). The parse time of a line overlaps the arrival of the next.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Final

BYTE_SECONDS: Final = 100e-6
"""Time of one byte on the host-to-firmware wire (oracle, measured)."""

_EVENT_BYTES: Final = re.compile(rb"[\r\n?!~%@]")
"""Bytes whose arrival matters at once: line ends and realtime bytes."""


class Wire:
    """A queue of bytes in transit with an explicit clock (``byte_seconds`` 0: no transit)."""

    def __init__(self, byte_seconds: float = BYTE_SECONDS) -> None:
        if not (math.isfinite(byte_seconds) and byte_seconds >= 0.0):
            raise ValueError(f"byte_seconds must be finite and >= 0: {byte_seconds}")
        self.byte_seconds = byte_seconds
        self._data = bytearray()
        self.in_transit: Final = self._data
        """The bytes still in transit (read them only: the same bytearray, never replaced)."""
        self._head_at = 0.0  # arrival of the first byte in transit
        self._last_at = -math.inf  # arrival of the last byte delivered
        self._event_index: int | None = None  # next_event's index into _data (None: unknown)
        self.delivered = 0
        """Bytes that have arrived so far (taken off the wire)."""

    def __len__(self) -> int:
        return len(self._data)

    def send(self, data: bytes, now: float) -> None:
        """The host writes ``data`` at ``now`` (after whatever is still in transit)."""
        if not data:
            return
        if not self._data:
            self._head_at = max(now, self._last_at) + self.byte_seconds
        self._data += data
        self._event_index = None

    def next_event(self) -> float | None:
        """When the next line end or realtime byte arrives (else the last byte), None if empty."""
        if not self._data:
            return None
        index = self._event_index
        if index is None:  # the bytes changed since the last search
            found = _EVENT_BYTES.search(self._data)
            index = self._event_index = found.start() if found is not None else len(self._data) - 1
        return self._head_at + index * self.byte_seconds

    def arrived_by(self, t: float) -> int:
        """How many bytes have arrived by ``t`` since power-on, those still in transit counted
        at their arrival times (``t`` not before the last byte taken)."""
        if not self._data or t < self._head_at - 1e-12:
            return self.delivered
        if self.byte_seconds <= 0.0:
            return self.delivered + len(self._data)
        count = math.floor((t - self._head_at) / self.byte_seconds + 1e-6) + 1
        return self.delivered + min(count, len(self._data))

    def busy_until(
        self, start: float, seconds: float, arrived: int, interrupts: Callable[[int], float]
    ) -> float:
        """When ``seconds`` of work begun at ``start`` (``arrived`` bytes had come by then)
        end, the ``n`` bytes arriving meanwhile adding ``interrupts(n)`` seconds."""
        if not self._data:  # nothing in transit: what arrived by any time is what came
            return start + seconds + interrupts(self.delivered - arrived)
        end = start + seconds
        for _ in range(64):  # each round adds the interrupts of the bytes the last one added
            later = start + seconds + interrupts(self.arrived_by(end) - arrived)
            if later == end:
                break
            end = later
        return end

    def take_due(self, now: float) -> bytes:
        """The bytes that have arrived by ``now`` (oldest first), taken off the wire."""
        if not self._data or now < self._head_at - 1e-12:
            return b""
        if self.byte_seconds > 0.0:
            count = math.floor((now - self._head_at) / self.byte_seconds + 1e-6) + 1
        else:
            count = len(self._data)
        count = min(count, len(self._data))
        due = bytes(self._data[:count])
        del self._data[:count]
        self.delivered += count
        self._event_index = None
        self._last_at = self._head_at + (count - 1) * self.byte_seconds
        self._head_at += count * self.byte_seconds
        return due
