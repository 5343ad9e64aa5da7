"""The wire: a transport, the sans-IO state machine on it, counters and the wire log.

:class:`Wire` is the only part of the client that writes bytes. It registers every line with
:class:`~mirobot_async._core.protocol.MirobotConnection` right before writing it (no ``await`` in
between, so its reply slot exists before the robot can answer), feeds every received byte to
the state machine and yields its events, counts everything in :class:`ClientStats` and logs
every line sent (``-> ...``) and received (``<- ...``) at DEBUG on the ``mirobot_async.wire``
logger. It also carries the "progress" signal that waiting calls sleep on.

The transport is pluggable through :class:`Transport` / :class:`TransportOpener` (pass
``open_transport=`` to :meth:`Mirobot.connect <mirobot_async._client.client.Mirobot.connect>`): the
default opens a serial port (:func:`serial_opener`); tests wrap it to watch the bytes, and a
multiplexed controller bus can provide its own.
"""

from __future__ import annotations

import asyncio
import logging
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Protocol

from mirobot_async._client.ports import AUTO, DEFAULT_PROBE_TIMEOUT, find_mirobot
from mirobot_async._client.transport import Implementation, SerialLink
from mirobot_async._core.protocol import Event, MirobotConnection, PendingLine
from mirobot_async.errors import MirobotConnectionError

__all__ = [
    "IN_PROCESS_SCHEME",
    "ClientStats",
    "DataCallback",
    "LostCallback",
    "Transport",
    "TransportOpener",
    "Wire",
    "WireTap",
    "register_in_process",
    "serial_opener",
    "unregister_in_process",
]

_wire_log = logging.getLogger("mirobot_async.wire")

DataCallback = Callable[[bytes], None]
LostCallback = Callable[[BaseException | None], None]


class Transport(Protocol):
    """What the client needs of an open link (:class:`~mirobot_async._client.transport.SerialLink`
    is one).

    ``write`` queues bytes and never blocks; ``abort`` drops the link at once (synchronous);
    ``close`` does the same and waits (boundedly) until it is released. The opener's
    ``on_lost`` callback must be called once when the link ends by itself. A link that is no
    serial line may say how far apart two ``?`` must be (an optional ``status_min_gap``
    attribute, seconds: 0 for an in-process arm, whose reports are printed at once).
    """

    def write(self, data: bytes) -> None: ...

    def abort(self) -> None: ...

    async def close(self) -> None: ...


class TransportOpener(Protocol):
    """``await opener(url, on_data=..., on_lost=..., timeout=...)`` -> an open :class:`Transport`.

    Must raise :class:`~mirobot_async.errors.MirobotConnectionError` when ``url`` cannot be
    opened within ``timeout`` seconds, and deliver every received chunk to ``on_data``.
    """

    async def __call__(
        self, url: str, *, on_data: DataCallback, on_lost: LostCallback, timeout: float
    ) -> Transport: ...


class WireTap(Protocol):
    """What watches every byte the wire writes and receives (the tape recorder,
    ``connect(record=...)``): each write once, after the transport took it; each received chunk
    once, before the state machine sees it. ``attach`` once the link is open, ``begin`` once
    the connect succeeded, ``close`` when the connection ends (or the link did not open)."""

    def written(self, data: bytes) -> None: ...

    def received(self, data: bytes) -> None: ...

    def attach(self, url: str, transport: Transport) -> None: ...

    def begin(self) -> None: ...

    def close(self, end: str = "closed") -> None: ...


IN_PROCESS_SCHEME = "virtual://"
"""URLs of virtual arms served inside this process (:mod:`mirobot_async.virtual`)."""
_in_process: dict[str, TransportOpener] = {}


def register_in_process(url: str, opener: TransportOpener) -> None:
    """Serve ``url`` (``virtual://...``) with ``opener`` in this process until unregistered."""
    if not url.startswith(IN_PROCESS_SCHEME):
        raise ValueError(f"{url!r} does not start with {IN_PROCESS_SCHEME!r}")
    _in_process[url] = opener


def unregister_in_process(url: str) -> None:
    """Stop serving ``url``: later opens fail with :class:`MirobotConnectionError`."""
    _in_process.pop(url, None)


def serial_opener(
    implementation: Implementation = "fast", exclusive: bool = True
) -> TransportOpener:
    """The default opener: a pyserial URL through
    :class:`~mirobot_async._client.transport.SerialLink`.

    The URL ``"auto"`` is the one Mirobot :func:`~mirobot_async._client.ports.find_mirobot` finds
    (probing with ``?`` and ``$$`` only, at most ``timeout`` seconds per stage, 3 s by default;
    :class:`~mirobot_async.errors.MirobotConnectionError` listing the ports when none or several
    answer). Cancellation while probing returns at once; the probes end by their own timeout.
    """

    async def open_serial(
        url: str, *, on_data: DataCallback, on_lost: LostCallback, timeout: float
    ) -> Transport:
        if url.startswith(IN_PROCESS_SCHEME):
            opener = _in_process.get(url)
            if opener is None:
                raise MirobotConnectionError(
                    f"{url}: no virtual Mirobot by that name in this process (it was closed, "
                    "or started in another process)"
                )
            return await opener(url, on_data=on_data, on_lost=on_lost, timeout=timeout)
        if url == AUTO:
            url = await asyncio.to_thread(find_mirobot, timeout=min(timeout, DEFAULT_PROBE_TIMEOUT))
        return await SerialLink.open(
            url,
            on_data=on_data,
            on_lost=on_lost,
            implementation=implementation,
            exclusive=exclusive,
            timeout=timeout,
        )

    return open_serial


