"""The emulator's serial port as a TCP socket: ``socket://HOST:PORT`` for pyserial and our client.

Portable (plain sockets, no pty, no ``fcntl``/``termios``). One client at a time, as on a serial
port: a second connection while one is served gets one line saying the port is busy (when its
open is over, as below), then the end of the stream (FIN, not a reset: what it sent meanwhile
is read and dropped, so that the line is not lost to a reset); it is closed when its client
closes it or after :data:`REFUSED_LINGER_S`. A connection is an open of the port; it takes effect
(``--reset-on-open`` resets the firmware then) at the client's first byte or
:data:`~._port.OPEN_SETTLE_S` after it connected, so that pyserial's open-time flush does not
swallow the banner. When the client goes away the robot keeps its state, and output meanwhile
is lost (nobody is on the other end of the cable). ``TCP_NODELAY`` is set: every write goes out
at once, as on a serial line. What a client writes is read only while the emulator has room for
it (bounded input), so a client writing faster than the emulator takes bytes is blocked by
TCP's flow control.
"""

from __future__ import annotations

import contextlib
import selectors
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ._port import OPEN_SETTLE_S, READ_CHUNK, Arrival, Port

__all__ = ["BUSY_MESSAGE", "REFUSED_LINGER_S", "TcpPort", "socket_url"]

BUSY_MESSAGE = b"mirobot-emulator: port busy: another client is connected\r\n"
REFUSED_LINGER_S = 2.0
"""A refused connection is closed by us this long after it connected if its client has not
closed it first (closing at once while its bytes are unread would reset it: the line lost)."""


@dataclass(slots=True)
class _Refusal:
    """A second client being told the port is busy."""

    tell_at: float  # when the busy line goes out, unless the client sends a byte first
    close_at: float  # when the connection is closed anyway
    told: bool = False


def socket_url(host: str, port: int) -> str:
    """``socket://HOST:PORT``, an IPv6 host in brackets."""
    shown = f"[{host}]" if ":" in host else host
    return f"socket://{shown}:{port}"


