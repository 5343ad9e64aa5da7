"""One parse of a raw line, reading every word exactly as the firmware (GRBL 0.9j) reads it.

:func:`parse_line` turns a raw line into an immutable :class:`ParsedLine` once; the offline
checker (:mod:`mirobot_async._core.validation`), the safety envelope's predictor
(:mod:`mirobot_async._safety.prediction`), the modal tracker (:mod:`mirobot_async._core.modal`) and
the client's scheduler all read that value instead of re-parsing the text.

Numbers are read as the firmware's ``read_float`` does (confirmed on the firmware oracle): an
optional sign, digits with at most one point, **only the first 8 digits kept, counting leading
zeros** (``X0000000030`` is 0, ``X123456789`` is 123456780); no
exponent (``X1e1`` is ``X1`` then the word ``E1``). ``G``/``M`` numbers are truncated to a byte
(``M16404`` and ``M20.001`` are ``M20``) and refused when their hundredths are not zero
(``M20.5``, ``M276``: ``Invalid gcode ID:23``). Pure module: no I/O.
"""

from __future__ import annotations

import math
import re
import struct
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from types import MappingProxyType
from typing import Final, Literal

__all__ = [
    "MAX_INT_DIGITS",
    "MAX_LINE_LENGTH",
    "REALTIME_BYTES",
    "CodeWord",
    "DollarLine",
    "FirmwareNumber",
    "ParsedLine",
    "Word",
    "normalize_line",
    "parse_line",
    "read_number",
]

MAX_LINE_LENGTH: Final = 80
"""Longest line the firmware accepts after dropping spaces and comments (``Line overflow``)."""
MAX_INT_DIGITS: Final = 8
"""Digits of a number the firmware keeps (GRBL 0.9j ``MAX_INT_DIGITS``), leading zeros count."""
REALTIME_BYTES: Final = "?!~%@"
"""Bytes the firmware takes at once (status, hold, start, reset, safety door) and removes from
the line, wherever they are (inside a comment too)."""

AXIS_LETTERS: Final = "XYZABCD"
"""Axis words: J1..J6 and the rail D in ``M21``; x y z and roll pitch yaw (and D) in ``M20``."""


_F32: Final = struct.Struct("<f")


def _f32(value: float) -> float:
    """``value`` rounded to single precision (the AVR's ``float``, and its ``double``)."""
    try:
        return float(_F32.unpack(_F32.pack(value))[0])
    except OverflowError:
        return math.copysign(math.inf, value)


def normalize_line(line: str | bytes) -> str:
    """The line as the firmware's parser sees it: bytes <= 0x20 and ``/`` dropped, letters upper
    case, ``( ... )`` and ``; ...`` comments removed. Realtime bytes (``? ! ~ % @``) are removed
    too.
    """
    text = line.decode("latin-1") if isinstance(line, bytes) else line
    return normalize_text(text)[0]


_PLAIN: Final = {
    **{code: None for code in range(0x21)},
    ord("/"): None,
    **{ord(char): None for char in REALTIME_BYTES},
    **{code: code - 0x20 for code in range(ord("a"), ord("z") + 1)},
}
"""``str.translate`` table of a line without comments: what :func:`normalize_text` drops and
upper-cases, character by character."""


def normalize_text(text: str) -> tuple[str, bool]:
    """(normalized text, True if a ``(`` comment was left open)."""
    if "(" not in text and ";" not in text:
        return text.translate(_PLAIN), False  # no comment: each character alone decides
    out: list[str] = []
    in_comment = False
    for char in text:
        if char in REALTIME_BYTES:
            continue
        if in_comment:
            if char == ")":
                in_comment = False
            continue
        if char == ";":
            break
        if char == "(":
            in_comment = True
        elif ord(char) <= 0x20 or char == "/":
            continue
        elif "a" <= char <= "z":
            out.append(char.upper())
        else:
            out.append(char)
    return "".join(out), in_comment


@dataclass(frozen=True, slots=True)
class FirmwareNumber:
    """A number as the firmware's ``read_float`` reads it from a normalized line."""

    value: float
    """The value of the digits kept (the firmware rounds it to single precision)."""
    end: int
    """Index just after the number."""
    digits: int
    """How many digits were written."""
    lossy: bool
    """True when a dropped digit (beyond the 8th) was not zero: the value differs from the text."""
    single: float = 0.0
    """The value as the firmware computes it, in single precision (for command numbers)."""


_NUMBER: Final = re.compile(r"([+-]?)([0-9]*)(?:\.([0-9]*))?")
"""A number as ``read_float`` takes it: a sign, digits, at most one point (ASCII digits only)."""


