"""The bytes on the cable, both ways, with bounded buffers.

Input: client -> wire pacing (``--baud``) -> data faults -> firmware. Output: firmware -> lines
-> data faults -> ``delay`` -> ``stall`` -> wire pacing -> USB latency timer -> port (one byte
per write with ``split-bytes``).

**Bounded, as a real port is.** A serial port never holds an unbounded amount of data: a host
writing faster than the baud rate is blocked by its driver's full transmit buffer, and a host
that does not read loses nothing only until the device blocks. So the emulator holds at most
:data:`INPUT_HOLD_LIMIT` bytes in transit to the firmware and stops taking input from the port
while :data:`OUTPUT_HOLD_LIMIT` bytes or more wait to reach the client: the client's writes then
fill the OS buffers and block (or fail with ``EAGAIN``), as on a serial port. Bytes that do
reach the firmware faster than it takes them are lost in its 128-byte receive ring, as on the
arm (the firmware model does that).
"""

from __future__ import annotations

import math
import re
import time

from .._faults import FaultFilter, OutputDelay
from ._pacing import UsbLatencyBuffer, WirePacer
from ._port import READ_CHUNK, Port

__all__ = ["INPUT_HOLD_LIMIT", "OUTPUT_HOLD_LIMIT", "InputPath", "OutputPath"]

INPUT_HOLD_LIMIT = 4096
"""Bytes in transit to the firmware at most (like a USB-serial driver's transmit buffer)."""
OUTPUT_HOLD_LIMIT = 65536
"""While this many bytes or more wait for the client, no input is taken from the port."""
# split-bytes on a pty: a written byte reaches the slave's input queue asynchronously (the
# kernel pushes the pty's flip buffer from a work queue, usually within microseconds): wait this
# long at most to see it arrive there. Waits poll the port: busily for SPLIT_SPIN_S (a reading
# client takes a few microseconds per byte, time.sleep costs ~60), then every SPLIT_POLL_S.
SPLIT_LANDING_S = 0.0003
SPLIT_SPIN_S = 0.0003
SPLIT_POLL_S = 0.0001
SPLIT_READ_WAIT_S = 0.002  # wait this long for the client to read a byte just written, ...
SPLIT_RETRY_S = 0.001  # ... else look again this much later (from the loop)
SPLIT_BUDGET_S = 0.005  # write bytes for at most this long, then serve input again
SPLIT_GAP_S = 0.00005  # a port that cannot tell what was read (TCP): this long between bytes

_OUTPUT_LINES = re.compile(rb"[^\n]*\n")  # output lines, each with its ending


class InputPath:
    """Bytes from the client on their way to the firmware; counts what crossed the wire."""

    def __init__(self, baud: int | None, fault_filter: FaultFilter) -> None:
        self._wire = WirePacer(baud)
        self._filter = fault_filter
        self.bytes_in = 0  # bytes received from the client (before pacing and faults)
        self.lines_in = 0  # b"\n" among them
        self.status_requests_in = 0  # b"?" among them
        self.resets_in = 0  # b"%" among them
        self.held_max = 0  # the most bytes ever held in transit

    def room(self) -> int:
        """Bytes the port may read now (0: leave them in the OS buffers)."""
        return max(0, min(READ_CHUNK, INPUT_HOLD_LIMIT - len(self._wire)))

    def held(self) -> int:
        """Bytes in transit to the firmware."""
        return len(self._wire)

    def push(self, data: bytes, now: float) -> None:
        """Bytes read from the port at ``now``."""
        if not data:
            return
        self.bytes_in += len(data)
        self.lines_in += data.count(b"\n")
        self.status_requests_in += data.count(b"?")
        self.resets_in += data.count(b"%")
        self._wire.push(data, now)
        self.held_max = max(self.held_max, len(self._wire))

    def pop(self, now: float) -> bytes:
        """The bytes that reach the firmware by ``now`` (the ``?`` to ignore taken out)."""
        data = self._wire.pop(now)
        return self._filter.input_bytes(data) if data else data

    @property
    def crossed_at(self) -> float | None:
        """When the first byte of the last :meth:`pop` crossed a paced wire (else None)."""
        return self._wire.crossed_at

    def next_time(self) -> float | None:
        """When more bytes reach the firmware (None: nothing in transit)."""
        return self._wire.next_time()

    def clear(self) -> None:
        """Forget the bytes in transit."""
        self._wire.clear()


