"""Whether the firmware accepts a line, and what the line leaves behind either way.

One reading of the firmware's G-code parser (GRBL 0.9j as the Mirobot runs it), from the one
parse of the line (:class:`~mirobot_async._core.line.ParsedLine`) and what is known of the
parser's modes (:class:`~mirobot_async._core.modal.MotionModes`): :func:`line_fate` says whether
the line gets ``ok`` (accepted; its motion may still be dropped: locked, soft limit) or an error,
and the modes after it. Validation (``mirobot check``, ``send()``), the modal tracking of every
line written and the safety envelope all take their verdict from here, so that none of them
predicts a line as run that the firmware refuses (the lines streamed behind it would then run
from a position nobody predicted).

The parser, in its order (oracle, classic ``20191228_2``; the emulator models the same):

1. the word scanner stops at the first bad word: an unknown code or letter, a fraction
   (``M20.5``), two words of one modal group, a repeated word, a negative ``F N P T S E``.
   ``M3 M4 M5 M20 M21 M50`` take the modal group of the ``G``/``M`` word before them in the line
   (a value word in between leaves another group; first in a line they take the feed-mode
   group), so ``G90 M21``, ``G0 M20``, ``G91 M3``, ``G90 M50`` and ``M21 G93`` are violations;
2. the checks of the whole line: ``G4`` needs ``P``, a ``G1``/``G2``/``G3``/``G5`` needs a feed
   rate (none after homing: ``Undefined feed rate``), arcs need their words and a radius that
   spans the chord, every value word must be used by a command (``P`` without ``G4``);
3. on the classic firmware a refused line's ``M20``/``M21`` read before the error still switches
   the mode (and re-reads the arm's position), and its ``M50`` still unlocks; on 2021 a refused
   line changes nothing (ASSUMED, as the emulator).

A verdict that depends on what is unknown (the feed rate at connect, the pose an absolute arc
starts from, the classic firmware's arc plane) is ``None``. Alarm (``Alarm lock``) is the
caller's. Pure module.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Final

from mirobot_async._core.line import CodeWord, ParsedLine, parse_line
from mirobot_async._core.modal import HOMED, MM_PER_INCH, MotionModes, line_feed, modes_after

__all__ = [
    "ARC_START_UNKNOWN",
    "Fate",
    "Scan",
    "line_fate",
    "merge_unknown",
    "modes_after_refusal",
    "scan",
    "update_modes",
]

UNSUPPORTED: Final = "Unsupported command"
MODAL_GROUP: Final = "Modal group violation"
UNDEFINED_FEED: Final = "Undefined feed rate"
NOT_INTEGER: Final = "Invalid gcode ID:23"
AXIS_CONFLICT: Final = "Invalid gcode ID:24"
REPEATED: Final = "Invalid gcode ID:25"
NO_AXIS_WORDS: Final = "Invalid gcode ID:26"
BAD_LINE_NUMBER: Final = "Invalid gcode ID:27"
VALUE_MISSING: Final = "Invalid gcode ID:28"
G53_MOTION: Final = "Invalid gcode ID:30"
AXIS_WORDS_EXIST: Final = "Invalid gcode ID:31"
NOT_IN_PLANE: Final = "Invalid gcode ID:32"
INVALID_TARGET: Final = "Invalid gcode ID:33"
ARC_RADIUS: Final = "Arc radius error"
NO_OFFSETS: Final = "Invalid gcode ID:35"
UNUSED: Final = "Invalid gcode ID:36"
TOOL_LENGTH_AXIS: Final = "Invalid gcode ID:37"

ARC_START_UNKNOWN: Final = "the pose the arc starts from (absolute arcs)"
_HINTS: Final = {
    UNDEFINED_FEED: "no feed rate in effect (after homing, or F0); state F in the line",
    NO_AXIS_WORDS: "the command needs axis words",
    VALUE_MISSING: "a word the command needs is missing (G4 needs P)",
    AXIS_WORDS_EXIST: "axis words with motion cancelled (G80)",
    NOT_IN_PLANE: "an arc needs X and/or Y",
    INVALID_TARGET: "an arc's end is its start",
    ARC_RADIUS: "the chord is longer than 2R",
    NO_OFFSETS: "G2/G3 needs R",
    UNUSED: "a word no command in the line uses",
    AXIS_CONFLICT: "two commands in the line take the axis words",
    REPEATED: "a word appears twice",
    NOT_INTEGER: "a command number with a fraction",
}

_STALE: Final = frozenset({3, 4, 5, 20, 21, 50})
"""``M`` codes that take the modal group of the word before them (see the module docstring)."""
_M_GROUPS: Final = {0: "M4", 1: "M4", 2: "M4", 30: "M4", 8: "M8", 9: "M8"}
_G_GROUPS: Final = {
    **dict.fromkeys((4, 10, 28, 30, 53, 92), "G0"),
    **dict.fromkeys((43, 49), "G8"),
    **dict.fromkeys((0, 1, 2, 3, 5, 80), "G1"),
    **dict.fromkeys((17, 18, 19), "G2"),
    **dict.fromkeys((90, 91), "G3"),
    **dict.fromkeys((93, 94), "G5"),
    **dict.fromkeys((20, 21), "G6"),
    40: "G7",
    **dict.fromkeys(range(54, 60), "G12"),
    61: "G13",
}
_VALUE_LETTERS: Final = frozenset("FIJKLNPRSETXYZABCD")
_NON_NEGATIVE: Final = frozenset("FNPTSE")
_VALUE_GROUPS: Final = {"F": "G0", "S": "G8", "N": "G5"}
"""The group a value word leaves for a stale word after it (oracle: ``F100 M3 G4``)."""
_AXES: Final = "XYZABCD"
_ALWAYS_USED: Final = frozenset("NFSTE")
_AXIS_COMMANDS: Final = frozenset({10, 28, 30, 92})
_CLASSIC_PLANE_WORDS: Final = frozenset("ABC")
MAX_LINE_NUMBER: Final = 9999999


@dataclass(frozen=True, slots=True)
class Scan:
    """What the firmware's word scanner made of a line (step 1 of the module docstring)."""

    error: str | None
    """The error it stopped at, or None (the words are valid one by one)."""
    word: str | None
    """The word it stopped at, as written (None: a syntax error, or no error)."""
    coordinate: int | None
    """The last ``M20``/``M21`` it read (20, 21), the word it stopped at included."""
    unlock: bool
    """It read an ``M50``."""
    nonmodal: int | None = None
    """``4 10 28 30 53 92`` (``281 301 921``: the ``.1`` forms), when the line has one."""
    explicit_motion: bool = False
    """A ``G0``..``G3``/``G5`` (or ``G10 G28 G30 G92``) in the line: an axis command."""
    plane: int | None = None
    tool_length: int | None = None