_WORD: Final = re.compile(r"([A-Z])([+-]?[0-9]*(?:\.[0-9]*)?)")
"""A letter and the number after it, as :data:`_NUMBER` reads it."""


def read_number(text: str, start: int, *, single: bool = True) -> FirmwareNumber | None:
    """Read a number at ``text[start:]`` as GRBL 0.9j does; None when no digit follows.
    ``single=False`` skips :attr:`FirmwareNumber.single` (left 0.0; only command words use it)."""
    match = _NUMBER.match(text, start)
    assert match is not None  # every part is optional
    sign, whole, fraction = match.groups()
    fraction = fraction or ""
    ndigit = len(whole) + len(fraction)
    if ndigit == 0:
        return None
    if ndigit <= MAX_INT_DIGITS:
        intval = int(whole + fraction)
        exp = -len(fraction)
        lossy = False
    else:
        digits = whole + fraction
        intval = int(digits[:MAX_INT_DIGITS])
        lossy = digits[MAX_INT_DIGITS:].strip("0") != ""
        # dropped integer digits scale it up, kept fraction digits down: they add up to this
        exp = len(whole) - MAX_INT_DIGITS
    # The firmware computes in single precision; the value here is the exact decimal number of
    # the kept digits (they differ by less than a micrometre in any reachable range).
    value = intval / 10 ** (-exp) if exp < 0 else float(intval * 10**exp)
    result = 0.0
    if single:
        result = _f32(float(intval))
        if result != 0.0:
            while exp <= -2:
                result = _f32(result * _f32(0.01))
                exp += 2
            if exp < 0:
                result = _f32(result * _f32(0.1))
            while exp > 0:
                result = _f32(result * 10.0)
                exp -= 1
    if sign == "-":
        value, result = -value, -result
    return FirmwareNumber(value, match.end(), ndigit, lossy, result)


def _c_round(x: float) -> int:
    """C ``round``: half away from zero."""
    return math.floor(x + 0.5) if x >= 0 else -math.floor(-x + 0.5)


_INTEGER_TEXT: Final = re.compile(r"\d+(?:\.0*)?")


@dataclass(frozen=True, slots=True)
class Word:
    """One word of a G-code line: a letter and its number, as written and as the firmware reads."""

    letter: str
    text: str
    """The number as written (after normalization)."""
    value: float
    """The number as the firmware reads it (its first 8 digits)."""
    lossy: bool = False
    """The firmware drops a non-zero digit of it (more than 8 digits)."""

    def __str__(self) -> str:
        return self.letter + self.text


@dataclass(frozen=True, slots=True)
class CodeWord(Word):
    """A ``G`` or ``M`` word: the command number the firmware executes."""

    code: int = 0
    """The firmware's command number: the value truncated to a byte (``M16404`` is 20)."""
    mantissa: int = 0
    """The hundredths the firmware reads (``G28.1``: 10); not zero, the firmware refuses every
    command but a few ``.1`` forms (``Invalid gcode ID:23``, e.g. ``M20.5``)."""
    _canonical: bool = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(
            self,
            "_canonical",
            not self.mantissa
            and _INTEGER_TEXT.fullmatch(self.text) is not None
            and int(self.text.split(".")[0]) == self.code,
        )

    @property
    def fraction_error(self) -> bool:
        """The word has hundredths (:attr:`mantissa`): refused by the client."""
        return self.mantissa != 0

    @property
    def canonical(self) -> bool:
        """True when the word is written as the plain integer it means (``G01``, ``M3``)."""
        return self._canonical


def _code_word(letter: str, text: str, number: FirmwareNumber) -> CodeWord:
    value = number.value
    single = number.single
    if not math.isfinite(single):
        return CodeWord(letter, text, value, number.lossy, 0, 1)
    code = math.trunc(single) % 256
    mantissa = _c_round(_f32(_f32(single - code) * 100.0)) % 65536
    # G90.1/G91.x etc. take a fraction in GRBL; none is a Mirobot command, so any is an error here.
    return CodeWord(letter, text, value, number.lossy, code, mantissa)


DollarKind = Literal[
    "help", "query", "homing", "setting", "unlock", "zero", "startup", "restore", "jog", "unknown"
]


