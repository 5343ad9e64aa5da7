"""The serial link: a pyserial URL opened as an asyncio transport (the client's only I/O).

:class:`SerialLink` opens any pyserial URL (a device such as ``/dev/ttyUSB0``, a pty path,
``socket://host:port``, ``loop://``) at 115200 baud 8N1 without flow control, hands every received
chunk of bytes to a callback and reports the end of the link exactly once to another. It knows
nothing about lines or replies: the client feeds the bytes to the sans-IO state machine.

Implementation: ``serial_asyncio_fast`` (pyserial-asyncio-fast), the maintained, API-compatible
fork of pyserial-asyncio. The original ``serial_asyncio`` can be chosen with
``implementation="original"`` (for the benchmark that compares them); its close path calls
``tcdrain`` on the event loop, which can block for as long as the peer does not read, so this
module discards unsent output before closing it. URLs whose pyserial object has no file
descriptor (``loop://``) are served by a small polling transport.

Guarantees:

* Opening fails at once with :class:`~mirobot_async.errors.MirobotConnectionError` quoting the
  operating system's words (missing path, busy port, refused socket). A network server that
  accepts the connection and then says it is busy (our emulator, ser2net) ends the link with
  such an error, quoting the server's words, passed to ``on_lost`` (:func:`refusal_error`).
* :meth:`SerialLink.write` never blocks: bytes the OS cannot take now are buffered by the
  transport (the client never has more than a few hundred bytes outstanding).
* End of file, an I/O error or the peer going away calls ``on_lost`` exactly once, promptly
  (a pty whose other side is closed reports it within a millisecond), and only that: nothing
  reaches the event loop's exception handler (no "Fatal write error on serial transport", no
  "Task exception was never retrieved" from a second clean-up; see :class:`_EndOnce`).
* :meth:`SerialLink.close` is idempotent and bounded: unsent output is discarded, and waiting for
  the transport to finish is limited by a timeout.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import functools
import logging
import os
import socket
import urllib.parse
from collections.abc import Callable
from typing import Any, Literal

import serial
from serial.urlhandler import protocol_socket

from mirobot_async.errors import MirobotConnectionError, MirobotUsageError

__all__ = ["DEFAULT_BAUDRATE", "Implementation", "SerialLink", "refusal_error"]

_log = logging.getLogger("mirobot_async.transport")

DEFAULT_BAUDRATE = 115200
"""The Mirobot's fixed line speed (8 data bits, no parity, 1 stop bit, no flow control)."""

Implementation = Literal["fast", "original"]
"""``"fast"``: pyserial-asyncio-fast (default); ``"original"``: pyserial-asyncio 0.6."""

DataCallback = Callable[[bytes], None]
LostCallback = Callable[[BaseException | None], None]


_REFUSAL_LIMIT = 256
"""A server's refusal is one short line then the end of the stream: bytes seen at most."""
_NETWORK_SCHEMES = ("socket", "rfc2217")


def refusal_error(url: str, received: bytes) -> MirobotConnectionError | None:
    """The error for a network server that said it is busy and ended the stream, or ``None``.

    ``received``: every byte the link brought before it ended. Our emulator says
    ``mirobot-emulator: port busy: another client is connected``; ser2net
    ``Port already in use``. The server's words are quoted, as the OS's are for a local port.
    """
    if urllib.parse.urlparse(url).scheme not in _NETWORK_SCHEMES:
        return None
    if not received or len(received) >= _REFUSAL_LIMIT:
        return None
    words = received.decode("ascii", "replace").strip()
    if not words or "\n" in words or "\r" in words:
        return None
    lowered = words.lower()
    if "busy" not in lowered and "in use" not in lowered:
        return None
    return MirobotConnectionError(
        f"could not open {url!r}: it is in use by another program "
        f"(could not lock it: the server says {words!r})"
    )


