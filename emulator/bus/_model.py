"""The RS485 bus: what the host's USB-RS485 adapter sees, with N controller+arm nodes behind it.

:class:`Bus` has the public methods of :class:`mirobot_emulator.firmware.Firmware` that the
server uses (``now``, ``receive``, ``advance``, ``read_output``, ``next_deadline``, ``reset``,
``trigger_hard_limit``), so the server serves a bus exactly as it serves one arm.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

from ..firmware import Firmware
from ._controller import Controller
from ._options import BAUD_CODES, DEFAULT_BUS_BAUD, BusOptions

__all__ = ["MAX_LINE", "Bus"]

MAX_LINE = 256
"""Longest line (bytes, line end included) a controller buffers; longer ones are dropped
(INFERRED: the real buffer size is unknown)."""

_SAME_INSTANT_LIMIT = 100_000  # never loop forever on a model that does not move its clock


class _Segment:
    """Bytes one node transmits back to back from ``start`` (each takes one byte time)."""

    __slots__ = ("data", "sent", "start")

    def __init__(self, start: float, data: bytes) -> None:
        self.start = start
        self.data = data
        self.sent = 0


class Bus:
    """``nodes`` controllers at addresses 1..N, each with an arm of ``profile`` (one profile for
    all, or one per node), on a bus at ``baud`` (8N1: a byte takes ``10 / baud`` seconds; one of
    the ``O141`` rates, every controller set to it).

    Host bytes (:meth:`receive`) travel at the bus baud; a controller acts on a line when its
    last byte has arrived and answers after ``options.turnaround`` seconds, at the bus baud;
    replies of several nodes are serialised on the wire. Every time two parties would have
    talked at once on the real half-duplex bus (a node and the host, or two nodes), the bus counts
    a collision (:attr:`collisions`) but delivers both unharmed: a client that keeps one request
    in flight never causes one.
    """

    def __init__(
        self,
        nodes: int = 1,
        profile: str | Sequence[str] = "2021",
        *,
        homing_seconds: float | None = None,
        baud: int = DEFAULT_BUS_BAUD,
        options: BusOptions | None = None,
    ) -> None:
        if not 1 <= nodes <= 99:
            raise ValueError(f"nodes={nodes}: a bus has 1..99 controllers")
        profiles = [profile] * nodes if isinstance(profile, str) else list(profile)
        if len(profiles) != nodes:
            raise ValueError(f"{len(profiles)} profiles for {nodes} nodes")
        codes = {rate: code for code, rate in BAUD_CODES.items()}
        if baud not in codes:
            raise ValueError(f"baud={baud}: a controller runs at one of {sorted(codes)}")
        self.options = options if options is not None else BusOptions()
        self.baud = baud
        self.byte_time = 10.0 / baud
        self.nodes: tuple[Controller, ...] = tuple(
            Controller(
                i + 1,
                # The bus models the wire's byte times itself: the arm takes each line at once.
                Firmware(p, homing_seconds=homing_seconds, byte_seconds=0.0),
                self.options,
                baud_code=codes[baud],
            )
            for i, p in enumerate(profiles)
        )
        """The controllers in bus order (their addresses may change by ``O140``)."""
        self.now = 0.0
        """Simulated seconds since power-on (every arm's clock follows it)."""
        self.collisions = 0
        self.lines_dropped = 0
        """Lines longer than :data:`MAX_LINE`, or addressed to nobody listening."""
        self._inbound: deque[tuple[float, int]] = deque()  # host bytes and when they arrive
        self._host_free = 0.0  # the end of the host's last byte on the wire
        self._line = bytearray()
        self._outbound: deque[_Segment] = deque()
        self._wire_free = 0.0  # the end of the last byte a node transmits
        self._talker: Controller | None = None
        self._collect(0.0)

    # ---- the Firmware-like interface

    def receive(self, data: bytes) -> None:
        """Bytes from the host: each arrives one byte time after the previous one ends."""
        if not data:
            return
        if self._wire_free > self.now:
            self.collisions += 1  # the host talks while a node still transmits
        when = max(self.now, self._host_free)
        for byte in bytes(data):
            when += self.byte_time
            self._inbound.append((when, byte))
        self._host_free = when

    def advance(self, dt: float) -> None:
        """Run the clock ``dt`` seconds (``math.inf``: until nothing changes by itself)."""
        if not dt >= 0.0:
            raise ValueError(f"dt must be >= 0, got {dt}")
        end = self.now + dt
        same_instant = 0
        while (when := self._next_event()) is not None and when <= end:
            same_instant = same_instant + 1 if when <= self.now else 0
            if same_instant > _SAME_INSTANT_LIMIT:  # pragma: no cover - a model bug
                break
            self._step_to(max(when, self.now))
        if math.isinf(end):
            self._step_to(max(self.now, self._wire_free, self._host_free))
        else:
            self._step_to(end)

    def read_output(self) -> bytes:
        """The bytes that have reached the host by :attr:`now`."""
        out = bytearray()
        while self._outbound:
            segment = self._outbound[0]
            done = min(len(segment.data), self._bytes_done(segment.start))
            if done > segment.sent:
                out += segment.data[segment.sent : done]
                segment.sent = done
            if segment.sent < len(segment.data):
                break
            self._outbound.popleft()
        return bytes(out)

    def next_deadline(self) -> float | None:
        """When something next happens: a request line arrives, an arm changes by itself, or
        a reply line (or the rest of one) reaches the host."""
        candidates = [
            when for when in (self._next_event(), self._next_output()) if when is not None
        ]
        return min(candidates) if candidates else None

    def reset(self) -> None:
        """Power-cycle every controller (``O100`` on each); bytes on the wire are lost."""
        self._inbound.clear()
        self._outbound.clear()
        self._line.clear()
        self._host_free = self._wire_free = self.now
        for node in self.nodes:
            node.restart()
            node.take_output()

    def trigger_hard_limit(self, axis: int = 1, *, address: int = 1) -> None:
        """Fault injection: a limit switch of the arm at ``address`` closes now."""
        self.controller(address).arm.trigger_hard_limit(axis)
        self._collect(self.now)

    # ---- inspection

    def controller(self, address: int) -> Controller:
        """The (first) controller at ``address``; :class:`KeyError` if none."""
        for node in self.nodes:
            if node.address == address:
                return node
        raise KeyError(f"no controller at address {address}")

    @property
    def rx_lost(self) -> int:
        """Bytes the arms' receive rings lost, all nodes together."""
        return sum(node.arm.rx_lost for node in self.nodes)

    # ---- the clock

    def _next_event(self) -> float | None:
        """The next instant the model must act at: a line end arrives, an arm's deadline."""
        times: list[float] = []
        if self._inbound:
            line_end = next((when for when, byte in self._inbound if byte == 0x0A), None)
            times.append(self._inbound[-1][0] if line_end is None else line_end)
        for node in self.nodes:
            deadline = node.arm.next_deadline()
            if deadline is not None:
                times.append(deadline)
        return min(times) if times else None

    def _next_output(self) -> float | None:
        """When the host next gets something: the first byte of the next reply line, else the
        end of the line being transmitted (two wake-ups per line for a server)."""
        for segment in self._outbound:
            sent = segment.sent
            if sent >= len(segment.data):
                continue
            if sent == 0 or segment.data[sent - 1] == 0x0A:
                last = sent
            else:
                newline = segment.data.find(b"\n", sent)
                last = newline if newline >= 0 else len(segment.data) - 1
            return segment.start + (last + 1) * self.byte_time
        return None

    def _bytes_done(self, start: float) -> int:
        if self.now < start:
            return 0
        return int((self.now - start) / self.byte_time + 1e-9)

    def _step_to(self, when: float) -> None:
        for node in self.nodes:
            node.arm.advance(max(0.0, when - node.arm.now))
        self.now = when
        while self._inbound and self._inbound[0][0] <= when:
            _, byte = self._inbound.popleft()
            self._line.append(byte)
            if byte == 0x0A:
                line = bytes(self._line)
                self._line.clear()
                self._dispatch(line)
            elif len(self._line) > MAX_LINE:
                self._line.clear()
                self.lines_dropped += 1
        self._collect(when)

    def _dispatch(self, line: bytes) -> None:
        """A whole line heard by every controller listening at the bus baud."""
        listening = [node for node in self.nodes if node.baud == self.baud]
        text = line.lstrip(b" \r\x00")
        if text.startswith(b"@"):
            digits = len(text) - 1 - len(text[1:].lstrip(b"0123456789"))
            if digits == 0:
                self.lines_dropped += 1
                return
            address = int(text[1 : 1 + digits])
            body = text[1 + digits :]
            if address == 0:
                if self.options.broadcast == "execute":
                    for node in listening:
                        node.hear(body, answer=False)
                return
            targets = [node for node in listening if node.address == address]
        else:
            body = line
            wanted = self.options.unprefixed
            targets = [node for node in listening if wanted and node.address == wanted]
        if not targets:
            self.lines_dropped += 1
        for node in targets:
            node.hear(body)

    def _collect(self, when: float) -> None:
        """Route every arm's output; put what the controllers transmit on the wire."""
        for node in self.nodes:
            node.collect()
            heard = node.baud == self.baud  # at another baud: noise the host cannot read
            data = node.take_output()
            if data and heard:
                self._transmit(node, data, when)

    def _transmit(self, node: Controller, data: bytes, when: float) -> None:
        ready = when + self.options.turnaround
        if self._host_free > ready:
            self.collisions += 1  # the host is still talking
        if self._wire_free > ready and self._talker is not node:
            self.collisions += 1  # another node is still talking
        start = max(ready, self._wire_free)
        self._outbound.append(_Segment(start, data))
        self._wire_free = start + len(data) * self.byte_time
        self._talker = node