@dataclass(frozen=True, slots=True)
class DollarLine:
    """A ``$`` system command, classified."""

    kind: DollarKind
    """``homing`` is any ``$H...`` (the firmware homes for ``$H8`` too); ``query`` is ``$$``,
    ``$#``, ``$G``, ``$I``, ``$N``, ``$C``; ``startup`` stores a line run at every reset."""
    number: int | None = None
    """Setting number as the firmware reads it (``$041=1`` and ``$41.4=1`` are ``$41``)."""
    value: float | None = None
    """Setting value as the firmware reads it."""
    canonical: bool = True
    """False when the setting is written in an odd form the firmware reads differently."""
    error: str | None = None
    """The firmware's error for a malformed ``$`` line, when known."""


_QUERIES: Final = frozenset({"$$", "$#", "$G", "$I", "$N", "$C"})


def _dollar(text: str) -> DollarLine:
    if text == "$":
        return DollarLine("help")
    if text in _QUERIES:
        return DollarLine("query")
    if text == "$X":
        return DollarLine("unlock")
    if text.startswith("$H"):
        return DollarLine("homing")
    if text == "$M":
        return DollarLine("zero")
    if text.startswith("$J"):
        return DollarLine("jog")
    if text.startswith("$RST="):
        return DollarLine("restore")
    if text.startswith("$N"):
        return DollarLine("startup")
    number = read_number(text, 1)
    if number is None:
        return DollarLine("unknown", error="Bad number format")
    if number.end >= len(text) or text[number.end] != "=":
        return DollarLine("unknown", error="Invalid statement")
    value = read_number(text, number.end + 1)
    if value is None:
        return DollarLine("unknown", error="Bad number format")
    if value.end != len(text) or not 0 <= number.value <= 255:
        return DollarLine("unknown", error="Invalid statement")
    parameter = math.trunc(number.value)
    written = text[1 : number.end]
    canonical = (
        written.isdigit()
        and int(written) == parameter
        and not value.lossy
        and math.isfinite(value.value)
    )
    return DollarLine("setting", parameter, value.value, canonical)


_G_GROUP: Final = {
    **dict.fromkeys((0, 1, 2, 3, 5, 80), "motion"),
    **dict.fromkeys((90, 91), "distance"),
    **dict.fromkeys((20, 21), "units"),
}
_M_GROUP: Final = dict.fromkeys((20, 21), "coordinate")
_NO_AXES: Final[Mapping[str, float]] = MappingProxyType({})
_PROGRAM_END: Final = frozenset({2, 30})