@lru_cache(maxsize=2048)
def scan(text: str, firmware: str) -> Scan:
    """The scanner's reading of the normalized line ``text`` (its words from the one parse) on
    ``firmware`` (``"classic"`` knows no ``G5``). Remembered (the last 2048): assumes it is a
    pure function of the text and the family, and :class:`Scan` immutable."""
    parsed = parse_line(text)
    seen: set[str] = set()
    values: set[str] = set()
    last = "G5"  # oracle: 'M21 G93' is a violation
    coordinate: int | None = None
    unlock = explicit = False
    nonmodal = plane = tool = None
    for word in parsed.words:
        letter = word.letter
        if not isinstance(word, CodeWord):
            if letter not in _VALUE_LETTERS:
                return Scan(UNSUPPORTED, str(word), coordinate, unlock)
            last = _VALUE_GROUPS.get(letter, "word " + letter)
            if letter in values:
                return Scan(REPEATED, str(word), coordinate, unlock)
            if letter in _NON_NEGATIVE and word.value < 0:
                return Scan("Value < 0", str(word), coordinate, unlock)
            values.add(letter)
            continue
        code, mantissa = word.code, word.mantissa
        if letter == "M":
            if mantissa:
                return Scan(NOT_INTEGER, str(word), coordinate, unlock)
            if code in _STALE:
                group = last
                if code in (20, 21):
                    coordinate = code
                unlock = unlock or code == 50
            elif code in _M_GROUPS:
                group = _M_GROUPS[code]
            else:
                return Scan(UNSUPPORTED, str(word), coordinate, unlock)
        else:
            found = _g_group(code, mantissa, explicit, firmware)
            if isinstance(found, str):
                return Scan(found, str(word), coordinate, unlock)
            group, code = found
            if group == "G0":
                nonmodal = code
            if code in (0, 1, 2, 3, 5) or code in _AXIS_COMMANDS:
                explicit = True
            if group == "G2":
                plane = code
            if group == "G8":
                tool = code
        if group in seen:
            return Scan(MODAL_GROUP, str(word), coordinate, unlock)
        seen.add(group)
        last = group
    return Scan(None, None, coordinate, unlock, nonmodal, explicit, plane, tool)


