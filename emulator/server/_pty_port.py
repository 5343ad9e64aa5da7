"""The emulator's serial port as a pseudo-terminal (POSIX only; imported only in pty mode).

The slave is put in raw mode right after ``openpty`` (a new pty is cooked: echo, ICANON,
ONLCR/ICRNL would translate line endings and echo commands back). The emulator keeps its own
slave fd open, so clients can close and reopen the port, and the robot state survives.

**Opens.** A pty does not tell its master when the slave is opened, but every serial library
configures the port when it opens it (pyserial: ``tcsetattr``, then ``tcflush(TCIFLUSH)``). The
master is in packet mode (``TIOCPKT``) and the slave has ``EXTPROC`` set, so each ``tcsetattr``
reaches the master as ``TIOCPKT_IOCTL`` and each input flush as ``TIOCPKT_FLUSHREAD``. A
configuration is taken as "the port was opened"; the open takes effect (for ``--reset-on-open``)
at the flush that follows it, so that the banner printed by the reset is not flushed away, or
at the client's first byte, or :data:`OPEN_SETTLE_S` later, whichever comes first. A flush
without a configuration (the vendor's newer SDK flushes before each status poll) is not an
open. Where ``EXTPROC`` is unknown (neither Linux nor BSD/macOS) every flush counts as an open;
without packet mode at all (no ``TIOCPKT``) opens are not seen.
"""

from __future__ import annotations

import array
import errno
import os
import selectors
import struct
import sys
import time
from typing import Any

try:
    import fcntl
    import termios
    import tty
except ImportError:  # not POSIX: the pty mode is not offered there, the TCP mode is
    pass

import contextlib

from ._port import OPEN_SETTLE_S, READ_CHUNK, Arrival, Port

__all__ = ["PtyPort", "pty_available"]

EIO_RETRY_S = 0.05  # no slave open at all (after a close fault): look again this much later
TIOCPKT_FLUSHREAD = 0x01  # the same on Linux and the BSDs
TIOCPKT_IOCTL = 0x40


def pty_available() -> bool:
    """True where pseudo-terminals can be served (POSIX with ``termios``)."""
    return hasattr(os, "openpty") and "termios" in globals()


def _extproc_flag() -> int | None:
    """The ``EXTPROC`` local-mode bit of this platform (the termios module does not export it)."""
    if sys.platform.startswith("linux"):
        return 0o200000
    if sys.platform == "darwin" or "bsd" in sys.platform:
        return 0x800
    return None


class PtyPort(Port):
    """A pseudo-terminal: the master is served, the slave's path is published."""

    def __init__(self, log: Any = None) -> None:
        self._log = log or (lambda message: None)
        self._master = -1
        self._slave = -1
        self._packet = False  # packet mode: control bytes tell flushes and termios changes
        self._sees_configs = False  # EXTPROC set: termios changes are reported
        self._open_since: float | None = None  # a configuration seen, its flush not yet
        self._eio_until = -float("inf")

    @property
    def is_open(self) -> bool:
        return self._master >= 0

    def open(self) -> str:
        """Create the pty in raw (and, where possible, packet) mode; return the slave's path."""
        if not pty_available():
            raise OSError("no pseudo-terminals on this platform: serve on TCP (--listen)")
        master, slave = os.openpty()
        try:
            tty.setraw(slave)  # before packet mode: the termios changes must not make packets
            extproc = _extproc_flag()
            tiocpkt = getattr(termios, "TIOCPKT", None)
            if tiocpkt is not None:
                if extproc is not None:
                    attrs = termios.tcgetattr(slave)
                    attrs[3] |= extproc
                    termios.tcsetattr(slave, termios.TCSANOW, attrs)
                    self._sees_configs = bool(termios.tcgetattr(slave)[3] & extproc)
                fcntl.ioctl(master, tiocpkt, struct.pack("i", 1))
                self._packet = True
            os.set_blocking(master, False)
            os.set_inheritable(master, False)
            os.set_inheritable(slave, False)
            path = os.ttyname(slave)
        except BaseException:
            os.close(master)
            os.close(slave)
            raise
        self._master, self._slave = master, slave
        self.address = path
        return path

    @property
    def sees_opens(self) -> bool:
        """True when clients opening the port can be told apart (see the module docstring)."""
        return self._packet

    def watches(self, read: bool, write: bool) -> dict[Any, int]:
        if self._master < 0 or time.monotonic() < self._eio_until:
            return {}  # (no slave open: the master would report a hangup at once)
        events = selectors.EVENT_READ if read else 0
        if write:
            events |= selectors.EVENT_WRITE
        return {self._master: events} if events else {}

    def on_ready(self, fileobj: Any, events: int, room: int) -> Arrival:
        if events & selectors.EVENT_READ and room > 0:
            return self._read(room)
        return Arrival()

    def _read(self, room: int) -> Arrival:
        try:
            packet = os.read(self._master, min(room, READ_CHUNK) + self._packet)
        except BlockingIOError:
            return Arrival()
        except OSError as exc:
            if exc.errno == errno.EIO:  # no slave open: nobody to read from
                self._eio_until = time.monotonic() + EIO_RETRY_S
                return Arrival()
            raise
        if not packet:
            return Arrival()
        if not self._packet:
            return Arrival(data=packet)
        control, data = packet[0], packet[1:]
        arrival = Arrival(data=data)
        if control & TIOCPKT_IOCTL and self._open_since is None:
            self._open_since = time.monotonic()
        if control & TIOCPKT_FLUSHREAD and (self._open_since is not None or not self._sees_configs):
            arrival.opened = 1
            self._open_since = None
        if data and self._open_since is not None:
            arrival.opened = 1
            self._open_since = None
        return arrival

    def poll(self, now: float) -> Arrival:
        if self._open_since is not None and now >= self._open_since + OPEN_SETTLE_S:
            self._open_since = None
            return Arrival(opened=1)
        return Arrival()

    def next_time(self) -> float | None:
        times = [t for t in (self._eio_until,) if t > time.monotonic()]
        if self._open_since is not None:
            times.append(self._open_since + OPEN_SETTLE_S)
        return min(times) if times else None

    def write(self, data: bytes | bytearray) -> int:
        if self._master < 0:
            return 0
        try:
            return os.write(self._master, data)
        except BlockingIOError:
            return 0
        except OSError as exc:
            if exc.errno == errno.EIO:  # no slave open: keep the bytes, retry a bit later
                self._eio_until = time.monotonic() + EIO_RETRY_S
                return 0
            raise

    def unread(self) -> int | None:
        """Bytes waiting in the port for the client to read (``FIONREAD`` on our slave fd)."""
        if self._slave < 0:
            return None
        count = array.array("i", [0])
        try:
            fcntl.ioctl(self._slave, termios.FIONREAD, count)
        except OSError:
            return None
        return count[0]

    def hang_up(self) -> None:
        """Close the master (clients see a hangup)."""
        self.close()

    def close(self) -> None:
        for name in ("_master", "_slave"):
            fd = getattr(self, name)
            if fd >= 0:
                setattr(self, name, -1)
                with contextlib.suppress(OSError):
                    os.close(fd)
