"""STEP 2 of GRBL 0.9j's parser: a filtered line into its words (:class:`GBlock`), with the
modal-group, repeat and sign checks; plus GRBL's number reading."""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass, field
from typing import Final

from . import _codes as c

AXIS_WORDS: Final = "XYZABCD"  # index = joint (M21: J1..J6, rail) or pose component (M20)
_VALUE_WORDS: Final = frozenset("FIJKLNPRSETXYZABCD")
_NON_NEGATIVE_WORDS: Final = frozenset("FNPTSE")
STALE_GROUP_WORDS: Final = "M3 M4 M5 M20 M21 M50"
"""Oracle: these words take the modal group of the G or M word before them in the line (a
stale group), so any modal word before them is a ``Modal group violation`` (``G91 M3``,
``M8 M5``, ``M3 M20``, ``G4 M5``), while ``M3 G91``, ``M5 M8``, ``G4 P0 M3`` and
``G10 Z3 M21`` are fine (a value word in between leaves another group); first in a line they
take the feed-mode group (``M21 G93`` is a violation). ASSUMED the same on 2021."""

_VALUE_WORD_STALE_GROUPS: Final = {"F": "G0", "S": "G8", "N": "G5"}
"""The group a value word leaves for the stale words after it (oracle: ``F100 M3 G4``,
``S100 M3 G49``, ``N1 M3 G93`` are violations, ``S1 M3 G93`` is not). ASSUMED: the other value
words leave a group no G or M word has (``G93 K1 M50``, ``P0 M3 G4``, ``T1 M3 G91`` are fine)."""

NONMODAL_AXIS_COMMANDS: Final = frozenset({10, 28, 30, 92})
"""Non-modal commands that take the axis words (then no motion mode may)."""


_FLOAT: Final = re.compile(r"[+-]?([0-9]*)(?:\.([0-9]*))?")
"""What ``read_float`` takes: a sign, digits, one point and digits (ASCII digits only)."""


def read_float(line: str, i: int) -> tuple[float, int] | None:
    """GRBL 0.9j ``read_float``: sign, digits, one point, at most 8 significant digits kept.

    Returns the value and the index after it, or None when no digit was read.
    """
    found = _FLOAT.match(line, i)
    assert found is not None  # the pattern matches the empty string
    whole, fraction = found.groups()
    ndigit = len(whole) + len(fraction) if fraction is not None else len(whole)
    if ndigit == 0:
        return None
    if ndigit > 8:
        return _read_float_digits(line, i)  # GRBL drops the digits after the 8th
    return _kept_digits(whole, fraction, line[i] == "-"), found.end()


def _kept_digits(whole: str, fraction: str | None, negative: bool) -> float:
    """The value of at most 8 digits: the same integer and power of ten as the digit loop."""
    intval = int(whole + fraction) if fraction else int(whole)
    exp = -len(fraction) if fraction else 0
    value = float(intval) * 10.0**exp if intval else 0.0
    return -value if negative else value


def _read_float_digits(line: str, i: int) -> tuple[float, int] | None:
    """:func:`read_float` digit by digit, as GRBL reads (needed past 8 significant digits)."""
    n = len(line)
    negative = False
    if i < n and line[i] in "+-":
        negative = line[i] == "-"
        i += 1
    intval = 0
    exp = 0
    ndigit = 0
    decimal = False
    while i < n:
        ch = line[i]
        if "0" <= ch <= "9":
            ndigit += 1
            if ndigit <= 8:
                if decimal:
                    exp -= 1
                intval = intval * 10 + (ord(ch) - 48)
            elif not decimal:
                exp += 1
        elif ch == "." and not decimal:
            decimal = True
        else:
            break
        i += 1
    if ndigit == 0:
        return None
    value = float(intval) * 10.0**exp if intval else 0.0
    return (-value if negative else value), i


def c_round(x: float) -> int:
    """C ``round``: half away from zero."""
    return math.floor(x + 0.5) if x >= 0 else -math.floor(-x + 0.5)


def uint8(value: float) -> int:
    """C conversion of a float to ``uint8_t`` as GRBL does it for command numbers."""
    return math.trunc(value) % 256


@dataclass
class GBlock:
    """The words of one G-code line (GRBL's ``parser_block_t``)."""

    nonmodal: int | None = None  # 4, 10, 28, 30, 53, 92; 281, 301, 921 = G28.1, G30.1, G92.1
    motion: int | None = None  # 0, 1, 2, 3, 5 (2021 gate), 80
    axis_command: bool = False  # an explicit G0..G3/G5 in the line
    plane: int | None = None
    distance: int | None = None
    feed_mode: int | None = None
    units: int | None = None
    coord_select: int | None = None
    flow: int | None = None  # M0, M1, M2, M30
    spindle: int | None = None  # M3, M4, M5
    coolant: int | None = None  # M8, M9
    tool_length: int | None = None  # 431 (G43.1), 49
    coord_mode: int | None = None  # M20, M21
    unlock: bool = False  # M50
    home: bool = False  # M95
    words: dict[str, float] = field(default_factory=dict)


def scan(line: str, profile: str) -> tuple[GBlock, int]:
    """The words of ``line`` and 0, or the words before the first scanning error and its GRBL
    status (the classic firmware acts on the ``M20``/``M21``/``M50`` scanned before it).

    A line seen lately is not read again: its words are copied from the last reading (a fresh
    :class:`GBlock` each call, so a caller may change its own)."""
    scanned, status = _scan_memo(line, profile)
    copy = object.__new__(GBlock)
    copy.__dict__.update(scanned.__dict__)
    copy.words = dict(scanned.words)
    return copy, status


