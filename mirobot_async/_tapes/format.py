"""The tape format: what an arm received and printed, with the instants (pure).

A tape file is JSON Lines, optionally gzip-compressed. Each tape is a header line (it has
``"tape": 1``) followed by its events, up to the next header. Strings are bytes, one character
per byte (latin-1). The events:

``{"t": 0.7070594, "in": "\\n"}``
    bytes the host wrote, at ``t`` (a firmware tape: one byte per event at the instant it entered
    the UART; a recorded tape: the bytes of one write, at the instant of the write).
    ``"dropped": true``: lost before the firmware had enabled its receiver.
``{"t": 0.7090513, "t0": 0.7087708, "out": "ok\\r\\n"}``
    one output line with its line ending: ``t`` its last byte, ``t0`` its first (a recorded tape
    knows only when the line arrived: ``t0`` is then absent). ``"partial": true``: cut off.
``{"t": 6.02, "switch": "J1", "pressed": true, ...}``
    a limit pin changed (firmware tapes only; the replay does not need them).
``{"t": 4.6, "end": "signal", ...}``
    the recording ended.

The header says where the tape came from; :data:`HEADER_FIELDS` lists every field a reader
accepts, and an unknown one is an error (a newer writer's tape is refused, not misread).
"""

from __future__ import annotations

import gzip
import io
import json
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from mirobot_async.errors import TapeFormatError

TAPE_VERSION = 1

FIRMWARE_HEADER_FIELDS = frozenset(
    {
        "tape", "id", "test", "index", "phase", "test_outcome", "firmware", "argv", "flags",
        "eeprom", "elf_sha256", "clock_hz", "power_on_t", "banner_end_t", "end_t", "ended",
        "encoding", "in_bytes", "out_lines", "hard_limit_alarms", "suspect",
    }
)  # fmt: skip
"""Fields of the firmware's tapes (recorded from the vendor's firmware in a simulator)."""

RECORDED_HEADER_FIELDS = frozenset(
    {
        "tape", "id", "source", "clock", "link", "baud", "banner", "family", "family_evidence",
        "library_version", "os", "python", "time_scale", "started", "encoding", "note",
        "firmware",
    }
)  # fmt: skip
"""Fields of a tape recorded by this library (``record=``, ``--record``, ``mirobot doctor``)."""

HEADER_FIELDS = FIRMWARE_HEADER_FIELDS | RECORDED_HEADER_FIELDS
EVENT_FIELDS = {
    "in": frozenset({"t", "in", "dropped"}),
    "out": frozenset({"t", "t0", "out", "partial"}),
    "switch": frozenset({"t", "switch", "pressed", "model", "steps", "fw_steps", "torn"}),
    "end": frozenset({"t", "end", "steps"}),
}


@dataclass(frozen=True, slots=True)
class Written:
    """Bytes the host wrote at ``t`` (seconds on the tape's clock)."""

    t: float
    data: bytes
    dropped: bool = False


@dataclass(frozen=True, slots=True)
class Printed:
    """One line the arm printed (its line ending included): first byte at ``t0``, last at ``t``."""

    t: float
    data: bytes
    t0: float | None = None
    partial: bool = False

    @property
    def start(self) -> float:
        """When the line began (``t0`` where the tape knows it, else ``t``)."""
        return self.t if self.t0 is None else self.t0


@dataclass(frozen=True, slots=True)
class Marker:
    """An event the replay does not feed: a switch change or the end of the recording."""

    t: float
    kind: str
    fields: dict[str, Any]


TapeEvent = Written | Printed | Marker


@dataclass
class Tape:
    """One tape: its header (as written) and its events; ``line`` is the header's line number."""

    header: dict[str, Any]
    events: list[TapeEvent] = field(default_factory=list)
    path: str = ""
    line: int = 0

    @property
    def id(self) -> str:
        """The tape's name (``id`` in its header)."""
        return str(self.header.get("id", f"{self.path}:{self.line}"))

    @property
    def source(self) -> str:
        """``firmware`` (the vendor's firmware in a simulator), ``device`` or ``virtual``."""
        return str(self.header.get("source", "firmware"))

    @property
    def suspect(self) -> str | None:
        """Why the tape is not evidence (a simulator artefact), or None."""
        value = self.header.get("suspect")
        return None if value is None else str(value)

    @property
    def end_t(self) -> float:
        """The instant of the last event."""
        return self.events[-1].t if self.events else 0.0


def _text(value: object, what: str) -> bytes:
    if not isinstance(value, str):
        raise ValueError(f"{what} must be a string, got {type(value).__name__}")
    try:
        return value.encode("latin-1")
    except UnicodeEncodeError as exc:
        raise ValueError(f"{what} holds a character above U+00FF (tapes are bytes)") from exc