class _LinkProtocol(asyncio.Protocol):
    """Forwards bytes and the end of the link to the owner's callbacks (end reported once).

    A link that ends having brought only a server's "busy" line (:func:`refusal_error`) is
    reported to ``on_lost`` with that :class:`MirobotConnectionError`.
    """

    def __init__(self, url: str, on_data: DataCallback, on_lost: LostCallback) -> None:
        self._url = url
        self._on_data = on_data
        self._on_lost = on_lost
        self._ended = False
        self._head = bytearray()  # the first bytes received (up to _REFUSAL_LIMIT)
        self.lost: asyncio.Future[None] = asyncio.get_running_loop().create_future()

    def data_received(self, data: bytes) -> None:
        if not self._ended and data:
            if len(self._head) < _REFUSAL_LIMIT:
                self._head += data[: _REFUSAL_LIMIT - len(self._head)]
            self._on_data(data)

    def eof_received(self) -> bool:
        # Sockets: the peer closed its side. Returning False lets the transport close itself,
        # which then calls connection_lost(None).
        self._end(None)
        return False

    def connection_lost(self, exc: Exception | None) -> None:
        self._end(exc)
        if not self.lost.done():
            self.lost.set_result(None)

    def _end(self, exc: BaseException | None) -> None:
        if not self._ended:
            self._ended = True
            self._on_lost(refusal_error(self._url, bytes(self._head)) or exc)


class _PolledSerialTransport(asyncio.Transport):
    """A minimal transport for pyserial objects without a file descriptor (``loop://``,
    ``rfc2217://``).

    Reads are polled every millisecond (each poll drains everything waiting); writes go straight
    to the object (these URL handlers buffer in memory or in a socket and do not block).
    """

    POLL_INTERVAL = 0.001
    MAX_READ = 65536  # bytes per poll at most, so a fast peer cannot hold the event loop

    def __init__(
        self, loop: asyncio.AbstractEventLoop, protocol: asyncio.Protocol, port: Any
    ) -> None:
        super().__init__()
        self._loop = loop
        self._protocol = protocol
        self._serial: Any = port
        self._closing = False
        self._timer: asyncio.TimerHandle | None = None
        port.timeout = 0
        loop.call_soon(protocol.connection_made, self)
        loop.call_soon(self._poll)

    def _poll(self) -> None:
        if self._closing:
            return
        data = bytearray()
        try:
            # timeout=0: read() never blocks. rfc2217:// returns at most one byte per read(), so
            # drain what is waiting; reading even when nothing waits lets rfc2217:// raise
            # "reader thread died" once its socket has closed (its end-of-link marker is
            # consumed by this read, so it must not be skipped).
            while len(data) < self.MAX_READ and (
                chunk := self._serial.read(max(self._serial.in_waiting, 1))
            ):
                data += chunk
        except (serial.SerialException, OSError) as exc:
            if data:
                self._protocol.data_received(bytes(data))
            self._shutdown(exc)
            return
        if data:
            self._protocol.data_received(bytes(data))
        if not self._closing:
            self._timer = self._loop.call_later(self.POLL_INTERVAL, self._poll)

    def write(self, data: bytes | bytearray | memoryview) -> None:
        if self._closing:
            return
        try:
            self._serial.write(bytes(data))
        except (serial.SerialException, OSError) as exc:
            self._shutdown(exc)

    def is_closing(self) -> bool:
        return self._closing

    def close(self) -> None:
        self._shutdown(None)

    def abort(self) -> None:
        self._shutdown(None)

    def get_write_buffer_size(self) -> int:
        return 0

    def get_extra_info(self, name: str, default: Any = None) -> Any:
        return self._serial if name == "serial" else default

    def _shutdown(self, exc: BaseException | None) -> None:
        if self._closing:
            return
        self._closing = True
        if self._timer is not None:
            self._timer.cancel()
        with contextlib.suppress(Exception):
            self._serial.close()
        self._loop.call_soon(self._protocol.connection_lost, _as_exception(exc))


