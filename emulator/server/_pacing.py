"""The speed of the wire: baud-rate pacing and a USB-serial adapter's latency timer.

Both are pure (the caller passes ``now``, wall-clock seconds) and hold the bytes in transit.
"""

from __future__ import annotations

import math
from collections import deque

__all__ = ["PACING_GRANULARITY_S", "USB_PACKET_PAYLOAD", "UsbLatencyBuffer", "WirePacer"]

USB_PACKET_PAYLOAD = 62  # FTDI full-speed packet: 64 bytes, 2 of them modem status
PACING_GRANULARITY_S = 0.002  # paced bytes are released in chunks of about this duration


class _Segment:
    __slots__ = ("data", "offset", "start")

    def __init__(self, start: float, data: bytes) -> None:
        self.start = start  # when the byte at ``offset`` starts its transmission
        self.data = data
        self.offset = 0


class WirePacer:
    """Bytes through a serial wire: each byte takes 10/baud seconds after the previous one (8N1).

    With ``baud=None`` it is a pass-through. Bytes pushed at time t start their transmission at t
    or when the wire is free; :meth:`pop` returns those fully transmitted by ``now``. ``len()``
    is the number of bytes still in transit (the caller bounds it).
    """

    def __init__(self, baud: int | None) -> None:
        self._byte_time = 10.0 / baud if baud else 0.0
        self._chunk = max(1, int(PACING_GRANULARITY_S / self._byte_time)) if baud else 0
        self._segments: deque[_Segment] = deque()
        self._busy_until = -math.inf
        self._direct = bytearray()
        self._held = 0
        self.crossed_at: float | None = None
        """When the first byte of the last :meth:`pop` finished crossing (None: unpaced or
        nothing popped), so that the firmware can get the bytes at their own instant rather
        than when the loop woke up."""

    def __len__(self) -> int:
        return self._held

    @property
    def paced(self) -> bool:
        """True when a baud rate is set (bytes take time), False for a pass-through."""
        return bool(self._byte_time)

    def push(self, data: bytes, now: float) -> None:
        """Bytes handed to the wire at ``now``."""
        if not data:
            return
        self._held += len(data)
        if not self._byte_time:
            self._direct += data
            return
        start = max(now, self._busy_until)
        self._segments.append(_Segment(start, bytes(data)))
        self._busy_until = start + len(data) * self._byte_time

    def pop(self, now: float) -> bytes:
        """The bytes that have crossed the wire by ``now``, oldest first."""
        if not self._byte_time:
            direct = bytes(self._direct)
            self._direct.clear()
            self._held = 0
            return direct
        out = bytearray()
        self.crossed_at = None
        while self._segments:
            seg = self._segments[0]
            ready = int((now - seg.start) / self._byte_time + 1e-6)
            if ready <= 0:
                break
            if self.crossed_at is None:
                self.crossed_at = seg.start + self._byte_time
            take = min(ready, len(seg.data) - seg.offset)
            out += seg.data[seg.offset : seg.offset + take]
            if seg.offset + take >= len(seg.data):
                self._segments.popleft()
                continue
            seg.start += take * self._byte_time
            seg.offset += take
            break
        self._held -= len(out)
        return bytes(out)

    def next_time(self) -> float | None:
        """When the next chunk of bytes will have crossed (None: nothing in transit)."""
        if not self._segments:
            return None
        seg = self._segments[0]
        return seg.start + self._byte_time * min(self._chunk, len(seg.data) - seg.offset)

    def clear(self) -> None:
        """Forget the bytes in transit (the wire is free at once)."""
        self._segments.clear()
        self._direct.clear()
        self._busy_until = -math.inf
        self._held = 0


class UsbLatencyBuffer:
    """An FTDI-like latency timer: output waits until it is ``latency`` s old or fills a packet."""

    def __init__(self, latency: float) -> None:
        self._latency = latency
        self._buf = bytearray()
        self._since = 0.0

    def __len__(self) -> int:
        return len(self._buf)

    def push(self, data: bytes, now: float) -> None:
        """Bytes received by the adapter at ``now``."""
        if data and not self._buf:
            self._since = now
        self._buf += data

    def pop(self, now: float) -> bytes:
        """The bytes the adapter sends to the host by ``now`` (full packets, or the timer ran)."""
        if self._latency <= 0:
            everything = bytes(self._buf)
            self._buf.clear()
            return everything
        out = bytearray()
        while len(self._buf) >= USB_PACKET_PAYLOAD:
            out += self._buf[:USB_PACKET_PAYLOAD]
            del self._buf[:USB_PACKET_PAYLOAD]
            self._since = now
        if self._buf and now - self._since >= self._latency - 1e-9:
            out += self._buf
            self._buf.clear()
        return bytes(out)

    def next_time(self) -> float | None:
        """When the latency timer fires (None: off or empty)."""
        if self._latency <= 0 or not self._buf:
            return None
        return self._since + self._latency

    def clear(self) -> None:
        """Forget the bytes held."""
        self._buf.clear()
