"""Record a tape from any arm, as it goes: ``Mirobot.connect(url, record=FILE)``, ``--record``.

:class:`TapeRecorder` writes one tape (:mod:`.format`) to a file: every byte run the client
writes to the link (one ``in`` event per write) and every whole line the arm prints (one
``out`` event, ``t`` the instant its last byte arrived; a recorded tape has no ``t0``). Each
event line is written and flushed at once, so memory stays bounded over hours and a process
that is killed leaves a readable tape up to its last whole line. On :meth:`TapeRecorder.close`
a partial received line is written with ``"partial":true``, then the end marker
``{"t":..,"end":"closed"}`` (``"lost"`` when the link ended by itself).

The header says what is known only after the connect (the banner, the firmware family), so
the events until then are held (at most :data:`HEADER_WAIT_BYTES`), and the header is written
first when the connect ends (:meth:`TapeRecorder.begin`), fails (:meth:`TapeRecorder.close`) or
the held events outgrow the bound.

Instants: ``"clock":"wall"``: seconds since the recording started, on the monotonic clock.
``"clock":"simulated"``: the in-process virtual arm's own clock (seconds since its power-on, as
the firmware model counts them), which its link offers as an optional ``clock()`` method (the
instant of the bytes it is writing or delivering now), so that a replay into the same model
feeds each byte at the instant the virtual arm took it.
"""

from __future__ import annotations

import datetime
import os
import platform
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any, Final, Protocol

from mirobot_async._tapes.format import Marker, Printed, Written, event_line, header_line
from mirobot_async.errors import MirobotUsageError

__all__ = [
    "HEADER_WAIT_BYTES",
    "LONGEST_LINE",
    "ArmFacts",
    "TapeRecorder",
    "link_kind",
    "record_arm",
]

HEADER_WAIT_BYTES: Final = 64 * 1024
"""Event lines held (bytes of JSON) while the header waits for the connect to end."""
LONGEST_LINE: Final = 4096
"""Received bytes without a line end kept at most: more is written as a ``partial`` line (the
firmware's longest line is a status report of ~200 bytes)."""

Facts = Callable[[], dict[str, Any]]


class TapeRecorder:
    """One tape, written to ``path`` as it goes (appended: a file may hold several tapes).

    ``header`` is the header's fields known at the start; ``facts()`` (optional) gives those
    known later (banner, family), read when the header is written.
    """

    def __init__(
        self, path: str | os.PathLike[str], header: dict[str, Any], facts: Facts | None = None
    ) -> None:
        path = Path(path)
        if path.is_file():
            with path.open("rb") as probe:
                if probe.read(2) == b"\x1f\x8b":
                    raise MirobotUsageError(
                        f"record={str(path)!r} is gzip-compressed: tapes are appended as plain "
                        "JSON Lines (choose another file)"
                    )
        try:
            self._file: IO[str] | None = path.open("a", encoding="utf-8", newline="\n")
        except OSError as exc:
            raise MirobotUsageError(f"record={str(path)!r} cannot be written: {exc}") from None
        self.path = path
        self._origin = time.monotonic()
        self.clock: Callable[[], float] = self._wall
        self.clock_kind = "wall"
        self._header = dict(header)
        self._header.setdefault("started", _utc_now())
        self._facts = facts
        self.link_family: str | None = None
        """The firmware family the link itself says (a virtual arm's profile), if any."""
        self._held: list[str] | None = []  # event lines until the header is written
        self._held_bytes = 0
        self._line = bytearray()  # the received line so far (no line end yet)
        self.end: str | None = None
        """Why the recording ended (``closed``, ``lost``), or None while it goes on."""

    def _wall(self) -> float:
        return time.monotonic() - self._origin

    def use_clock(self, clock: Callable[[], float]) -> None:
        """Take the instants from ``clock`` (a simulated one) from now on."""
        self.clock = clock
        self.clock_kind = "simulated"

    def attach(self, url: str, transport: object) -> None:
        """The link is open: note its kind, its baud rate and, on a virtual arm, its clock and
        time scale (optional ``clock()`` and ``time_scale`` of the transport)."""
        kind = link_kind(url, transport)
        header = self._header
        header["link"] = kind
        header["source"] = "virtual" if kind == "virtual" else "device"
        baud = getattr(transport, "baudrate", None)
        ok = isinstance(baud, int) and kind not in ("tcp", "virtual", "loop")
        header["baud"] = baud if ok else None
        scale = getattr(transport, "time_scale", None)
        if isinstance(scale, int | float):
            header["time_scale"] = float(scale)
        profile = getattr(transport, "firmware_profile", None)
        self.link_family = profile if isinstance(profile, str) else None
        clock = getattr(transport, "clock", None)
        if callable(clock):
            self.use_clock(clock)

    @property
    def buffered(self) -> int:
        """Bytes the recorder holds now (events waiting for the header, a partial line)."""
        return self._held_bytes + len(self._line)

    # ---- events ----

    def written(self, data: bytes) -> None:
        """The client wrote ``data`` to the link (one event)."""
        if self._file is not None and data:
            self._emit(event_line(Written(self.clock(), bytes(data))))

    def received(self, data: bytes) -> None:
        """The client received ``data``: each line it completes is one event."""
        if self._file is None or not data:
            return
        t = self.clock()
        line = self._line
        start = 0
        while (end := data.find(b"\n", start)) >= 0:
            line += data[start : end + 1]
            self._emit(event_line(Printed(t, bytes(line))))
            line.clear()
            start = end + 1
        line += data[start:]
        if len(line) > LONGEST_LINE:
            self._emit(event_line(Printed(t, bytes(line), partial=True)))
            line.clear()

    def _emit(self, text: str) -> None:
        held = self._held
        if held is None:
            self._write(text)
            return
        held.append(text)
        self._held_bytes += len(text)
        if self._held_bytes > HEADER_WAIT_BYTES:
            self.begin()

    def _write(self, text: str) -> None:
        file = self._file
        assert file is not None
        try:
            file.write(text)
            file.flush()
        except OSError:  # a full disk must not break the arm's connection: stop recording
            self._file = None
            file.close()

    # ---- header and end ----

    def begin(self) -> None:
        """Write the header (with what is known now) and the events held; stream from now on."""
        held = self._held
        if held is None or self._file is None:
            return
        self._held = None
        self._held_bytes = 0
        header = {**self._header, "clock": self.clock_kind}
        if self._facts is not None:
            header.update(self._facts())
        self._write(header_line(header) + "".join(held))

    def close(self, end: str = "closed") -> None:
        """Write a partial received line, the end marker, and close the file (idempotent)."""
        if self._file is None:
            return
        self.begin()
        t = self.clock()
        if self._line and self._file is not None:
            self._write(event_line(Printed(t, bytes(self._line), partial=True)))
            self._line.clear()
        if self._file is not None:
            self._write(event_line(Marker(t, "end", {"end": end})))
            self._file.close()
            self._file = None
        self.end = end