class _SocketSerial(protocol_socket.Serial):
    """pyserial's ``socket://`` port, mended for pyserial-asyncio (``implementation="original"``;
    the fast one uses asyncio's own socket transport for ``socket://``).

    * pyserial 3.5's ``read`` drops the bytes it has already received when the end of the
      stream follows them in the same call (a server's last words before it closes, such as
      "port busy"): a non-blocking read here returns them, and the end comes with the next.
    * Its ``open`` discards what the server sent at once (a flush meant for a serial port's
      stale input; a new connection has none): the server's first words are kept.
    * Its ``close`` skips closing the socket when ``shutdown()`` fails (it does once the peer
      has reset the connection: a leaked socket, a ``ResourceWarning``), then sleeps 0.3 s "for
      quick reconnects", on the event loop when pyserial-asyncio closes it.
    """

    _opening = False

    def open(self) -> None:
        self._opening = True
        try:
            super().open()
        finally:
            self._opening = False

    def reset_input_buffer(self) -> None:
        if not self._opening:
            super().reset_input_buffer()

    def read(self, size: int = 1) -> bytes:
        sock: socket.socket | None = getattr(self, "_socket", None)
        if sock is None or self.timeout != 0:
            return super().read(size)  # closed (pyserial raises), or a blocking read
        try:
            data = sock.recv(size)  # the socket is non-blocking (pyserial's open sets it)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as exc:
            raise serial.SerialException(f"read failed: {exc}") from exc
        if not data:
            raise serial.SerialException("socket disconnected")
        return data

    def close(self) -> None:
        sock: socket.socket | None = getattr(self, "_socket", None)
        self._socket = None
        self.is_open = False
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)  # fails once the peer has reset the connection
            sock.close()


def _open_port(url: str, **serial_kwargs: Any) -> Any:
    """The pyserial object for ``url`` (blocking: run in a thread)."""
    if urllib.parse.urlparse(url).scheme == "socket":
        return _SocketSerial(url, **serial_kwargs)
    return serial.serial_for_url(url, **serial_kwargs)


class _EndOnce:
    """Mixed into ``serial_asyncio(_fast).SerialTransport``: the end of the link is quiet and once.

    * A write or read error on a serial port (the device unplugged, the emulator killed) is the
      end of the link, reported to the protocol's ``connection_lost`` as asyncio's own socket
      transports do, not also to the event loop's exception handler ("Fatal write error on
      serial transport" with a traceback in the user's log).
    * The connection-lost clean-up is scheduled at most once. The libraries schedule it from
      ``_close`` (read error), ``_abort`` (write error, ``abort()``) and again when flushing
      after ``_close``; a second run fails in a background task ("Task exception was never
      retrieved ... 'NoneType' object has no attribute 'connection_lost'").
    """

    _end_scheduled = False

    def _fatal_error(
        self, exc: BaseException, message: str = "Fatal error on serial transport"
    ) -> None:
        if isinstance(exc, OSError):  # serial.SerialException is an OSError too
            _log.debug("%s: %s", message, exc)
            self._abort(exc)
            return
        super()._fatal_error(exc, message)  # type: ignore[misc]

    def _close(self, exc: BaseException | None = None) -> None:
        if self._end_scheduled:
            return
        if self._flushed():  # type: ignore[attr-defined]  # then _close schedules the end
            self._end_scheduled = True
        super()._close(exc)  # type: ignore[misc]

    def _abort(self, exc: BaseException | None) -> None:
        if self._end_scheduled:
            return
        self._end_scheduled = True
        super()._abort(exc)  # type: ignore[misc]


@functools.cache
def _transport_class(base: type[asyncio.Transport]) -> Callable[..., asyncio.Transport]:
    """``base`` (a pyserial-asyncio SerialTransport class) with :class:`_EndOnce` mixed in."""
    cls: Callable[..., asyncio.Transport] = type(f"_Guarded{base.__name__}", (_EndOnce, base), {})
    return cls


def _as_exception(exc: BaseException | None) -> Exception | None:
    if exc is None or isinstance(exc, Exception):
        return exc
    return RuntimeError(str(exc))


def _os_words(exc: BaseException) -> tuple[int, str] | None:
    """``(errno, the OS's text)`` of an OS-level error (``OSError``, ``termios.error``)."""
    if isinstance(exc, OSError) and isinstance(exc.errno, int):
        try:
            return exc.errno, os.strerror(exc.errno)
        except ValueError:  # pragma: no cover - an errno the OS does not know
            return exc.errno, str(exc.strerror or exc)
    args = exc.args
    if len(args) == 2 and isinstance(args[0], int) and isinstance(args[1], str):
        return args[0], args[1]  # termios.error(25, 'Inappropriate ioctl for device')
    return None