@dataclass(frozen=True, slots=True)
class ParsedLine:
    """A raw line parsed once: what the firmware will read from it (immutable).

    Syntax the firmware refuses as a whole (``Bad number format``, ``Expected command letter``,
    ``Line overflow``) is in :attr:`syntax_error`; deeper rules (modal groups, unused words, the
    feed rate) are the firmware's verdict from the words: :mod:`mirobot_async._core.acceptance`.
    """

    source: str
    """The raw text without its line ending (decoded as latin-1)."""
    text: str
    """The normalized text the firmware parses (see :func:`normalize_line`)."""
    open_comment: bool
    """A ``(`` comment was not closed: the rest of the line is ignored."""
    kind: Literal["empty", "gcode", "dollar"]
    words: tuple[Word, ...] = ()
    """Every word in order (``G``/``M`` words are :class:`CodeWord`)."""
    dollar: DollarLine | None = None
    syntax_error: str | None = None
    # Derived once from ``words`` (the line is read many times: validation, guard, chaining,
    # the scheduler), so that every property below is a plain read.
    _codes: tuple[CodeWord, ...] = field(init=False, repr=False, compare=False)
    _values: Mapping[str, float] = field(init=False, repr=False, compare=False)
    _g_codes: tuple[int, ...] = field(init=False, repr=False, compare=False)
    _m_codes: tuple[int, ...] = field(init=False, repr=False, compare=False)
    _repeated: tuple[str, ...] = field(init=False, repr=False, compare=False)
    _axis_words: Mapping[str, float] = field(init=False, repr=False, compare=False)
    _motion: int | None = field(init=False, repr=False, compare=False)
    _distance: int | None = field(init=False, repr=False, compare=False)
    _units: int | None = field(init=False, repr=False, compare=False)
    _coordinate_mode: int | None = field(init=False, repr=False, compare=False)
    _odd_numbers: bool = field(init=False, repr=False, compare=False)
    _axis_letters: frozenset[str] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        codes: list[CodeWord] = []
        values: dict[str, float] = {}
        twice: list[str] = []
        g_codes: list[int] = []
        m_codes: list[int] = []
        first: dict[str, int] = {}  # the first code of each modal group (M20/M21: the last)
        odd = False
        for w in self.words:
            odd = odd or w.lossy
            if isinstance(w, CodeWord):
                odd = odd or not w.canonical
                codes.append(w)
                code = w.code
                (g_codes if w.letter == "G" else m_codes).append(code)
                group = (_G_GROUP if w.letter == "G" else _M_GROUP).get(code)
                if group == "coordinate":  # the firmware keeps the last (oracle: M20 X1 M21)
                    first[group] = code
                elif group is not None:
                    first.setdefault(group, code)
            elif w.letter in values:
                if w.letter not in twice:
                    twice.append(w.letter)
            else:
                values[w.letter] = w.value
        setter = object.__setattr__
        setter(self, "_codes", tuple(codes))
        setter(self, "_values", MappingProxyType(values))
        setter(self, "_g_codes", tuple(g_codes))
        setter(self, "_m_codes", tuple(m_codes))
        setter(self, "_repeated", tuple(twice))
        axes = {k: values[k] for k in AXIS_LETTERS if k in values}
        setter(self, "_axis_words", MappingProxyType(axes) if axes else _NO_AXES)
        setter(self, "_axis_letters", frozenset(axes))
        coordinate = first.get("coordinate")
        setter(self, "_motion", first.get("motion"))
        setter(self, "_distance", first.get("distance"))
        setter(self, "_units", first.get("units"))
        setter(self, "_coordinate_mode", coordinate)
        setter(self, "_odd_numbers", odd)

    # ---- the words -------------------------------------------------------------------------

    @property
    def codes(self) -> tuple[CodeWord, ...]:
        """The ``G`` and ``M`` words."""
        return self._codes

    @property
    def g_codes(self) -> tuple[int, ...]:
        """The ``G`` numbers as the firmware reads them."""
        return self._g_codes

    @property
    def m_codes(self) -> tuple[int, ...]:
        """The ``M`` numbers as the firmware reads them."""
        return self._m_codes

    @property
    def values(self) -> Mapping[str, float]:
        """Value words (not ``G``/``M``) by letter, first occurrence (see :attr:`repeated`)."""
        return self._values

    @property
    def repeated(self) -> tuple[str, ...]:
        """Value letters written more than once (the firmware: ``Invalid gcode ID:25``)."""
        return self._repeated

    def value(self, letter: str) -> float | None:
        """The value of word ``letter`` as the firmware reads it, or None."""
        return self._values.get(letter)

    @property
    def axis_words(self) -> Mapping[str, float]:
        """The axis words ``X Y Z A B C D`` present, as the firmware reads them."""
        return self._axis_words

    @property
    def axis_letters(self) -> frozenset[str]:
        """The letters of :attr:`axis_words`."""
        return self._axis_letters

    @property
    def motion(self) -> int | None:
        """The motion code stated in the line (G0 G1 G2 G3 G5 G80), or None."""
        return self._motion

    @property
    def distance(self) -> int | None:
        """90 (absolute) or 91 (relative) when stated."""
        return self._distance

    @property
    def units(self) -> int | None:
        """20 (inches) or 21 (mm) when stated."""
        return self._units

    @property
    def coordinate_mode(self) -> int | None:
        """20 (Cartesian, ``M20``) or 21 (joints, ``M21``) when stated (the last one written)."""
        return self._coordinate_mode

    @property
    def dwell_seconds(self) -> float | None:
        """Seconds of a ``G4 P..`` dwell, or None when the line has no complete dwell."""
        if 4 not in self.g_codes:
            return None
        return self.value("P")

    @property
    def program_end(self) -> bool:
        """``M2`` or ``M30``: waits for the queue, then resets some modes."""
        return not _PROGRAM_END.isdisjoint(self._m_codes)

    @property
    def is_homing(self) -> bool:
        """Any ``$H...`` line (the firmware homes for every variant it accepts), comments and
        blanks dropped as the firmware drops them: ``(x)$H`` homes as ``$H`` does."""
        return self.dollar is not None and self.dollar.kind == "homing"

    @property
    def homing_kind(self) -> Literal["$H", "$HH"] | None:
        """Which homing search the line starts (``None``: not a homing line): ``"$H"``, every
        axis at once (also the 2021 ``$H0``..``$H7``, one axis), or ``"$HH"``, one group after
        another (also ``$HE`` and any other ``$H...``: the longest, when unknown)."""
        if not self.is_homing:
            return None
        text = self.text
        if text == "$H" or (len(text) == 3 and "0" <= text[2] <= "7"):
            return "$H"
        return "$HH"

    @property
    def clears_alarm(self) -> bool:
        """Answered ``ok``, the line leaves Alarm and releases the axis lock: ``$X``, every
        ``$H...`` the firmware accepts (it homes for each), and a G-code line with ``M50``."""
        if self.dollar is not None:
            return self.dollar.kind in ("unlock", "homing")
        return self.kind == "gcode" and self.syntax_error is None and 50 in self.m_codes

    def changes_setting(self, *numbers: int) -> bool:
        """The line may change one of the settings ``numbers`` (``$N=...`` in any form the
        firmware reads as one of them, ``$RST=...`` restoring the defaults, or a ``$`` line
        this parse cannot classify: conservatively, yes)."""
        dollar = self.dollar
        if dollar is None:
            return False
        if dollar.kind in ("restore", "unknown"):
            return True
        return dollar.kind == "setting" and dollar.number in numbers

    @property
    def changes_base_offset(self) -> bool:
        """The line may change the 2021 base offset ``$41..$43`` (:meth:`changes_setting`):
        the one rule of the client and the envelope."""
        return self.changes_setting(41, 42, 43)

    @property
    def queues_motion(self) -> bool:
        """The line may put a block in the planner: a G-code line with an axis word or a ``G4``
        dwell (``$`` commands do not: ``$H`` is answered when homing ends)."""
        if self.kind != "gcode":
            return False
        return bool(self.axis_words) or 4 in self.g_codes

    @property
    def has_odd_numbers(self) -> bool:
        """A word the firmware reads differently from its text (digits dropped, odd G/M form)."""
        return self._odd_numbers

    @property
    def may_move(self) -> bool:
        """True unless the line certainly does not move the arm (conservative)."""
        if self.kind == "empty":
            return False
        if self.dollar is not None:
            return self.dollar.kind in ("homing", "zero", "jog", "startup", "restore", "unknown")
        if self.syntax_error is not None:
            return False  # the firmware rejects the whole line
        return bool(self.axis_words) or any(code not in _STILL_G for code in self.g_codes)

    def __str__(self) -> str:
        return self.text


