"""The controller bus: one serial link, one node talking at a time, one ``Mirobot`` per address.

:class:`ControllerBus` owns the link (a USB-RS485 adapter, 38400 8N1 by default) and a driver
task that puts one request at a time on the wire, prefixed ``@<address>`` (unpadded, as every
vendor client sends it; EXBOX.md 2) and ended with ``\\r\\n`` (the manual; every vendor client).
Replies carry no address, so the next node is addressed only once the current one has answered
everything it owes (:class:`~mirobot_async.bus._ledger.NodeLedger`). Nodes with work are served
round-robin, one request each, so one busy arm cannot starve the others.

Each arm's ``Mirobot`` gets a virtual transport (:class:`ArmTransport`) in place of a serial
port: its lines and realtime bytes become requests to its node, and the node's replies come
back to it as a direct link would deliver them (the extra ``ok`` lines of the line ends are
consumed). The ``Mirobot`` keeps all its guarantees (one outcome per line, in order;
cancellation never shifts a reply; a lost link fails every pending call).

The one exception to "one request at a time": while a node holds the bus with a forwarded line
the arm has not answered yet (a full planner, ``$H``, ``G4``), the host may ask *that same* node
for its status (and send it ``!``/``~``): every byte on the wire still comes from that one node,
so nothing can be misattributed, and a long wait is not mistaken for a dead node.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from mirobot_async._client.condition import HOMING_BOUND, homing_bound
from mirobot_async._client.transport import SerialLink
from mirobot_async.bus._ledger import Kind, NodeLedger, Owed, forwarded_line
from mirobot_async.errors import (
    MirobotLinkLostError,
    MirobotUsageError,
    NodeSilentError,  # defined with the error tree
)

__all__ = ["DEFAULT_BUS_BAUD", "BusStats", "BusTiming", "LinkSide", "NodeSilentError"]

_log = logging.getLogger("mirobot_async.bus")

DEFAULT_BUS_BAUD = 38400
"""What every vendor example opens the bus at (the factory default is INFERRED, EXBOX.md 1)."""

_REALTIME = {b"?": Kind.STATUS, b"!": Kind.REALTIME, b"~": Kind.REALTIME, b"%": Kind.REALTIME}


@dataclass(slots=True)
class BusTiming:
    """The bus's time limits (seconds)."""

    answer_timeout: float = 0.5
    """A controller command, a status request or a realtime byte must get its first reply byte
    within this (ARD waits 500 ms; the controller's own reply comes within ~100 ms)."""
    settle: float = 0.02
    """Silence that ends a reply of unknown length (a query's bare value, the line-end ``ok``
    a controller might not relay)."""
    probe_interval: float = 1.0
    """A node holding the bus this long without a byte is asked for its status (same node)."""
    planner_window: int | None = 16
    """Lines an arm may have answered but not finished before its next line waits for a status
    saying ``Idle`` (the arm's planner holds 18 blocks; a line sent to a full planner would
    hold the whole bus until a block ends). ``None``: no limit."""
    window_poll: float = 0.02
    """How often an arm whose window is full is asked for its status."""
    homing_bounds: dict[str, float] = field(default_factory=lambda: dict(HOMING_BOUND))
    """How long an arm homing (``$H``...) may answer nothing, not even ``?``, at the default
    homing rates (:data:`~mirobot_async._client.condition.HOMING_BOUND`): meanwhile the bus neither
    probes it nor takes an unanswered status request for a silent node."""
    reply_grace: float = 60.0
    """Each arm's :attr:`Mirobot.reply_grace <mirobot_async.Mirobot.reply_grace>`. A line
    waits in the bus's queue while other nodes talk, and a status request overtakes it, so the
    direct link's rule (a quiet robot that answered a ``?`` asked 0.5 s after a line has lost
    its reply) would give up lines that were merely not sent yet."""


