"""The only texts where the emulator may differ from the firmware's tapes: field-binary texts.

The firmware's tapes record the vendor's source revision 20191228_2. Arms in the field run
binaries whose banner and homing texts differ from that source; the device logs in
``tests/data/vectors.json`` show them, and device logs outrank the tapes. Each entry maps the
field text the emulator prints to the source revision's text before the byte-for-byte
comparison; nothing else is normalised. Behavioural differences never go here: they are listed
per tape with their reason (``tests/tapes/known.py``).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FieldText:
    field: bytes
    """What a shipped binary prints (the emulator follows the device logs)."""
    source: bytes
    """What the source revision prints in its place (whole lines, line ending included)."""
    cite: str
    """The vectors.json device log that shows the field text."""


FIELD_TEXTS: tuple[FieldText, ...] = (
    FieldText(
        field=b"Qinnew Robot 20191228_2 based on Grbl 0.9j ['$' for help]\r\n",
        source=b"Wlkata Robot 20191228_2 based on Grbl 0.9j--Modified by Thor Zhou "
        b"['$' for help]\r\n",
        cite="vectors.json banner_classic[3] (power-on banner of a shipped classic binary)",
    ),
    FieldText(
        field=b"\r\nFree memory: 2036\r\n",
        source=b"",
        cite='vectors.json transcripts "homing (classic)": $H -> "", "Free memory: 2036", ...',
    ),
    FieldText(
        field=b"in homeing moving...ok\r\n",
        source=b"ok\r\n",
        cite='vectors.json transcripts "homing (classic)": ... "in homeing moving...ok"',
    ),
)

_BY_FIELD = {entry.field: entry.source for entry in FIELD_TEXTS}


def normalise_emulator(
    printed: list[tuple[float | None, bytes]],
) -> list[tuple[float | None, bytes]]:
    """The lines the emulator printed (with their instants), each field text replaced by the
    source revision's (a two-line field text is two consecutive lines; an empty source removes
    them)."""
    out: list[tuple[float | None, bytes]] = []
    k = 0
    while k < len(printed):
        at, line = printed[k]
        pair = line + printed[k + 1][1] if k + 1 < len(printed) else None
        if pair is not None and pair in _BY_FIELD:
            source = _BY_FIELD[pair]
            if source:
                out.append((at, source))
            k += 2
            continue
        out.append((at, _BY_FIELD.get(line, line)))
        k += 1
    return out
