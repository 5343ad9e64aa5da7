"""What the serve loop needs of a port (a pty or a TCP socket), and what a read brings."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

__all__ = ["OPEN_SETTLE_S", "READ_CHUNK", "Arrival", "Port"]

READ_CHUNK = 1024
"""Bytes read from the port at most at once: each input byte can make output (a ``?`` makes a
status line of ~170 bytes), so a read is kept small enough for the output it can cause."""
OPEN_SETTLE_S = 0.05
"""A client that opened the port is given this long to flush its input (pyserial does at open)
before the open takes effect (``--reset-on-open``: the banner would be flushed away), unless it
sends a byte first."""


@dataclass(slots=True)
class Arrival:
    """What came in through the port: opens, bytes from the client, a client gone."""

    opened: int = 0
    """Clients that opened the port (now is the moment a DTR-line reset would take effect)."""
    data: bytes = b""
    """Bytes from the client, after the opens."""
    closed: bool = False
    """The client went away (TCP): bytes on their way to it are lost."""

    def __bool__(self) -> bool:
        return bool(self.opened or self.data or self.closed)


class Port(ABC):
    """A serial-port-like endpoint the emulator serves; non-blocking, driven by a selector.

    The loop asks :meth:`watches` which file objects to watch for which events, hands the ready
    ones to :meth:`on_ready`, calls :meth:`poll` at each step for timed events, and writes with
    :meth:`write` (which never blocks).
    """

    address: str | None = None
    """What clients open (a device path or a ``socket://`` URL); set by :meth:`open`."""

    @abstractmethod
    def open(self) -> str:
        """Create the endpoint; return its address."""

    @abstractmethod
    def watches(self, read: bool, write: bool) -> dict[Any, int]:
        """File objects to watch -> selector events, given whether input and output are wanted."""

    @abstractmethod
    def on_ready(self, fileobj: Any, events: int, room: int) -> Arrival:
        """A watched file object is ready; read at most ``room`` bytes of client data.

        ``fileobj`` None: look for input that may have come before the loop started.
        """

    def poll(self, now: float) -> Arrival:
        """Timed events due at ``now`` (none by default)."""
        return Arrival()

    def next_time(self) -> float | None:
        """When :meth:`poll` has something to do (None: nothing timed)."""
        return None

    @abstractmethod
    def write(self, data: bytes | bytearray) -> int:
        """Write without blocking; return the bytes taken (0: try again later)."""

    def unread(self) -> int | None:
        """Bytes written but not yet read by the client (None: the port cannot tell)."""
        return None

    @property
    def has_client(self) -> bool:
        """False when nobody can receive output (it is then lost, as on an unplugged cable)."""
        return True

    @property
    @abstractmethod
    def is_open(self) -> bool:
        """True from :meth:`open` until :meth:`hang_up` or :meth:`close`."""

    @abstractmethod
    def hang_up(self) -> None:
        """The cable is pulled: clients see the link end; the port serves no more."""

    @abstractmethod
    def close(self) -> None:
        """Release everything (idempotent)."""