def _instant(value: object, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def parse_event(record: dict[str, Any]) -> TapeEvent:
    """One event line's object as a :data:`TapeEvent` (ValueError: not a valid event)."""
    kind = next((k for k in EVENT_FIELDS if k in record), None)
    if kind is None:
        raise ValueError(f"not an event (none of {', '.join(EVENT_FIELDS)}): {sorted(record)}")
    unknown = set(record) - EVENT_FIELDS[kind]
    if unknown:
        raise ValueError(f"unknown field(s) in a {kind!r} event: {', '.join(sorted(unknown))}")
    t = _instant(record.get("t"), "t")
    if kind == "in":
        data = _text(record["in"], "in")
        if not data:
            raise ValueError("an 'in' event with no bytes")
        return Written(t, data, bool(record.get("dropped", False)))
    if kind == "out":
        data = _text(record["out"], "out")
        t0 = record.get("t0")
        return Printed(
            t, data, None if t0 is None else _instant(t0, "t0"), bool(record.get("partial"))
        )
    return Marker(t, kind, record)


def parse_header(record: dict[str, Any]) -> dict[str, Any]:
    """A header line's object, checked (ValueError: unknown version or fields)."""
    version = record.get("tape")
    if version != TAPE_VERSION:
        raise ValueError(f"unknown tape version {version!r} (this library reads {TAPE_VERSION})")
    unknown = set(record) - HEADER_FIELDS
    if unknown:
        raise ValueError(f"unknown header field(s): {', '.join(sorted(unknown))}")
    if not isinstance(record.get("id", ""), str):
        raise ValueError("the header's id must be a string")
    return record


def _open_text(path: Path) -> IO[str]:
    with path.open("rb") as probe:
        magic = probe.read(2)
    if magic == b"\x1f\x8b":
        return io.TextIOWrapper(gzip.open(path, "rb"), encoding="utf-8")
    return path.open("r", encoding="utf-8")


@dataclass
class TapeText:
    """One tape's lines as read from its file, parsed only when asked (:meth:`parse`): a suite
    that replays one tape of a large file need not parse the others' events."""

    path: str
    line: int
    """The header's line number (1-based)."""
    header: dict[str, Any]
    lines: list[str]

    @property
    def id(self) -> str:
        return str(self.header.get("id", f"{self.path}:{self.line}"))

    def parse(self) -> Tape:
        """The tape with its events (:class:`~mirobot_async.errors.TapeFormatError` naming the
        file and line of the first bad event)."""
        tape = Tape(self.header, path=self.path, line=self.line)
        append = tape.events.append
        for number, raw in enumerate(self.lines, start=self.line + 1):
            if not raw.strip():
                continue
            try:
                record = json.loads(raw)
            except ValueError as exc:
                raise TapeFormatError(self.path, number, f"invalid JSON ({exc.args[0]})") from None
            try:
                if not isinstance(record, dict):
                    raise ValueError("a line must be a JSON object")
                append(parse_event(record))
            except ValueError as exc:
                raise TapeFormatError(self.path, number, str(exc)) from None
        return tape


def split_tapes(path: str | Path) -> list[TapeText]:
    """The tapes of a file (``.jsonl`` or gzip-compressed) with their headers checked and their
    events unparsed. Raises :class:`~mirobot_async.errors.TapeFormatError` naming the file and
    line for a bad header, an event before any header, a truncated gzip stream or a file with no
    tape. A last line without its newline (a recording cut off) is left out."""
    path = Path(path)
    name = str(path)
    texts: list[TapeText] = []
    number = 0
    try:
        with _open_text(path) as stream:
            for number, raw in enumerate(stream, start=1):
                if not raw.endswith("\n"):
                    break  # the last line of a tape whose writer was killed: not whole
                if '"tape"' in raw and raw.lstrip().startswith("{"):
                    try:
                        record = json.loads(raw)
                        if isinstance(record, dict) and "tape" in record:
                            texts.append(TapeText(name, number, parse_header(record), []))
                            continue
                    except ValueError as exc:
                        raise TapeFormatError(name, number, str(exc)) from None
                if not texts:
                    if not raw.strip():
                        continue
                    raise TapeFormatError(name, number, "an event before the first header")
                texts[-1].lines.append(raw)
    except FileNotFoundError:
        raise TapeFormatError(name, 0, "no such file") from None
    except (EOFError, OSError, UnicodeDecodeError) as exc:
        raise TapeFormatError(name, number + 1, f"unreadable: {exc}") from None
    if not texts:
        raise TapeFormatError(name, number, "no tape header in the file")
    return texts


def read_tapes(path: str | Path) -> Iterator[Tape]:
    """Every tape in a file (``.jsonl`` or gzip-compressed), in order, with its events.

    Raises :class:`~mirobot_async.errors.TapeFormatError` naming the file and line for invalid
    JSON, an unknown version or field, an event before any header, a truncated gzip stream or a
    file with no tape. A last line without its newline (a recording cut off) is ignored.
    """
    for text in split_tapes(path):
        yield text.parse()


def bytes_text(data: bytes) -> str:
    """Bytes as a tape string (one character per byte)."""
    return data.decode("latin-1")


def event_line(event: TapeEvent) -> str:
    """One event as its JSON line (with its newline)."""
    record: dict[str, Any]
    if isinstance(event, Written):
        record = {"t": round(event.t, 7), "in": bytes_text(event.data)}
        if event.dropped:
            record["dropped"] = True
    elif isinstance(event, Printed):
        record = {"t": round(event.t, 7)}
        if event.t0 is not None:
            record["t0"] = round(event.t0, 7)
        record["out"] = bytes_text(event.data)
        if event.partial:
            record["partial"] = True
    else:
        record = dict(event.fields)
        record["t"] = round(event.t, 7)
    return json.dumps(record, separators=(",", ":")) + "\n"


def header_line(header: dict[str, Any]) -> str:
    """A header as its JSON line (``tape`` first; checked as a reader would)."""
    record = {"tape": TAPE_VERSION, **{k: v for k, v in header.items() if k != "tape"}}
    parse_header(record)
    return json.dumps(record, separators=(",", ":")) + "\n"