@functools.lru_cache(maxsize=512)
def _scan_memo(line: str, profile: str) -> tuple[GBlock, int]:
    """:func:`_scan` of the last 512 lines: assumes the words are a pure function of the text and
    the profile (the result is never handed out, copies are: callers may change theirs)."""
    return _scan(line, profile)


def _scan(line: str, profile: str) -> tuple[GBlock, int]:
    """The words of ``line`` (see :func:`scan`), read now, word by word from the start,
    stopping at the first error."""
    g = GBlock()
    groups = _Groups()
    i = 0
    n = len(line)
    while i < n:
        letter = line[i]
        if not "A" <= letter <= "Z":
            return g, c.EXPECTED_COMMAND_LETTER
        parsed = read_float(line, i + 1)
        if parsed is None:
            return g, c.BAD_NUMBER_FORMAT
        value, i = parsed
        status = _word(g, letter, value, groups, profile)
        if status:
            return g, status
    return g, 0


def _word(g: GBlock, letter: str, value: float, groups: _Groups, profile: str) -> int:
    """One word into ``g``: 0, or its GRBL status."""
    if letter == "G" or letter == "M":
        int_value = math.trunc(value) % 256  # uint8(value), c_round(x) inlined
        x = 100.0 * (value - int_value)
        mantissa = (math.floor(x + 0.5) if x >= 0 else -math.floor(-x + 0.5)) % 65536
        if letter == "G":
            return _g_word(g, int_value, mantissa, groups, profile)
        return _m_word(g, int_value, mantissa, groups)
    return _value_word(g, letter, value, groups)


class _Groups:
    """The modal groups a line has used, and the last one named (see :data:`STALE_GROUP_WORDS`)."""

    def __init__(self) -> None:
        self.seen: set[str] = set()
        self.last = "G5"  # oracle: 'M21 G93' and 'M50 G94' are violations, 'M3 G91' is not

    def claim(self, group: str) -> int:
        """Use ``group`` once in the line: 0, or the modal-group violation; it becomes the group
        the stale words after it take."""
        if group in self.seen:
            return c.MODAL_GROUP_VIOLATION
        self.seen.add(group)
        self.last = group
        return 0


def _m_word(g: GBlock, code: int, mantissa: int, groups: _Groups) -> int:
    if mantissa:
        return c.COMMAND_VALUE_NOT_INTEGER
    if code in (0, 1, 2, 30):
        group = "M4"
        g.flow = code
    elif code in (3, 4, 5):
        group = groups.last  # oracle: see STALE_GROUP_WORDS
        g.spindle = code
    elif code in (8, 9):
        group = "M8"
        g.coolant = code
    elif code in (20, 21):
        group = groups.last
        g.coord_mode = code
    elif code == 50:
        group = groups.last
        g.unlock = True
    elif code == 95:
        group = "M95"
        g.home = True
    else:
        return c.UNSUPPORTED_COMMAND
    return groups.claim(group)


def _value_word(g: GBlock, letter: str, value: float, groups: _Groups) -> int:
    if letter not in _VALUE_WORDS:
        return c.UNSUPPORTED_COMMAND
    groups.last = _VALUE_WORD_STALE_GROUPS.get(letter, f"word {letter}")
    if letter in g.words:
        return c.WORD_REPEATED
    if letter in _NON_NEGATIVE_WORDS and value < 0:
        return c.NEGATIVE_VALUE
    g.words[letter] = value
    return 0


def _g_word(g: GBlock, code: int, mantissa: int, groups: _Groups, profile: str) -> int:
    if code in (38, 43) and not (code == 43 and mantissa == 10):
        return c.UNSUPPORTED_COMMAND  # probing and G43 are not modelled
    if code in (4, 10, 28, 30, 53, 92):
        group = "G0"
        if mantissa == 10 and code in (28, 30, 92):
            code = code * 10 + 1
            mantissa = 0
        g.nonmodal = code
        if code in NONMODAL_AXIS_COMMANDS:
            if g.axis_command:
                return c.AXIS_COMMAND_CONFLICT
            g.axis_command = True
    elif code in (43, 49):
        group = "G8"
        g.tool_length = 431 if code == 43 else 49
        mantissa = 0
    elif code in (0, 1, 2, 3, 5, 80):
        if code == 5 and profile == "classic":
            return c.UNSUPPORTED_COMMAND
        if code != 80:
            if g.axis_command:
                return c.AXIS_COMMAND_CONFLICT
            g.axis_command = True
        group = "G1"
        g.motion = code
    elif code in (17, 18, 19):
        group = "G2"
        g.plane = code
    elif code in (90, 91):
        if mantissa == 0:
            group = "G3"
            g.distance = code
        else:
            group = "G4"
            if mantissa != 10 or code == 90:
                return c.UNSUPPORTED_COMMAND
            mantissa = 0
    elif code in (93, 94):
        group = "G5"
        g.feed_mode = code
    elif code in (20, 21):
        group = "G6"
        g.units = code
    elif code == 40:
        group = "G7"
    elif 54 <= code <= 59:
        group = "G12"
        g.coord_select = code
    elif code == 61:
        group = "G13"
        if mantissa:
            return c.UNSUPPORTED_COMMAND
    else:
        return c.UNSUPPORTED_COMMAND
    if mantissa:
        return c.COMMAND_VALUE_NOT_INTEGER
    return groups.claim(group)