def _open_error_text(url: str, exc: BaseException) -> str:
    """One sentence: which URL could not be opened and why, quoting the OS's words once.

    pyserial wraps the OS's error in its own text that repeats it (``[Errno 2] could not open
    port /dev/x: [Errno 2] No such file or directory: '/dev/x'``): the innermost OS error of the
    exception chain gives the words, pyserial's own text only the stage that failed.
    """
    chain: list[BaseException] = []
    current: BaseException | None = exc
    while current is not None and current not in chain:
        chain.append(current)
        current = current.__cause__ or current.__context__
    found = next((w for w in map(_os_words, reversed(chain)) if w is not None), None)
    outer = str(exc).strip()
    lowered = outer.lower()
    if "could not exclusively lock" in lowered:
        stage = "it is in use by another program (could not lock it"
    elif "could not configure port" in lowered:
        stage = "it is not a serial port (could not configure it"
    else:
        stage = None
    if found is None:
        return f"could not open {url!r}: {outer or type(exc).__name__}"
    code, words = found
    name = errno.errorcode.get(code)
    words = f"{words} ({name})" if name else words
    if stage is not None:
        return f"could not open {url!r}: {stage}: {words})"
    return f"could not open {url!r}: {words}"


def _close_port(port: Any) -> None:
    """Close a port that no transport owns (opening failed after the OS opened it)."""
    try:
        port.close()
    except Exception:  # pragma: no cover - best effort
        _log.debug("could not close a port left over by a failed open", exc_info=True)


def _close_opened_port(opening: asyncio.Future[Any]) -> None:
    """Done-callback of an open nobody waits for any more: close the port if it was opened."""
    if opening.cancelled() or opening.exception() is not None:
        return  # nothing opened (the exception is retrieved: it was already reported)
    _log.debug("closing a port opened after its caller gave up")
    _close_port(opening.result())