def _g_group(code: int, mantissa: int, explicit: bool, firmware: str) -> tuple[str, int] | str:
    """(the modal group of ``G<code>.<mantissa>``, the code as the line keeps it), or the
    scanner's error."""
    if code == 43 and mantissa == 10:
        return "G8", 431
    group = _G_GROUPS.get(code)
    if group is None or code == 43 or (code == 5 and firmware == "classic"):
        return UNSUPPORTED
    if group == "G0" and mantissa == 10 and code in (28, 30, 92):
        return group, code * 10 + 1
    if (code in _AXIS_COMMANDS or code in (0, 1, 2, 3, 5)) and explicit:
        return AXIS_CONFLICT
    if code in (90, 91) and mantissa:
        return ("G4", code) if mantissa == 10 and code == 91 else UNSUPPORTED
    if code == 61 and mantissa:
        return UNSUPPORTED
    if mantissa and code != 49:
        return NOT_INTEGER
    return group, code


@dataclass(frozen=True, slots=True)
class Fate:
    """The firmware's verdict on a line and the modes it leaves (see :func:`line_fate`)."""

    accepted: bool | None
    """``ok`` (True), an error (False), or unknown (None: see :attr:`why`)."""
    modes: MotionModes
    """The modes after the line, accepted or not (``None`` parts: unknown)."""
    why: str | None = None
    """The firmware's error text (refused), or what the verdict depends on (unknown)."""
    word: str | None = None
    """The word the firmware stopped at, when it is one word's fault."""
    hint: str | None = None
    """What the refusal means, when the firmware's text does not say it."""

    @property
    def problem(self) -> str:
        """The refusal (or the unknown) said for a message naming the line."""
        if self.accepted is None:
            return f"whether the firmware accepts it depends on {self.why}, which is unknown"
        where = f" at {self.word}" if self.word is not None else ""
        hint = self.hint or _HINTS.get(str(self.why))
        return f"the firmware refuses it{where} ('{self.why}'{': ' + hint if hint else ''})"


def merge_unknown(a: MotionModes, b: MotionModes) -> MotionModes:
    """Modes that are the same in ``a`` and ``b``, the others unknown."""
    if a == b:
        return a
    return MotionModes(
        a.cartesian if a.cartesian == b.cartesian else None,
        a.relative if a.relative == b.relative else None,
        a.motion if a.motion == b.motion else None,
        a.inches if a.inches == b.inches else None,
        a.feed if a.feed == b.feed else None,
        a.inverse_time if a.inverse_time == b.inverse_time else None,
    )


