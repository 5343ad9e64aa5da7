"""The readings of the controller protocol that the sources disagree on, as options.

Each field is one CONFLICT or INFERRED point of ``EXBOX.md``; the default is named in its
docstring with the reason. ``BusOptions.parse(["o103=number", ...])`` builds one from
``KEY=VALUE`` strings (what a ``--bus-option`` command-line flag would collect).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

__all__ = ["BAUD_CODES", "DEFAULT_BUS_BAUD", "BusOptions"]

DEFAULT_BUS_BAUD = 38400
"""Every vendor example opens the bus at 38400 (EXBOX 1, "in practice"); the factory default is
INFERRED from that."""

BAUD_CODES: dict[int, int] = {0: 4800, 1: 9600, 2: 38400, 3: 57600, 4: 115200}
"""``O141`` codes (manual p.36)."""

_CHOICES: dict[str, tuple[str, ...]] = {
    "o103": ("word", "number"),
    "o105": ("homing", "repeat"),
    "o105_reply": ("ok", "relay"),
    "o110": ("list", "lines"),
    "query_ok": ("gpio", "always", "never"),
    "gpio": ("sdk", "manual"),
    "version": ("both", "exbox", "forward"),
    "o117": ("finish", "reset"),
    "broadcast": ("ignore", "execute"),
}


@dataclass(frozen=True, slots=True)
class BusOptions:
    """How the emulated controllers read the points the sources disagree on (EXBOX.md)."""

    o103: str = "word"
    """``O103`` reply: ``word`` = ``State,<Word>,<n>`` (default: satisfies both word-parsing
    clients, ARD and MB, EXBOX 3.2) or ``number`` = the manual's bare ``n`` (0..5)."""
    o105: str = "homing"
    """``O105``: ``homing`` (default: every client since 2023, modes 0..10) or ``repeat`` (the
    2021 manual's "repeat run" flag)."""
    o105_reply: str = "ok"
    """Homing by ``O105``: ``ok`` at once from the controller, the arm's own reply consumed
    (default: SIM and the checklist) or ``relay`` (the arm's ``Info, in homing moving...ok``)."""
    o110: str = "list"
    """``O110`` file list: ``list`` = one line ``["test","work"]`` (default: the manual's
    example) or ``lines`` = one name per line."""
    query_ok: str = "gpio"
    """``ok`` after a query's value line: ``gpio`` = only after the GPIO queries, the only ones a
    client reads as two lines (default: satisfies the SDK and the manual's ``o150?`` screenshot),
    ``always`` (SIM) or ``never`` (the manual's table)."""
    gpio: str = "sdk"
    """``O130``-``O134``: ``sdk`` = four fields ``A0,A1,D0,D1`` (default: wlkatapython, SIM) or
    ``manual`` = ``<pin>/<mode>/...`` and ``<pin>?`` (manual p.35-36)."""
    version: str = "both"
    """``$V``: ``both`` = the controller prints ``EXbox ...`` and the arm's ``Mirobot ...`` line,
    then ``ok`` (default: what WP/ARD parse; the arm firmware itself has no ``$V``), ``exbox`` =
    only the ``EXbox`` line and ``ok`` (MCP's note), ``forward`` = the arm answers alone (the
    vendor's "RS485 not supported")."""
    o117: str = "finish"
    """``O117`` stops a program: ``finish`` = no more lines are fed, the arm finishes what it
    has (default: the manual's stop key) or ``reset`` = the controller also sends ``%``."""
    broadcast: str = "ignore"
    """``@0`` lines: ``ignore`` (default: no source says a controller acts on them) or
    ``execute`` (every node executes them and none answers, as ARD expects)."""
    unprefixed: int = 0
    """Address of the node that takes lines without ``@NN`` (a controller on USB), 0 = none:
    unprefixed lines are ignored (default: on a shared bus they would collide)."""
    relay_banner: bool = False
    """Relay the arm's power-on banner to the bus (default no: nothing unsolicited on the bus)."""
    turnaround: float = 0.002
    """Seconds from the end of a request (or of the arm's reply line) until the controller starts
    transmitting: its processing and the RS485 driver's direction switch (INFERRED)."""
    controller_version: str = "20210410"
    """The controller's firmware date (manual p.13): ``O101`` and the ``EXbox`` line."""
    error_text: str = "error"
    """The reply to a bad or unknown ``O`` command (the real text is unknown; SIM, WPg)."""

    def __post_init__(self) -> None:
        for name, choices in _CHOICES.items():
            value = getattr(self, name)
            if value not in choices:
                raise ValueError(f"{name}={value!r}: expected one of {', '.join(choices)}")
        if not 0 <= self.unprefixed <= 99:
            raise ValueError(f"unprefixed={self.unprefixed}: expected an address 0..99")
        if not (math.isfinite(self.turnaround) and self.turnaround >= 0):
            raise ValueError(f"turnaround={self.turnaround}: expected seconds >= 0")
        if not self.error_text or "\n" in self.error_text or "\r" in self.error_text:
            raise ValueError("error_text must be one non-empty line")

    @classmethod
    def parse(cls, items: Iterable[str]) -> BusOptions:
        """Options from ``KEY=VALUE`` strings; raises :class:`ValueError` naming a bad one."""
        fields = {f.name: f for f in dataclasses.fields(cls)}
        values: dict[str, Any] = {}
        for item in items:
            key, sep, text = item.partition("=")
            key = key.strip().replace("-", "_")
            if not sep or key not in fields:
                raise ValueError(
                    f"bus option {item!r}: expected KEY=VALUE, KEY one of {sorted(fields)}"
                )
            default = fields[key].default
            try:
                if isinstance(default, bool):
                    if text.lower() not in ("1", "0", "true", "false", "yes", "no", "on", "off"):
                        raise ValueError(text)
                    values[key] = text.lower() in ("1", "true", "yes", "on")
                elif isinstance(default, int):
                    values[key] = int(text)
                elif isinstance(default, float):
                    values[key] = float(text)
                else:
                    values[key] = text
            except ValueError as err:
                raise ValueError(f"bus option {item!r}: bad value") from err
        return cls(**values)