class SerialLink:
    """One open serial link. Create it with :meth:`open`; never blocks the event loop."""

    def __init__(
        self,
        url: str,
        transport: asyncio.BaseTransport,
        protocol: _LinkProtocol,
        implementation: Implementation,
    ) -> None:
        self.url = url
        self.implementation: Implementation = implementation
        self._transport = transport
        self._protocol = protocol
        self._closed = False
        self.bytes_written = 0
        self.baudrate = DEFAULT_BAUDRATE

    @classmethod
    async def open(
        cls,
        url: str,
        *,
        on_data: DataCallback,
        on_lost: LostCallback,
        implementation: Implementation = "fast",
        baudrate: int = DEFAULT_BAUDRATE,
        exclusive: bool = True,
        timeout: float = 5.0,
    ) -> SerialLink:
        """Open ``url`` and start delivering received bytes to ``on_data``.

        ``on_lost(exc)`` is called exactly once when the link ends by itself (end of file, I/O
        error: ``exc`` is the error or ``None``) or is closed by :meth:`close`.

        ``exclusive`` (default) locks a device against a second opener (POSIX ``flock``, as
        pyserial's ``exclusive=True``): two programs writing to one arm would corrupt each
        other's replies, so a second client fails at once instead.

        Raises :class:`MirobotConnectionError` with the OS's words when the port cannot be opened
        (at once for a missing path or a busy port; after ``timeout`` seconds if opening hangs),
        :class:`MirobotUsageError` for an unknown ``implementation``. Cancellation while opening
        closes whatever was opened.
        """
        if implementation == "fast":
            import serial_asyncio_fast as impl
        elif implementation == "original":
            import serial_asyncio as impl  # type: ignore[import-untyped,no-redef]
        else:
            raise MirobotUsageError(
                f"implementation={implementation!r} must be 'fast' or 'original'"
            )
        if not isinstance(url, str) or not url:
            raise MirobotUsageError(f"url={url!r} must be a non-empty string")
        loop = asyncio.get_running_loop()
        serial_kwargs: dict[str, Any] = {
            "baudrate": baudrate,
            "bytesize": serial.EIGHTBITS,
            "parity": serial.PARITY_NONE,
            "stopbits": serial.STOPBITS_ONE,
            "xonxoff": False,
            "rtscts": False,
            "dsrdtr": False,
        }
        if exclusive and "://" not in url:
            serial_kwargs["exclusive"] = True
        protocol = _LinkProtocol(url, on_data, on_lost)
        transport: asyncio.BaseTransport
        try:
            async with asyncio.timeout(timeout):
                if implementation == "fast" and urllib.parse.urlparse(url).scheme == "socket":
                    # asyncio's own socket transport (pyserial-asyncio 0.6 would wrap the socket
                    # in its serial transport, unguarded: the generic path below guards it)
                    transport, _ = await impl.create_serial_connection(
                        loop, lambda: protocol, url, **serial_kwargs
                    )
                else:
                    opening = loop.run_in_executor(
                        None, functools.partial(_open_port, url, **serial_kwargs)
                    )
                    try:
                        # shielded: if this wait is cancelled (or times out) while the OS is
                        # still opening, the port it opens is closed (not leaked) once it is open
                        port = await asyncio.shield(opening)
                    except BaseException:
                        opening.add_done_callback(_close_opened_port)
                        raise
                    try:
                        try:
                            port.fileno()
                        except (AttributeError, serial.SerialException, OSError):
                            transport = _PolledSerialTransport(loop, protocol, port)
                        else:
                            # impl.connection_for_serial(), with the end of the link made quiet
                            transport = _transport_class(impl.SerialTransport)(loop, protocol, port)
                    except BaseException:
                        _close_port(port)
                        raise
        except TimeoutError as err:
            raise MirobotConnectionError(
                f"could not open {url!r}: no answer from the OS within {timeout:g} s"
            ) from err
        except (serial.SerialException, OSError, ValueError) as err:
            raise MirobotConnectionError(_open_error_text(url, err)) from err
        _log.debug("opened %s with %s", url, implementation)
        link = cls(url, transport, protocol, implementation)
        link.baudrate = baudrate
        return link

    @property
    def is_closing(self) -> bool:
        """True once the link is closing or closed (writes are then ignored)."""
        return self._closed or self._transport.is_closing()

    @property
    def write_buffer_size(self) -> int:
        """Bytes accepted by :meth:`write` that the OS has not taken yet."""
        transport = self._transport
        if isinstance(transport, asyncio.WriteTransport):
            return transport.get_write_buffer_size()
        return 0

    def write(self, data: bytes) -> None:
        """Queue ``data`` for writing; never blocks. Ignored once the link is closing."""
        if self.is_closing:
            return
        transport = self._transport
        assert isinstance(transport, asyncio.WriteTransport)
        self.bytes_written += len(data)
        transport.write(data)

    def abort(self) -> None:
        """Close at once, discarding unsent output (synchronous; see :meth:`close`)."""
        if self._closed:
            return
        self._closed = True
        transport = self._transport
        # Also when the transport is already closing itself (end of file, I/O error): our
        # serial transports (_EndOnce) run their clean-up once, so this cannot run it twice.
        port = transport.get_extra_info("serial")
        if port is not None and self.implementation == "original":
            # pyserial-asyncio 0.6 runs tcdrain() on the event loop while closing: make sure
            # there is nothing left to drain, or it blocks until the peer reads.
            with contextlib.suppress(Exception):
                port.reset_output_buffer()
        if isinstance(transport, asyncio.Transport):
            transport.abort()
        else:  # pragma: no cover - every transport here is an asyncio.Transport
            transport.close()

    async def close(self, timeout: float = 1.0) -> None:
        """Close the link; idempotent, never hangs.

        Unsent output is discarded (a closing client has already failed its pending calls).
        Waits at most ``timeout`` seconds for the transport to release the port, then returns
        anyway. Cancellation is honoured (the port is still released in the background).
        """
        self.abort()
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(timeout):
                await asyncio.shield(self._protocol.lost)