@dataclass(slots=True)
class ClientStats:
    """Counters of one connection (for monitoring and tests); they only ever increase."""

    lines_sent: int = 0
    lines_acknowledged: int = 0  # "ok" (including refused motions)
    lines_rejected: int = 0  # error lines
    lines_refused: int = 0  # "ok" but the motion was dropped
    replies_discarded: int = 0  # replies to lines whose caller had given up (cancelled)
    replies_lost: int = 0  # lines given up because their reply never came
    status_requests: int = 0  # "?" written
    status_reports: int = 0  # well-formed status lines received
    status_corrupted: int = 0  # unparsable status lines (dropped, asked again)
    status_retries: int = 0  # "?" asked again because no reply came in time
    status_requests_forgotten: int = 0  # "?" taken as ignored by the robot (never answered)
    alarms: int = 0
    resets: int = 0  # banners seen (power-on, reset(), spontaneous)
    protocol_violations: int = 0  # stray "ok", overlong lines...
    bytes_sent: int = 0  # every byte written (lines and realtime bytes such as "?")
    bytes_received: int = 0
    envelope_refusals: int = 0  # lines refused by the safety envelope (nothing written)


class Wire:
    """One link's bytes: write lines and realtime bytes, turn received bytes into events."""

    def __init__(self, stats: ClientStats) -> None:
        self.stats = stats
        self.conn = MirobotConnection()
        self.transport: Transport | None = None
        self._progress = asyncio.Event()
        self._rx_log = bytearray()
        self.tap: WireTap | None = None
        """Sees every byte written and received (``connect(record=...)``), once."""
        self.refusal: MirobotConnectionError | None = None
        """Why the link ended, when the transport says the open failed after all (a network
        server that accepted the connection, then said it is busy): the error to raise for
        the failed connect instead of "link lost"."""

    @property
    def rx_buffer_size(self) -> int:
        """The robot's receive buffer (character counting), in bytes."""
        return self.conn.rx_buffer_size

    async def open(
        self,
        url: str,
        opener: TransportOpener,
        *,
        on_data: DataCallback,
        on_lost: LostCallback,
        timeout: float,
    ) -> None:
        """Open the transport (raises what the opener raises; cancellation as the opener's)."""

        def lost(exc: BaseException | None) -> None:
            if isinstance(exc, MirobotConnectionError):
                self.refusal = exc
            on_lost(exc)

        try:
            self.transport = await opener(url, on_data=on_data, on_lost=lost, timeout=timeout)
        except BaseException:
            self.end_tap("closed")  # the link did not open
            raise
        if self.tap is not None:
            self.tap.attach(url, self.transport)

    def receive(self, data: bytes) -> Iterator[Event]:
        """Count and log ``data``, feed it to the state machine and yield its events."""
        self.stats.bytes_received += len(data)
        if self.tap is not None:
            self.tap.received(data)
        if _wire_log.isEnabledFor(logging.DEBUG):
            self._log_received(data)
        self.conn.receive_data(data)
        return self.conn.events()

    def _log_received(self, data: bytes) -> None:
        buf = self._rx_log
        buf += data
        *lines, rest = re.split(rb"\r\n|\r|\n", bytes(buf))
        buf[:] = rest[-1024:]
        for line in lines:
            if line.strip():
                _wire_log.debug("<- %s", line.decode("ascii", "replace"))

    def write_line(self, data: bytes) -> PendingLine:
        """Register ``data`` (one checked line, no line end) and write it; synchronous."""
        transport = self.transport
        assert transport is not None
        pending = self.conn.send_line(data)
        transport.write(pending.wire)
        if self.tap is not None:
            self.tap.written(pending.wire)
        self.stats.lines_sent += 1
        self.stats.bytes_sent += len(pending.wire)
        if _wire_log.isEnabledFor(logging.DEBUG):
            _wire_log.debug("-> %s", data.decode("ascii", "replace"))
        return pending

    def write_realtime(self, data: bytes) -> None:
        """Write a realtime byte (``?``, ``!``, ``~``, ``%``) from the state machine's helpers."""
        transport = self.transport
        assert transport is not None
        transport.write(data)
        if self.tap is not None:
            self.tap.written(data)
        self.stats.bytes_sent += len(data)
        if _wire_log.isEnabledFor(logging.DEBUG):
            _wire_log.debug("-> %s", data.decode("ascii"))

    def request_status(self) -> None:
        """Write a ``?`` (counted by the state machine and in :attr:`stats`)."""
        self.write_realtime(self.conn.request_status())
        self.stats.status_requests += 1

    def notify(self) -> None:
        """Wake every task waiting for progress (a reply, a reset, an alarm...)."""
        self._progress.set()
        self._progress = asyncio.Event()

    async def wait_progress(self, timeout: float | None) -> bool:
        """Wait for the next :meth:`notify`; False if ``timeout`` seconds passed first."""
        event = self._progress
        try:
            async with asyncio.timeout(timeout):
                await event.wait()
        except TimeoutError:
            return False
        return True

    async def next_progress(self) -> None:
        """Wait for the next :meth:`notify` without a limit (cancel to stop waiting)."""
        await self._progress.wait()

    def begin_tap(self) -> None:
        """The connect succeeded: the tap may write what it held (a tape's header first)."""
        if self.tap is not None:
            self.tap.begin()

    def end_tap(self, end: str) -> None:
        """The connection ended (``closed``, ``lost``): the tap writes its end and stops."""
        tap, self.tap = self.tap, None
        if tap is not None:
            tap.close(end)

    def abort(self) -> None:
        """Drop the link at once (unsent output is discarded)."""
        if self.transport is not None:
            self.transport.abort()

    async def close(self) -> None:
        """Close the link (bounded by the transport)."""
        if self.transport is not None:
            await self.transport.close()
