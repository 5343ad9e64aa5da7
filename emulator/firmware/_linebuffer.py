"""The receive ring and the line discipline (PROTOCOL 2): bytes in, filtered lines out.

A byte enters the receive ring (127 bytes; lost when it is full); the parser takes bytes from
the ring into the line buffer only while it is free, so the ring is what the host's character
counting sees. Filtering: ``\\r`` or ``\\n`` end a line, bytes ``<= 0x20`` and ``/`` are
dropped, ``(...)`` and ``;`` comments removed, letters upper-cased.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Final, NamedTuple

RX_BUFFER_SIZE: Final = 128
"""GRBL's receive ring in bytes; it holds one byte less (:data:`RX_CAPACITY`)."""

RX_CAPACITY: Final = RX_BUFFER_SIZE - 1
"""Bytes the ring holds (oracle: with the parser blocked, the 128th byte sent is lost).
Character counting with 128 stays safe: the line the parser holds is part of the count."""

LINE_BUFFER_SIZE: Final = 80
"""GRBL's line buffer in bytes: a line holds at most ``LINE_BUFFER_SIZE - 1`` = 79 bytes after
filtering (oracle: 79 accepted, 80 overflow)."""

MAX_LINE_LENGTH: Final = LINE_BUFFER_SIZE - 1

_DROPPED: Final = bytes(range(0x21)) + b"/"
"""Bytes the line filter drops: whitespace, control bytes and ``/`` (block delete)."""

_REALTIME: Final = frozenset(b"?!~%@")
_LINE_ENDS: Final = frozenset(b"\r\n")
_RUN: Final = re.compile(rb"[^?!~%@\r\n]*[\r\n]?")
"""Bytes up to and including the next line end, stopping before a realtime byte."""
_PLAIN_LINE: Final = re.compile(rb"[^?!~%@\r\n]*[\r\n]")
"""One line with its end and no realtime byte (the usual arrival)."""

_NO_COMMENT: Final = 0
_PARENTHESES: Final = 1
_SEMICOLON: Final = 2


class ReceivedLine(NamedTuple):
    """A complete filtered line, or the overflow of one (``overflow``: ``text`` is empty).
    (A named tuple: one made per line, cheaper than a frozen dataclass.)"""

    text: str
    overflow: bool = False
    raw: int = 0
    """Received bytes the line took from the ring (its line end included)."""