def _utc_now() -> str:
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="milliseconds")


_SCHEMES: Final = {"socket": "tcp", "rfc2217": "rfc2217", "loop": "loop", "virtual": "virtual"}


def link_kind(url: str, transport: object) -> str:
    """What kind of link ``url`` is (never its host or path): the transport's own ``link_kind``
    (``virtual``, ``bus``), else from the URL's scheme (``socket://`` is ``tcp``; a device
    path, a pty or ``auto`` is ``serial``)."""
    kind = getattr(transport, "link_kind", None)
    if isinstance(kind, str):
        return kind
    if "://" not in url:
        return "serial"
    scheme = url.split("://", 1)[0].lower()
    return _SCHEMES.get(scheme, scheme if scheme.isalnum() else "other")


class ArmFacts(Protocol):
    """What the client knows of the arm (its ``RobotCondition``), read for the header."""

    @property
    def firmware(self) -> str | None: ...

    @property
    def firmware_version(self) -> str | None: ...

    @property
    def banner(self) -> tuple[str, ...] | None: ...


def record_arm(path: str | os.PathLike[str], arm: ArmFacts) -> TapeRecorder:
    """A recorder for a connection (before it opens); its header's facts come from ``arm``
    when written. The wire then :meth:`~TapeRecorder.attach` es it to the open link."""
    from mirobot_async._version import __version__

    given = arm.firmware
    recorder: TapeRecorder | None = None
    header: dict[str, Any] = {
        "id": f"recorded {_utc_now()}",
        "library_version": __version__,
        "os": f"{platform.system()} {platform.release()}".strip(),
        "python": platform.python_version(),
    }

    def facts() -> dict[str, Any]:
        from mirobot_async._client.condition import firmware_from_banner

        banner = arm.banner
        if banner is not None and firmware_from_banner(banner)[0] is not None:
            evidence: str | None = "banner"
        elif arm.firmware is not None:
            evidence = "given" if arm.firmware == given else "settings"
        elif recorder is not None and recorder.link_family is not None:
            evidence = "virtual arm"
        else:
            evidence = None
        found: dict[str, Any] = {
            "banner": None if banner is None else list(banner),
            "family": arm.firmware or (recorder.link_family if recorder is not None else None),
            "family_evidence": evidence,
        }
        if arm.firmware_version is not None:
            found["firmware"] = arm.firmware_version
        return found

    recorder = TapeRecorder(path, header, facts)
    return recorder