def line_fate(parsed: ParsedLine, modes: MotionModes, firmware: str | None) -> Fate:
    """The firmware's verdict on ``parsed`` sent with the parser in ``modes`` (not in Alarm),
    and the modes after it; ``firmware`` None (unknown): what both profiles agree on."""
    if firmware in ("classic", "2021"):
        return _fate(parsed, modes, firmware)
    a, b = _fate(parsed, modes, "classic"), _fate(parsed, modes, "2021")
    if a == b:
        return a
    accepted = a.accepted if a.accepted == b.accepted else None
    why = a.why if accepted is not None else "the firmware profile"
    return Fate(accepted, merge_unknown(a.modes, b.modes), why)


def _fate(parsed: ParsedLine, modes: MotionModes, firmware: str) -> Fate:
    if parsed.kind == "empty":
        return Fate(True, modes)
    if parsed.kind == "dollar":
        assert parsed.dollar is not None
        kind = parsed.dollar.kind
        if kind == "homing":
            return Fate(True, HOMED)  # (then the stored startup lines run: the caller's)
        if kind in ("startup", "restore", "unknown"):
            return Fate(None, MotionModes.unknown(), "what the $ line changes")
        return Fate(None if kind not in ("help", "query", "unlock") else True, modes, "$")
    if parsed.syntax_error == "Line overflow":
        return Fate(False, modes, parsed.syntax_error)  # (its tail would be a line of its own)
    found = scan(parsed.text, firmware)
    error, word = found.error, found.word
    if error is None and parsed.syntax_error is not None:
        error = parsed.syntax_error
    if error is None:
        accepted, error = _check(parsed, found, modes, firmware)
        if accepted:
            return Fate(True, modes_after(parsed, modes))
        if accepted is None:
            rejected = _rejected(found, modes, firmware)
            return Fate(None, merge_unknown(modes_after(parsed, modes), rejected), error)
        motion = modes.motion if parsed.motion is None else parsed.motion
        if error == UNSUPPORTED and motion in (2, 3, 5) and parsed.axis_letters:
            hint = "arcs and G5 need the 2021 firmware and M20"
            return Fate(False, _rejected(found, modes, firmware), error, f"G{motion}", hint)
    return Fate(False, _rejected(found, modes, firmware), error, word)


def _rejected(found: Scan, modes: MotionModes, firmware: str) -> MotionModes:
    """The modes after a refused line: on classic, its ``M20``/``M21`` read before the error
    still switches the mode (oracle: ``M20 Q1`` -> ``Motion_MODE:1``)."""
    if firmware != "classic" or found.coordinate is None:
        return modes
    return replace(modes, cartesian=found.coordinate == 20)


def _check(
    parsed: ParsedLine, found: Scan, modes: MotionModes, firmware: str
) -> tuple[bool | None, str | None]:
    """Step 2 of the module docstring on a line the scanner read whole: (accepted, the error or
    what the verdict depends on)."""
    values = parsed.values
    axes = parsed.axis_letters
    nonmodal = found.nonmodal
    axis_words_used = nonmodal in _AXIS_COMMANDS
    axis_command = not axis_words_used and (found.explicit_motion or bool(axes))
    used = set(_ALWAYS_USED)
    if found.tool_length == 431:
        return False, TOOL_LENGTH_AXIS
    if values.get("N", 0.0) > MAX_LINE_NUMBER:
        return False, BAD_LINE_NUMBER
    coordinate, distance, units = parsed.coordinate_mode, parsed.distance, parsed.units
    cartesian = modes.cartesian if coordinate is None else coordinate == 20
    relative = modes.relative if distance is None else distance == 91
    inches = modes.inches if units is None else units == 20
    motion = modes.motion if parsed.motion is None else parsed.motion
    feed, inverse = line_feed(parsed, modes, inches)
    if axis_command and "F" not in values and inverse is not False:
        if inverse:
            return False, UNDEFINED_FEED
        return None, "the feed mode (G93/G94)"
    if nonmodal == 4:
        if "P" not in values:
            return False, VALUE_MISSING
        used.add("P")
    if nonmodal in (10, 92) and not axes:
        return False, NO_AXIS_WORDS
    if nonmodal == 10:
        if "L" not in values or "P" not in values:
            return False, VALUE_MISSING
        if values["L"] not in (2.0, 20.0) or values["P"] not in range(7):
            return False, UNSUPPORTED
        used |= {"L", "P"}
    if axis_words_used:
        used |= set(_AXES)
    if nonmodal == 53 and motion not in (0, 1):
        return (None, "the motion mode") if motion is None else (False, G53_MOTION)
    if motion == 80:
        if axes and not axis_words_used:
            return False, AXIS_WORDS_EXIST
    elif axis_command:
        if motion is None:
            return None, "the motion mode (G0/G1/G2/G3)"
        verdict = _motion_check(parsed, motion, cartesian, relative, inches, feed, firmware)
        if verdict is not None:
            return verdict
        used |= set(_AXES)
        if motion in (2, 3):
            used.add("R")
    unused = [letter for letter in values if letter not in used]
    if unused:
        return False, UNUSED
    return True, None