_STILL_G: Final = frozenset({0, 1, 2, 3, 4, 5, 17, 20, 21, 40, 54, 61, 80, 90, 91, 93, 94})
"""G codes that do not move by themselves (motion codes move only with axis words)."""


def _word(letter: str, written: str) -> Word:
    """The word ``letter`` + ``written`` (a number :data:`_NUMBER` matched whole)."""
    command = letter in "GM"
    if not command:
        digits = len(written) - (written[0] in "+-") - ("." in written)
        if digits <= MAX_INT_DIGITS:  # every digit kept: the exact decimal value, as read_number
            return Word(letter, written, float(written), False)
    number = read_number(written, 0, single=command)
    assert number is not None and number.end == len(written)
    if command:
        return _code_word(letter, written, number)
    return Word(letter, written, number.value, number.lossy)


def _scan(text: str) -> tuple[tuple[Word, ...], str | None]:
    words: list[Word] = []
    pos = 0
    end = len(text)
    match = _WORD.match
    while pos < end:
        found = match(text, pos)
        if found is None:  # the number is optional: no letter here
            return tuple(words), "Expected command letter"
        letter, written = found.groups()
        if not written.strip("+-."):  # no digit (at most a sign and a point)
            return tuple(words), "Bad number format"
        words.append(_word(letter, written))
        pos = found.end()
    return tuple(words), None


def parse_line(line: str | bytes | bytearray | memoryview) -> ParsedLine:
    """Parse one raw line (one line ending at most) into a :class:`ParsedLine`; never raises for
    the line's content (the result says what the firmware would refuse)."""
    raw = bytes(line).decode("latin-1") if not isinstance(line, str) else line
    return _parse_text(raw)


@lru_cache(maxsize=1024)
def _parse_text(raw: str) -> ParsedLine:
    """:func:`parse_line` of a text. Remembered (the last 1024 texts): assumes the parse is a
    pure function of the text and :class:`ParsedLine` immutable (a program repeats its lines)."""
    source = raw.rstrip("\r\n")
    text, open_comment = normalize_text(source)
    if not text:
        return ParsedLine(source, text, open_comment, "empty")
    if len(text) > MAX_LINE_LENGTH:
        kind: Literal["gcode", "dollar"] = "dollar" if text.startswith("$") else "gcode"
        return ParsedLine(source, text, open_comment, kind, syntax_error="Line overflow")
    if text.startswith("$"):
        dollar = _dollar(text)
        return ParsedLine(source, text, open_comment, "dollar", dollar=dollar, syntax_error=None)
    words, error = _scan(text)
    return ParsedLine(source, text, open_comment, "gcode", words, syntax_error=error)