class OutputPath:
    """The firmware's output on its way to the client (see the module docstring)."""

    def __init__(self, baud: int | None, usb_latency: float, fault_filter: FaultFilter) -> None:
        self._filter = fault_filter
        self.delay = OutputDelay()
        self._partial = bytearray()  # output after the last line end
        self._stalled = bytearray()
        self._stall_until = -math.inf
        self._wire = WirePacer(baud)
        self._usb = UsbLatencyBuffer(usb_latency)
        self.pending = bytearray()  # delivered by the adapter, not yet taken by the port
        self.split = False
        self.split_writes = 0  # bytes written one by one (split-bytes)
        self.bytes_out = 0  # bytes written to the client (the power-on banner included)
        self.held_max = 0  # the most bytes ever held
        self._next_split = -math.inf  # a port that cannot tell what was read: next byte then

    def held(self) -> int:
        """Bytes on their way to the client, in every stage."""
        return (
            len(self._partial)
            + len(self.delay)
            + len(self._stalled)
            + len(self._wire)
            + len(self._usb)
            + len(self.pending)
        )

    @property
    def full(self) -> bool:
        """True while no input should be taken (see :data:`OUTPUT_HOLD_LIMIT`)."""
        return self.held() >= OUTPUT_HOLD_LIMIT

    def power_on(self, output: bytes) -> None:
        """The power-on output: not paced, delayed or faulted (it happened "before")."""
        self._partial += output
        end = self._partial.rfind(b"\n") + 1
        self.pending += self._partial[:end]
        del self._partial[:end]

    def collect(self, output: bytes, now: float) -> None:
        """New firmware output at ``now``; complete lines go through the data faults."""
        if not output:
            return
        self._partial += output
        end = self._partial.rfind(b"\n")
        if end >= 0:
            complete = bytes(self._partial[: end + 1])
            del self._partial[: end + 1]
            for line in _OUTPUT_LINES.findall(complete):
                kept = self._filter.output_line(line)
                if kept:
                    self.delay.push(kept, now)
        self.held_max = max(self.held_max, self.held())

    def stall(self, until: float) -> None:
        """Hold all output until ``until`` (the firmware keeps running)."""
        self._stall_until = max(self._stall_until, until)

    def release(self, now: float) -> None:
        """Move what is due at ``now`` through delay, stall, wire and adapter to :attr:`pending`."""
        released = self.delay.pop(now)
        if released:
            self._stalled += released
        if self._stalled and now >= self._stall_until:
            self._wire.push(bytes(self._stalled), now)
            self._stalled.clear()
        wired = self._wire.pop(now)
        if wired:
            self._usb.push(wired, now)
        delivered = self._usb.pop(now)
        if delivered:
            self.pending += delivered

    def wants_write(self, port: Port) -> bool:
        """True when the port should be watched for room to write."""
        if not self.pending:
            return False
        if self.split:
            unread = port.unread()
            return unread == 0 if unread is not None else time.monotonic() >= self._next_split
        return True

    def next_time(self, now: float) -> float | None:
        """When something in the output stages becomes due (None: nothing waits)."""
        times = [
            t
            for t in (self.delay.next_time(), self._wire.next_time(), self._usb.next_time())
            if t is not None
        ]
        if self._stalled:
            times.append(self._stall_until)
        if self.split and self.pending:
            times.append(max(now + SPLIT_RETRY_S, self._next_split))
        return min(times) if times else None

    def discard(self) -> None:
        """Forget everything on its way (a reset of the link: reset on open, client gone)."""
        self._partial.clear()
        self.delay.clear()
        self._stalled.clear()
        self._wire.clear()
        self._usb.clear()
        self.pending.clear()

    def write_to(self, port: Port) -> None:
        """Write :attr:`pending` to the port without blocking (one byte per write when split)."""
        if not self.pending:
            return
        if not port.has_client:  # nobody on the other end of the cable
            self.pending.clear()
            return
        if self.split:
            self._write_split(port)
            return
        written = port.write(self.pending)
        self.bytes_out += written
        del self.pending[:written]

    def _write_one(self, port: Port) -> bool:
        if not port.write(self.pending[:1]):
            return False
        del self.pending[:1]
        self.bytes_out += 1
        self.split_writes += 1
        return True

    def _write_split(self, port: Port) -> None:
        """split-bytes: one byte per write, the next only once the client has read it.

        Returns after ``SPLIT_BUDGET_S`` (the loop serves input, then calls again) or when the
        client has not read the last byte ``SPLIT_READ_WAIT_S`` after it was written (the loop
        looks again every ``SPLIT_RETRY_S``; a client that does not read costs one ``ioctl``).
        On a port that cannot tell what the client read (TCP), bytes are written
        ``SPLIT_GAP_S`` apart: the client's reads then usually, not always, return one byte.
        """
        deadline = time.monotonic() + SPLIT_BUDGET_S
        if port.unread() is None:
            while self.pending and port.has_client and time.monotonic() >= self._next_split:
                if not self._write_one(port):
                    return
                self._next_split = time.monotonic() + SPLIT_GAP_S
                if time.monotonic() >= deadline:
                    return
                time.sleep(SPLIT_GAP_S)
            return
        start = -math.inf  # when the last byte landed in the port: none in this call
        while self.pending and port.is_open:
            if port.unread():  # the client has not read the last byte yet
                waited = time.monotonic() - start
                if waited >= SPLIT_READ_WAIT_S or time.monotonic() >= deadline:
                    return
                if waited >= SPLIT_SPIN_S:
                    time.sleep(SPLIT_POLL_S)
                continue
            if not self._write_one(port):
                return
            # Let the byte reach the slave's input queue before looking whether it was read:
            # otherwise the next byte could join it there and the client read both at once.
            start = time.monotonic()
            landing = start + SPLIT_LANDING_S
            while not port.unread() and time.monotonic() < landing:
                pass
            if time.monotonic() >= deadline:
                return