def _motion_check(
    parsed: ParsedLine,
    motion: int,
    cartesian: bool | None,
    relative: bool | None,
    inches: bool | None,
    feed: float | None,
    firmware: str,
) -> tuple[bool | None, str | None] | None:
    """The checks of a motion line (None: it passes them)."""
    values = parsed.values
    if motion in (2, 3) and firmware == "classic":
        return False, UNSUPPORTED  # (or another error: its arc plane is the wrist's, oracle)
    if motion in (2, 3, 5) and cartesian is None:
        return None, "the coordinate mode (M20/M21)"
    if motion in (2, 3, 5) and not cartesian:
        return False, UNSUPPORTED
    if motion == 0:
        return None
    if feed is None:
        return None, "the feed rate in effect (state F in the line)"
    if feed == 0.0:
        return False, UNDEFINED_FEED
    if motion not in (2, 3):
        return None
    if not parsed.axis_letters:
        return False, NO_AXIS_WORDS
    if "X" not in values and "Y" not in values:
        return False, NOT_IN_PLANE
    if "R" not in values:
        if "I" in values or "J" in values:
            return None, "the arc's centre (I/J arcs are not modelled)"
        return False, NO_OFFSETS
    if relative is not True or inches is None:
        return None, ARC_START_UNKNOWN
    scale = MM_PER_INCH if inches else 1.0
    x, y = values.get("X", 0.0) * scale, values.get("Y", 0.0) * scale
    if x == 0.0 and y == 0.0:
        return False, INVALID_TARGET
    radius = values["R"] * scale
    if 4.0 * radius * radius - x * x - y * y < 0:
        return False, ARC_RADIUS
    return None


PARSER_ERRORS: Final = frozenset({"Alarm lock"})
"""Errors given before the line is read at all (nothing of it acts, on any profile)."""


def modes_after_refusal(
    parsed: ParsedLine, modes: MotionModes, firmware: str | None, error: str | None
) -> MotionModes:
    """The modes after the firmware refused ``parsed`` with ``error`` (its text), sent in
    ``modes``: unchanged, but on classic a ``M20``/``M21`` its scanner read still switches the
    mode (``Alarm lock`` comes before the scanner); ``firmware`` None: that mode unknown."""
    if parsed.kind != "gcode" or error in PARSER_ERRORS or parsed.syntax_error == "Line overflow":
        return modes
    found = scan(parsed.text, firmware or "2021")
    if firmware is None and found.coordinate is not None:
        return replace(modes, cartesian=None)
    return _rejected(found, modes, firmware or "2021")


def update_modes(
    line: str | bytes | ParsedLine, modes: MotionModes, firmware: str | None = None
) -> MotionModes:
    """The modes after ``line`` is written (checked or not: accepted or refused, as
    :func:`line_fate` says); never raises. Homing re-initialises them (the stored startup lines
    are the caller's)."""
    parsed = line if isinstance(line, ParsedLine) else parse_line(line)
    return line_fate(parsed, modes, firmware).modes