class LineBuffer:
    """The 128-byte receive ring plus the line being assembled from it."""

    def __init__(self) -> None:
        self.lost: int = 0
        """Bytes lost so far because the ring was full."""
        self._ring = bytearray()
        self.ring: Final = self._ring
        """The ring's bytes (read them only: the same bytearray, never replaced)."""
        self._line = bytearray()
        self._comment = _NO_COMMENT
        self._raw = 0  # bytes taken into the line being assembled

    def __len__(self) -> int:
        """Bytes waiting in the ring."""
        return len(self._ring)

    @property
    def free(self) -> int:
        """Free bytes in the ring."""
        return RX_CAPACITY - len(self._ring)

    def put(self, c: int) -> bool:
        """One received byte into the ring; False (and counted as lost) when the ring is full."""
        if len(self._ring) >= RX_CAPACITY:
            self.lost += 1
            return False
        self._ring.append(c)
        return True

    def put_bytes(self, data: bytes) -> int:
        """As many of ``data`` as fit into the ring (none is lost here); how many were taken."""
        taken = min(len(data), RX_CAPACITY - len(self._ring))
        self._ring += data[:taken]
        return taken

    def arrive(
        self, data: bytes, pump: Callable[[], None], realtime: Callable[[int], None]
    ) -> None:
        """Bytes that have arrived at the UART: each realtime byte acts at once (``realtime``),
        after what came before it was handed to the parser (``pump``: it takes a line if it
        is free); the others enter the ring, ``pump`` called when a line is complete or the
        ring is full (the rest is lost if the parser is busy)."""
        if len(data) <= RX_CAPACITY - len(self._ring) and _PLAIN_LINE.fullmatch(data):
            self._ring += data  # the usual case: one whole line, room for it
            pump()
            return
        waiting = False  # bytes put since the last pump (the parser takes them as they come)
        i, n = 0, len(data)
        while i < n:
            if data[i] in _REALTIME:
                if waiting:
                    pump()  # what arrived before it is handled first
                    waiting = False
                realtime(data[i])
                i += 1
                continue
            match = _RUN.match(data, i)
            assert match is not None  # the pattern matches the non-realtime byte at i
            run, i = match.group(), match.end()
            ends_line = run[-1] in _LINE_ENDS
            while run:
                taken = self.put_bytes(run)
                run = run[taken:]
                waiting = waiting or taken > 0
                if (ends_line and not run) or not self.free:
                    pump()  # a line is complete or the ring is full
                    waiting = False
                    if run and not self.free:
                        self.lose(len(run))  # the parser is busy: the rest is lost
                        break
        if waiting:
            pump()

    def lose(self, count: int) -> None:
        """Count ``count`` received bytes as lost (they found the ring full)."""
        self.lost += count

    def clear(self) -> None:
        """Drop the ring and the partial line (soft reset)."""
        self._ring.clear()
        self._line.clear()
        self._comment = _NO_COMMENT
        self._raw = 0

    def take_line(self) -> ReceivedLine | None:
        """Move bytes from the ring into the line until one line is complete or overflows;
        None if the ring ran dry first (the partial line is kept).

        Overflow (oracle): the byte that would be the 80th is dropped, the line so far is
        discarded and reported at once, and the bytes after it start a new line (so a long
        line gets ``Line overflow`` and then the reply of its tail).
        """
        ring = self._ring
        if not ring:
            return None  # nothing received: the partial line (and its comment state) waits
        if not self._comment:
            line = self._take_plain_line()
            if line is not None:
                return line
        while ring:
            c = ring[0]
            del ring[0]
            self._raw += 1
            if c in (0x0A, 0x0D):
                line = ReceivedLine(self._line.decode("latin-1"), raw=self._raw)
                self._raw = 0
                self._line.clear()
                self._comment = _NO_COMMENT
                return line
            if self._filter(c):
                self._line.clear()
                self._comment = _NO_COMMENT
                raw, self._raw = self._raw, 0
                return ReceivedLine("", overflow=True, raw=raw)
        return None

    def _take_plain_line(self) -> ReceivedLine | None:
        """The common case at once: a whole line in the ring, without comments, that fits.
        None when the byte-by-byte path must decide (no line end yet, a comment, an overflow).
        """
        ring = self._ring
        end = ring.find(0x0A)
        cr = ring.find(0x0D, 0, end if end >= 0 else len(ring))
        if cr >= 0:
            end = cr
        if end < 0:
            return None
        received = bytes(ring[:end])
        if 0x28 in received or 0x3B in received:  # '(' or ';'
            return None
        kept = received.translate(None, _DROPPED)
        if len(self._line) + len(kept) > MAX_LINE_LENGTH:
            return None
        text = (bytes(self._line) + kept).upper().decode("latin-1")  # ASCII letters, as GRBL
        self._line.clear()
        del ring[: end + 1]
        taken, self._raw = self._raw + end + 1, 0
        return ReceivedLine(text, raw=taken)

    def _filter(self, c: int) -> bool:
        """Add ``c`` to the line as GRBL filters it; True when it overflows the line."""
        if self._comment:
            if c == 0x29 and self._comment == _PARENTHESES:  # ')'
                self._comment = _NO_COMMENT
        elif c <= 0x20 or c == 0x2F:  # whitespace, control bytes, '/' (block delete)
            pass
        elif c == 0x28:  # '('
            self._comment = _PARENTHESES
        elif c == 0x3B:  # ';'
            self._comment = _SEMICOLON
        elif len(self._line) >= MAX_LINE_LENGTH:
            return True
        elif 0x61 <= c <= 0x7A:
            self._line.append(c - 0x20)
        else:
            self._line.append(c)
        return False