@dataclass(slots=True)
class BusStats:
    """Counters of the bus (they only ever increase)."""

    requests: int = 0
    bytes_sent: int = 0
    bytes_received: int = 0
    stray_lines: int = 0
    probes: int = 0
    settled: int = 0
    silent_nodes: int = 0
    window_waits: int = 0
    """Status requests sent because an arm's planner window was full."""


@dataclass(slots=True)
class _Request:
    owed: Owed
    wire: bytes
    future: asyncio.Future[tuple[str, ...]] | None = None


@dataclass(slots=True)
class _Node:
    address: int
    ledger: NodeLedger
    lines: deque[_Request] = field(default_factory=deque)
    urgent: deque[_Request] = field(default_factory=deque)
    on_lost: Callable[[BaseException | None], None] | None = None
    last_rx: float = 0.0
    last_window_probe: float = -1e9
    silenced: NodeSilentError | None = None
    """Why the node was given up (it did not answer in time), if it was."""
    homing_until: float | None = None
    """Its controller was told to home the arm (``O105``): until then (or the arm's first
    report, or ``O103`` saying otherwise) the arm answers no ``?``, so its client's status
    requests wait in the queue (the bus stays free) instead of being taken for silence."""

    def queued(self) -> list[_Request]:
        return [*self.urgent, *self.lines]


