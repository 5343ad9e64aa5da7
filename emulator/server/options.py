"""What the server is asked to do (:class:`ServerOptions`) and what it needs of a firmware model."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

from .._faults import Fault

__all__ = ["BUS_BAUDS", "DEFAULT_LISTEN_HOST", "FirmwareLike", "ServerOptions", "parse_listen"]

DEFAULT_LISTEN_HOST = "127.0.0.1"
"""``--listen PORT`` binds here: the loopback only, unless the user names another address."""

BUS_BAUDS = (4800, 9600, 38400, 57600, 115200)
"""The bauds a multi-function controller's RS485 port runs at (EXBOX.md, ``O141``)."""


class FirmwareLike(Protocol):
    """What the server needs of :class:`mirobot_emulator.firmware.Firmware`.

    The server also reads, when present, the optional public attributes ``motion_end_times``,
    ``motion_ends`` (ends of motion), ``rx_lost`` (bytes the receive ring lost) and the
    planner's starvation counter (see :mod:`mirobot_emulator.server._control`).
    """

    @property
    def now(self) -> float: ...

    def receive(self, data: bytes) -> None: ...

    def advance(self, dt: float) -> None: ...  # dt may be math.inf: until nothing changes

    def read_output(self) -> bytes: ...

    def next_deadline(self) -> float | None: ...

    def reset(self) -> None: ...

    def trigger_hard_limit(self, axis: int = 1) -> None: ...


@dataclass(frozen=True, slots=True)
class ServerOptions:
    """The command-line options of ``mirobot-emulator`` (see ``--help``).

    ``listen`` is ``(host, port)`` to serve on TCP instead of a pty (port 0: the OS picks one).
    ``bus`` > 0 serves an RS485 bus of that many controllers (addresses 1..bus), each with an
    arm of ``firmware`` (:class:`mirobot_emulator.bus.Bus`), at ``bus_baud``, with the
    ``KEY=VALUE`` readings of ``bus_options`` (:class:`mirobot_emulator.bus.BusOptions`).
    """

    firmware: str = "2021"
    time_scale: float = 1.0
    link: str | None = None
    baud: int | None = None
    reset_on_open: bool = False
    usb_latency_ms: float = 0.0
    seed: int = 0
    faults: tuple[Fault, ...] = field(default_factory=tuple)
    homing_seconds: float | None = None
    listen: tuple[str, int] | None = None
    bus: int = 0
    bus_baud: int = 38400
    bus_options: tuple[str, ...] = ()

    def check(self) -> None:
        """Raise :class:`ValueError` naming the first option that cannot be served."""
        if self.time_scale < 0 or not math.isfinite(self.time_scale):
            raise ValueError("time_scale must be a finite number >= 0")
        if self.baud is not None and self.baud <= 0:
            raise ValueError("baud must be positive")
        if not self.usb_latency_ms >= 0:
            raise ValueError("usb_latency_ms must be >= 0")
        if self.listen is not None:
            host, port = self.listen
            if not host or not 0 <= port <= 65535:
                raise ValueError(f"listen={self.listen!r}: expected (host, port 0..65535)")
            if self.link:
                raise ValueError("link is a pty symlink: it cannot be combined with listen")
        self._check_bus()

    def _check_bus(self) -> None:
        if not 0 <= self.bus <= 99:
            raise ValueError(f"bus={self.bus}: a bus has 1..99 controllers (0: no bus)")
        if not self.bus:
            return
        if self.bus_baud not in BUS_BAUDS:
            raise ValueError(f"bus_baud={self.bus_baud}: a controller runs at one of {BUS_BAUDS}")
        if self.reset_on_open:
            # reset() on a bus power-cycles every node: no single arm's DTR does that
            raise ValueError("reset_on_open cannot be combined with bus")
        from ..bus import BusOptions  # imported here: the bus package pulls in the firmware

        BusOptions.parse(self.bus_options)  # raises ValueError naming a bad option


def parse_listen(text: str) -> tuple[str, int]:
    """``HOST:PORT``, ``[IPV6]:PORT`` or ``PORT`` (on :data:`DEFAULT_LISTEN_HOST`) -> (host, port).

    Raises :class:`ValueError` with the reason.
    """
    text = text.strip()
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host, port_text = DEFAULT_LISTEN_HOST, text
    elif host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    elif ":" in host:
        raise ValueError(f"{text!r}: write an IPv6 address in brackets, e.g. [::1]:0")
    if not host:
        host = DEFAULT_LISTEN_HOST
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"{text!r}: expected HOST:PORT with a port number") from None
    if not 0 <= port <= 65535:
        raise ValueError(f"{text!r}: the port must be in 0..65535 (0: any free port)")
    return host, port