class TcpPort(Port):
    """A listening TCP socket serving one client connection at a time."""

    def __init__(self, host: str, port: int, log: Callable[[str], None] | None = None) -> None:
        self._host = host
        self._port = port
        self._log = log or (lambda message: None)
        self._listener: socket.socket | None = None
        self._conn: socket.socket | None = None
        self._open_since: float | None = None  # connected; the open not yet in effect
        self._refused: dict[socket.socket, _Refusal] = {}
        self.refused = 0
        """Connections refused because a client was already connected."""

    @property
    def is_open(self) -> bool:
        return self._listener is not None

    @property
    def has_client(self) -> bool:
        return self._conn is not None

    def open(self) -> str:
        """Bind and listen; return ``socket://HOST:PORT`` with the port actually bound."""
        infos = socket.getaddrinfo(
            self._host, self._port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
        )
        family, kind, proto, _, sockaddr = infos[0]
        listener = socket.socket(family, kind, proto)
        try:
            if hasattr(socket, "SO_REUSEADDR") and not hasattr(socket, "SO_EXCLUSIVEADDRUSE"):
                # POSIX: a port left in TIME_WAIT by an earlier run can be bound again
                # (Windows' SO_REUSEADDR would let two servers share a port: not set there).
                listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            listener.bind(sockaddr)
            listener.listen(8)
            listener.setblocking(False)
            port = listener.getsockname()[1]
        except BaseException:
            listener.close()
            raise
        self._listener = listener
        self.address = socket_url(self._host, port)
        return self.address

    def watches(self, read: bool, write: bool) -> dict[Any, int]:
        watched: dict[Any, int] = {}
        if self._listener is not None:
            watched[self._listener] = selectors.EVENT_READ  # always: refuse a second client
        for conn in self._refused:
            watched[conn] = selectors.EVENT_READ  # its bytes are dropped, its close seen
        if self._conn is not None:
            events = (selectors.EVENT_READ if read else 0) | (selectors.EVENT_WRITE if write else 0)
            if events:
                watched[self._conn] = events
        return watched

    def on_ready(self, fileobj: Any, events: int, room: int) -> Arrival:
        if fileobj is None:
            return Arrival()
        if fileobj is self._listener:
            return self._accept()
        if fileobj in self._refused:
            self._tell_busy(fileobj)  # it has sent a byte (or closed): its open is over
            self._drain_refused(fileobj)
            return Arrival()
        if fileobj is self._conn and events & selectors.EVENT_READ and room > 0:
            return self._receive(room)
        return Arrival()

    def _accept(self) -> Arrival:
        while self._listener is not None:
            try:
                conn, peer = self._listener.accept()
            except (BlockingIOError, InterruptedError):
                break
            except OSError as exc:  # e.g. the connection was reset before it was accepted
                self._log(f"accept failed: {exc}")
                break
            if self._conn is not None:
                self._refuse(conn, peer)
                continue
            conn.setblocking(False)
            with contextlib.suppress(OSError):
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._conn = conn
            self._open_since = time.monotonic()
        return Arrival()

    def poll(self, now: float) -> Arrival:
        for conn, refusal in list(self._refused.items()):
            if now >= refusal.close_at:
                self._close_refused(conn)
            elif now >= refusal.tell_at:
                self._tell_busy(conn)
        if self._open_since is not None and now >= self._open_since + OPEN_SETTLE_S:
            self._open_since = None
            return Arrival(opened=1)
        return Arrival()

    def next_time(self) -> float | None:
        times = [r.close_at if r.told else r.tell_at for r in self._refused.values()]
        if self._open_since is not None:
            times.append(self._open_since + OPEN_SETTLE_S)
        return min(times) if times else None

    def _refuse(self, conn: socket.socket, peer: Any) -> None:
        """A second client: told the port is busy once its open is over (as an open takes
        effect: pyserial flushes its input while opening), its stream then ended; closed when
        it closes (see :meth:`_drain_refused`) or after :data:`REFUSED_LINGER_S`."""
        self.refused += 1
        self._log(f"refused a connection from {_peer_text(peer)}: another client is connected")
        conn.setblocking(False)
        now = time.monotonic()
        self._refused[conn] = _Refusal(now + OPEN_SETTLE_S, now + REFUSED_LINGER_S)

    def _tell_busy(self, conn: socket.socket) -> None:
        refusal = self._refused.get(conn)
        if refusal is None or refusal.told:
            return
        refusal.told = True
        try:
            conn.send(BUSY_MESSAGE)  # a short line into an empty buffer: taken whole
            conn.shutdown(socket.SHUT_WR)
        except OSError:
            self._close_refused(conn)

    def _drain_refused(self, conn: socket.socket) -> None:
        """Drop what a refused client sent; close once it has closed (or failed)."""
        try:
            while conn.recv(READ_CHUNK):
                pass
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            pass
        self._close_refused(conn)

    def _close_refused(self, conn: socket.socket) -> None:
        self._refused.pop(conn, None)
        with contextlib.suppress(OSError):
            conn.close()

    def _receive(self, room: int) -> Arrival:
        assert self._conn is not None
        try:
            data = self._conn.recv(min(room, READ_CHUNK))
        except (BlockingIOError, InterruptedError):
            return Arrival()
        except OSError as exc:
            self._drop(f"connection lost: {exc}")
            return Arrival(closed=True)
        if not data:
            self._drop(None)  # the client closed the connection: nothing to report
            return Arrival(closed=True)
        opened = 0 if self._open_since is None else 1
        self._open_since = None
        return Arrival(opened=opened, data=data)

    def _drop(self, reason: str | None) -> None:
        if self._conn is not None:
            if reason:
                self._log(reason)
            conn, self._conn = self._conn, None
            self._open_since = None
            conn.close()

    def write(self, data: bytes | bytearray) -> int:
        if self._conn is None:
            return 0
        try:
            return self._conn.send(data)
        except (BlockingIOError, InterruptedError):
            return 0
        except OSError as exc:
            self._drop(f"connection lost: {exc}")
            return 0

    def hang_up(self) -> None:
        """Close the connection and stop listening: the client sees the link end."""
        self.close()

    def close(self) -> None:
        for conn in list(self._refused):
            self._close_refused(conn)
        for sock in (self._conn, self._listener):
            if sock is not None:
                with contextlib.suppress(OSError):
                    sock.close()
        self._conn = None
        self._listener = None


def _peer_text(peer: Any) -> str:
    if isinstance(peer, tuple) and len(peer) >= 2:
        return f"{peer[0]}:{peer[1]}"
    return str(peer)