class LinkSide:
    """The driver of the bus: queues, the one node addressed at a time, timers.

    Used by :class:`~mirobot_async.bus.ControllerBus`; not a public API.
    """

    def __init__(self, url: str, timing: BusTiming, line_end: bytes) -> None:
        self.url = url
        self.timing = timing
        self.line_end = line_end
        self.ends = line_end.count(b"\r") + line_end.count(b"\n")
        self.stats = BusStats()
        self.nodes: dict[int, _Node] = {}
        self.link: SerialLink | None = None
        self.fatal: BaseException | None = None
        self._holder: _Node | None = None
        self._rx = bytearray()
        self._wake = asyncio.Event()
        self._order: deque[int] = deque()
        self._futures: dict[int, asyncio.Future[tuple[str, ...]]] = {}
        self._task: asyncio.Task[None] | None = None
        self._loop = asyncio.get_running_loop()

    # ---- lifecycle

    async def open(self, baud: int, exclusive: bool, timeout: float) -> None:
        """Open the link and start the driver (raises what :meth:`SerialLink.open` raises)."""
        self.link = await SerialLink.open(
            self.url,
            on_data=self._on_data,
            on_lost=self._on_lost,
            baudrate=baud,
            exclusive=exclusive,
            timeout=timeout,
        )
        self._task = self._loop.create_task(self._drive(), name=f"controller bus {self.url}")

    async def close(self) -> None:
        """Fail everything pending, stop the driver, close the link (bounded)."""
        self._fail_all(MirobotLinkLostError(f"the controller bus {self.url!r} was closed"))
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        if self.link is not None:
            await self.link.close()

    # ---- nodes and requests

    def node(self, address: int) -> _Node:
        """The queues of ``address`` (created on first use)."""
        node = self.nodes.get(address)
        if node is None:
            node = self.nodes[address] = _Node(address, NodeLedger(_discard))
            node.ledger.deliver = None
            self._order.append(address)
        return node

    def rekey(self, old: int, new: int) -> None:
        """A controller's address changed (``O140``): its queues follow it."""
        if old == new:
            return
        if new in self.nodes:
            raise MirobotUsageError(f"address {new} is already in use on this bus")
        node = self.nodes.pop(old)
        node.address = new
        self.nodes[new] = node
        self._order = deque(new if a == old else a for a in self._order)

    def submit_line(self, address: int, line: bytes) -> None:
        """A line for the arm (``line`` without its line end), after its queued lines."""
        self._check_open()
        owed = forwarded_line(line.decode("ascii", "replace"), self.ends)
        self.node(address).lines.append(_Request(owed, self._wire(address, line)))
        self._wake.set()

    def submit_realtime(self, address: int, byte: bytes) -> None:
        """``?``, ``!``, ``~`` (ahead of the arm's queued lines) or ``%`` (which drops them)."""
        self._check_open()
        kind = _REALTIME[byte]
        node = self.node(address)
        if kind is Kind.STATUS:
            waiting = next((r for r in node.urgent if r.owed.kind is Kind.STATUS), None)
            if waiting is not None and waiting.owed.for_client:
                # A "?" still queued for this node answers this one too: its report will be
                # printed after both were written. (One "?" per report on a slow, shared bus:
                # a client polling faster than the bus answers would queue them without end.)
                waiting.owed.copies += 1
                return
        owed = Owed(kind, byte.decode(), self.ends, status_owed=kind is Kind.STATUS)
        request = _Request(owed, self._wire(address, byte))
        if byte == b"%":
            node.lines.clear()  # a reset discards what the arm had not read yet
            node.lines.append(request)
        else:
            node.urgent.append(request)
        self._wake.set()

    def submit_controller(self, address: int, command: str) -> asyncio.Future[tuple[str, ...]]:
        """A controller command (``O...``, ``$V``); the future gets its reply lines."""
        self._check_open()
        future: asyncio.Future[tuple[str, ...]] = self._loop.create_future()
        owed = Owed(Kind.CONTROLLER, command, 1)
        request = _Request(owed, self._wire(address, command.encode("ascii")), future)
        self.node(address).lines.append(request)
        self._wake.set()
        return future

    def attach(
        self, address: int, deliver: Callable[[bytes], None], on_lost: Callable[..., None]
    ) -> None:
        """An arm's client takes the node's arm replies."""
        node = self.node(address)
        if node.ledger.deliver is not None:
            raise MirobotUsageError(f"the arm at @{address:02d} already has a client")
        node.ledger.deliver = deliver
        node.on_lost = on_lost

    def detach(self, address: int) -> None:
        """The arm's client closed: drop its queued lines, consume what the node still owes."""
        node = self.nodes.get(address)
        if node is None:
            return
        node.on_lost = None
        node.ledger.deliver = None
        node.urgent.clear()
        node.lines = deque(r for r in node.lines if r.future is not None)
        self._wake.set()

    def homing_started(self, address: int, mode: int) -> None:
        """The controller at ``address`` homes its arm (``O105=<mode>``; 9 and 10 home one
        axis or group after another: the ``$HH`` bound, else the ``$H`` one)."""
        bound = homing_bound("$HH" if mode in (9, 10) else "$H", None, self.timing.homing_bounds)
        self.node(address).homing_until = self._loop.time() + bound
        self._wake.set()

    def homing_ended(self, address: int) -> None:
        """The arm at ``address`` is no longer homing (``O103`` says so)."""
        node = self.nodes.get(address)
        if node is not None and node.homing_until is not None:
            node.homing_until = None
            self._wake.set()

    def _wire(self, address: int, body: bytes) -> bytes:
        return b"@" + str(address).encode() + body + self.line_end

    def _check_open(self) -> None:
        if self.fatal is not None:
            raise MirobotLinkLostError(str(self.fatal))

    # ---- received bytes

    def _on_data(self, data: bytes) -> None:
        self.stats.bytes_received += len(data)
        if self.fatal is not None:
            return  # closed: nobody waits for anything
        holder = self._holder
        if holder is not None:
            holder.last_rx = self._loop.time()
        self._rx += data
        while (end := self._rx.find(b"\n")) >= 0:
            raw = bytes(self._rx[: end + 1])
            del self._rx[: end + 1]
            holder = self._holder
            if holder is not None and raw.startswith(b"<"):
                holder.homing_until = None  # a report: the arm's homing search is over
            if holder is None:
                if raw.strip():
                    self.stats.stray_lines += 1
                    _log.warning("bus %s: a line with no request in flight: %r", self.url, raw)
                continue
            self._finish(holder, holder.ledger.take(raw))
        self._wake.set()

    def _on_lost(self, exc: BaseException | None) -> None:
        detail = f": {exc}" if exc is not None else " (end of file)"
        self._fail_all(MirobotLinkLostError(f"the controller bus {self.url!r} was lost{detail}"))

    def _fail_all(self, error: BaseException) -> None:
        if self.fatal is not None:
            return
        self.fatal = error
        for node in self.nodes.values():
            self._fail_node(node, error)
        self._wake.set()

    def _fail_node(self, node: _Node, error: BaseException) -> None:
        """Fail everything ``node`` owes or has queued; its arm's client loses its link."""
        for request in node.queued():
            if request.future is not None and not request.future.done():
                request.future.set_exception(error)
        node.lines.clear()
        node.urgent.clear()
        self._drop_owed(node, error)
        if node.on_lost is not None:
            on_lost, node.on_lost = node.on_lost, None
            on_lost(error)

    # ---- completions

    def _finish(self, node: _Node, done: list[Owed]) -> None:
        for owed in done:
            future = self._futures.pop(id(owed), None)
            if future is not None and not future.done():
                future.set_result(tuple(owed.lines))
        if not node.ledger and self._holder is node:
            self._holder = None

    def _drop_owed(self, node: _Node, error: BaseException) -> None:
        for owed in node.ledger.clear():
            future = self._futures.pop(id(owed), None)
            if future is not None and not future.done():
                future.set_exception(error)
        if self._holder is node:
            self._holder = None
            self._rx.clear()

    # ---- the driver

    async def _drive(self) -> None:
        while self.fatal is None:
            now = self._loop.time()
            self._check_timers(now)
            holder = self._holder
            if holder is None:
                self._start_next(now)
            elif holder.urgent and self._held_by_arm(holder):
                self._send(holder, holder.urgent.popleft(), now)  # same node: unambiguous
                continue
            wait = self._next_timer(self._loop.time())
            self._wake.clear()
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(wait):
                    await self._wake.wait()

    @staticmethod
    def _held_by_arm(node: _Node) -> bool:
        """``node`` holds the bus with a line its arm has not answered (and nothing of the
        controller's own): a status request or ``!``/``~`` to it may go out now."""
        owed = node.ledger.owed
        waiting = any(o.kind is Kind.LINE and o.main_final_pending for o in owed)
        return waiting and not node.ledger.holds_controller_command

    def _start_next(self, now: float) -> None:
        for _ in range(len(self._order)):
            address = self._order[0]
            self._order.rotate(-1)
            node = self.nodes.get(address)
            if node is None:
                continue
            if node.homing_until is not None and now >= node.homing_until:
                node.homing_until = None  # longer than homing can take: ask it again
            if node.urgent and not (node.homing_until is not None and self._status_only(node)):
                self._send(node, node.urgent.popleft(), now)
                return
            if not node.lines:
                continue
            if self._window_full(node):
                if now - node.last_window_probe >= self.timing.window_poll:
                    node.last_window_probe = now
                    self.stats.window_waits += 1
                    self._send(node, self._probe(node), now)
                    return
                continue
            self._send(node, node.lines.popleft(), now)
            return

    @staticmethod
    def _status_only(node: _Node) -> bool:
        """All the node's urgent requests are status requests (held back while it homes)."""
        return all(r.owed.kind is Kind.STATUS for r in node.urgent)

    def _window_full(self, node: _Node) -> bool:
        window = self.timing.planner_window
        head = node.lines[0]
        if window is None or head.owed.kind is not Kind.LINE:
            return False
        return node.ledger.unfinished >= window

    def _probe(self, node: _Node) -> _Request:
        """A status request of the bus's own (its report is not passed to the arm's client)."""
        owed = Owed(Kind.STATUS, "?", self.ends, status_owed=True, for_client=False)
        return _Request(owed, self._wire(node.address, b"?"))

    def _send(self, node: _Node, request: _Request, now: float) -> None:
        assert self.link is not None
        owed = request.owed
        owed.sent_at = now
        owed.answered_before = node.ledger.lines_answered
        node.ledger.add(owed)
        if request.future is not None:
            self._futures[id(owed)] = request.future
        if self._holder is not node:
            node.last_rx = now
            self._holder = node
        self.stats.requests += 1
        self.stats.bytes_sent += len(request.wire)
        self.link.write(request.wire)

    def _homing_until(self, node: _Node) -> float | None:
        """When the homing search of ``node``'s arm must have ended, if it may be running: its
        oldest owed line is a homing line not answered yet, or its controller homes it
        (``O105``): the firmware answers no ``?``."""
        if node.homing_until is not None:
            return node.homing_until
        for owed in node.ledger.owed:
            if owed.kind is Kind.LINE and owed.main_final_pending:
                if owed.homing_kind is not None:
                    bounds = self.timing.homing_bounds
                    return owed.sent_at + homing_bound(owed.homing_kind, None, bounds)
                return None
        return None

    def _next_timer(self, now: float) -> float | None:
        holder = self._holder
        timing = self.timing
        if holder is None or not holder.ledger:
            gated = [n.last_window_probe for n in self.nodes.values() if n.lines and not n.urgent]
            homing = [n.homing_until for n in self.nodes.values() if n.homing_until is not None]
            if not gated and not homing:
                return None
            wakes = [g + timing.window_poll for g in gated] + homing
            return max(0.0, min(wakes) - now) + 0.0005
        quiet_since = holder.last_rx
        deadlines = [quiet_since + timing.settle, quiet_since + timing.probe_interval]
        deadlines += [o.sent_at + timing.answer_timeout for o in holder.ledger.owed]
        deadlines.append(quiet_since + timing.answer_timeout)
        homing_until = self._homing_until(holder)
        if homing_until is not None:
            deadlines.append(homing_until)
        future = [d for d in deadlines if d > now]
        return (min(future) - now if future else 0.0) + 0.0005

    def _check_timers(self, now: float) -> None:
        holder = self._holder
        if holder is None:
            return
        ledger = holder.ledger
        if not ledger:
            self._holder = None
            return
        timing = self.timing
        quiet = now - holder.last_rx
        if quiet >= timing.settle and not self._rx:
            done = ledger.settle(realtime=quiet >= timing.answer_timeout)
            if done:
                self.stats.settled += 1
                self._finish(holder, done)
                if self._holder is not holder:
                    return
        head = ledger.owed[0]
        homing_until = self._homing_until(holder)
        homing = homing_until is not None and now < homing_until
        for owed in ledger.owed:
            prompt = owed.kind is Kind.CONTROLLER or (
                owed.kind is Kind.STATUS and owed.status_owed and not homing
            )
            waited = now - max(owed.sent_at, holder.last_rx if owed is head else owed.sent_at)
            if prompt and waited >= timing.answer_timeout:
                self._node_silent(holder, owed)
                return
        probing = any(o.status_owed for o in ledger.owed)
        if homing:
            return  # the arm answers no "?" while it searches its homing switches
        if quiet >= timing.probe_interval and not probing and head.kind is Kind.LINE:
            self.stats.probes += 1
            self._send(holder, self._probe(holder), now)

    def _node_silent(self, node: _Node, owed: Owed) -> None:
        """``node`` did not answer ``owed`` in time: a controller command fails alone; a silent
        arm (its status unanswered) fails everything it owes, and its client's link is lost."""
        self.stats.silent_nodes += 1
        detail = ""
        homing_until = self._homing_until(node)
        if homing_until is not None:
            homing = next(o for o in node.ledger.owed if o.kind is Kind.LINE)
            detail = (
                f" (its arm was homing, {homing.command!r}, and answered nothing for "
                f"{homing_until - homing.sent_at:g} s, longer than homing can take)"
            )
        error = NodeSilentError(node.address, owed.command, self.timing.answer_timeout, detail)
        node.silenced = error
        _log.warning("bus %s: %s", self.url, error)
        if owed.kind is Kind.CONTROLLER:
            self._drop_owed(node, error)
            return
        self._fail_node(node, error)


def _discard(_: bytes) -> None:
    """A sink for replies nobody waits for."""
