"""What the firmware keeps across resets and the envelope must know: startup lines, work
offsets, soft-limit travel, the ``G1`` interpolation switch.

The firmware stores these in EEPROM, so another program (or an earlier session) may have left
them: startup lines ``$N0``/``$N1`` run after every reset out of Alarm and after every homing
(oracle: ``G91ok``), work offsets ``G54..G59`` (``G10 L2``/``L20``) add to absolute targets in
both coordinate modes (oracle: ``G10 L2 P1 X40`` then ``M20 G90 G0 X202 ...`` ends at x = 242),
soft limits ``$20``/``$130..$146`` decide which moves the firmware drops, and on the 2021
firmware ``$35=0`` makes ``M20 G1`` a joint-space move. The envelope guard reads them (``$N``,
``$#``, ``$$``) before the first line that moves the arm; this module parses the listings and
computes their effect. Pure module.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Final, TypeAlias

from mirobot_async._core.acceptance import merge_unknown, update_modes
from mirobot_async._core.line import ParsedLine, parse_line
from mirobot_async._core.modal import MotionModes

Joints: TypeAlias = tuple[float, float, float, float, float, float]

__all__ = [
    "PARSER_UNKNOWN",
    "SOFT_LIMIT_SETTINGS",
    "ZERO_OFFSET",
    "Offset",
    "ParserPosition",
    "WorkCoordinates",
    "apply_startup_lines",
    "changes_work_offsets",
    "parse_coordinate_system",
    "parse_startup_lines",
    "parse_work_offsets",
    "soft_limit_ranges",
    "soft_limits_from_settings",
    "work_offset",
]

Offset: TypeAlias = tuple[float, float, float, float, float, float, float]
"""Per axis word, in the order ``X Y Z A B C D``."""

ZERO_OFFSET: Final[Offset] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
SOFT_LIMIT_SETTINGS: Final = (20, *range(130, 137), *range(140, 147))
"""``$20`` (soft limits on) and the travel ``$130..$136`` / ``$140..$146``, in this order."""


@dataclass(frozen=True, slots=True)
class ParserPosition:
    """Where the firmware's parser measures joint-mode targets from when that is not where the
    queued motion ends: a move refused as locked still moves the parser to its target (oracle:
    ``G91 X10`` locked, ``M50``, ``G91 X1`` ends at 11). ``joints`` None: unknown (after an
    alarm, a lost reply, a refusal the client could not place) until a line with ``M20``/``M21``
    re-reads the arm's position."""

    joints: Joints | None
    rail: float | None = None


PARSER_UNKNOWN: Final = ParserPosition(None)


_STARTUP_RE: Final = re.compile(r"^\$N(\d+)=(.*)$")
_OFFSET_RE: Final = re.compile(r"^\[(G5[4-9]|G92|G28|G30):([-0-9.,]+)\]$")
_SYSTEM_RE: Final = re.compile(r"^G5[4-9]$")
_REPORT_ORDER: Final = "ABCDXYZ"  # $# prints the firmware's axis order a..g
_WORD_ORDER: Final = "XYZABCD"
# firmware axis letters a..g are J4, J5, J6, D, J1, J2, J3 (index into J1..J6, rail = 6)
_LETTER_TO_JOINT: Final = (3, 4, 5, 6, 0, 1, 2)
_WORK_CODES: Final = frozenset({10, 28, 30, 54, 55, 56, 57, 58, 59, 92})


def parse_startup_lines(output: Iterable[str]) -> tuple[str, ...] | None:
    """The stored lines of a ``$N`` listing (``$N0=G91``, ``$N1=``), empty ones left out;
    None when the listing has none of its lines (not a ``$N`` answer)."""
    lines: list[str] = []
    seen = False
    for raw in output:
        match = _STARTUP_RE.match(raw.strip())
        if match is not None:
            seen = True
            if match.group(2):
                lines.append(match.group(2))
    return tuple(lines) if seen else None


def parse_work_offsets(output: Iterable[str]) -> tuple[tuple[Offset, ...], Offset] | None:
    """The ``G54..G59`` offsets and the ``G92`` offset of a ``$#`` listing (axis-word order);
    None when a row is missing or malformed."""
    rows: dict[str, Offset] = {}
    for raw in output:
        match = _OFFSET_RE.match(raw.strip())
        if match is None:
            continue
        try:
            values = [float(v) for v in match.group(2).split(",")]
        except ValueError:
            return None
        if len(values) != len(_REPORT_ORDER):
            return None
        by_letter = dict(zip(_REPORT_ORDER, values, strict=True))
        w = [by_letter[letter] for letter in _WORD_ORDER]
        rows[match.group(1)] = (w[0], w[1], w[2], w[3], w[4], w[5], w[6])
    names = [f"G{n}" for n in range(54, 60)]
    if not all(name in rows for name in [*names, "G92"]):
        return None
    return tuple(rows[name] for name in names), rows["G92"]


def parse_coordinate_system(output: Iterable[str]) -> int | None:
    """The work coordinate system in effect (54..59) from a ``$G`` listing, or None."""
    for raw in output:
        text = raw.strip()
        if text.startswith("[") and text.endswith("]"):
            codes = [int(w[1:]) for w in text[1:-1].split() if _SYSTEM_RE.match(w)]
            if len(codes) == 1:
                return codes[0]
    return None


def changes_work_offsets(text: str) -> bool:
    """A line that may change the work offsets or the coordinate system in effect (``G10``,
    ``G92``, ``G54..G59``, ``G28.1``/``G30.1``, ``$RST=#``/``$RST=*``)."""
    parsed = parse_line(text)
    if parsed.dollar is not None:
        return parsed.text in ("$RST=#", "$RST=*") or parsed.dollar.kind == "unknown"
    return any(code in _WORK_CODES for code in parsed.g_codes)


def apply_startup_lines(
    modes: MotionModes, lines: Sequence[str] | None, *, certain: bool
) -> MotionModes:
    """The modes after the stored startup ``lines`` ran from ``modes`` (``certain``) or may have
    run (the modes they change become unknown). Unknown lines (None) make every mode unknown."""
    if lines is None:
        return MotionModes.unknown()
    after = modes
    for text in lines:
        after = update_modes(text, after)
    return after if certain else merge_unknown(modes, after)


def startup_lines_move(lines: Sequence[str] | None) -> bool:
    """Whether stored startup lines may move the arm or change the work offsets (unknown: yes)."""
    if lines is None:
        return True
    for text in lines:
        parsed = parse_line(text)
        if parsed.kind != "gcode" or parsed.axis_words or changes_work_offsets(text):
            return True
    return False


def soft_limits_from_settings(settings: Mapping[int, float]) -> tuple[float, ...] | None:
    """``($20, $130..$136, $140..$146)`` from a ``$$`` listing, or None if one is missing."""
    if not all(n in settings for n in SOFT_LIMIT_SETTINGS):
        return None
    return tuple(float(settings[n]) for n in SOFT_LIMIT_SETTINGS)


def with_setting(values: tuple[float, ...], number: int, value: float) -> tuple[float, ...]:
    """``values`` (as :func:`soft_limits_from_settings`) after ``$number=value``."""
    index = SOFT_LIMIT_SETTINGS.index(number)
    return (*values[:index], value, *values[index + 1 :])


def soft_limit_ranges(
    values: tuple[float, ...] | None,
) -> tuple[tuple[float, float], ...] | None:
    """The firmware's soft-limit ranges of J1..J6 and the rail (index 6), or None when soft
    limits are off (``$20=0``) or unknown."""
    if values is None or values[0] == 0:
        return None
    ranges: list[tuple[float, float]] = [(0.0, 0.0)] * 7
    for k, joint in enumerate(_LETTER_TO_JOINT):
        ranges[joint] = (-values[8 + k], values[1 + k])
    return tuple(ranges)


def reset_modes(lines: Sequence[str] | None, *, ran: bool | None) -> MotionModes:
    """The modes after a reset: power-on, then the startup lines (``ran`` None: may have run)."""
    if not lines and lines is not None:
        return MotionModes()
    if ran is False:
        return MotionModes()
    return apply_startup_lines(MotionModes(), lines, certain=ran is True)


def work_offset(
    systems: Sequence[Offset] | None, g92: Offset | None, coordinate: int | None
) -> Offset | None:
    """The offset in effect: the ``G54..G59`` row of ``coordinate`` plus ``G92``; when the
    coordinate system is unknown, the common row if all six are equal; else None."""
    if systems is None or g92 is None:
        return None
    if coordinate is not None:
        row = systems[coordinate - 54]
    elif all(other == systems[0] for other in systems):
        row = systems[0]
    else:
        return None
    a, b = row, g92
    return (
        a[0] + b[0],
        a[1] + b[1],
        a[2] + b[2],
        a[3] + b[3],
        a[4] + b[4],
        a[5] + b[5],
        a[6] + b[6],
    )


@dataclass
class WorkCoordinates:
    """What the client knows of the work offsets: ``G54..G59`` (``$#``, stored), ``G92``
    (``$#``; cleared by a reset and homing), the system in effect (``$G``; ``G54`` after a
    reset, homing, program end or a line stating it), and the queries the firmware refused
    (not asked again: what they would give stays unknown)."""

    systems: tuple[Offset, ...] | None = None
    g92: Offset | None = None
    coordinate: int | None = None
    refused: set[str] = field(default_factory=set)

    def wanted(self, startup_known: bool) -> tuple[str, ...]:
        """The queries still needed: ``$N`` (unless ``startup_known``), ``$#``, ``$G``."""
        systems = self.systems
        wanted: tuple[str, ...] = () if startup_known else ("$N",)
        wanted += ("$#",) if systems is None or self.g92 is None else ()
        which = systems is None or any(row != systems[0] for row in systems)
        wanted += ("$G",) if self.coordinate is None and which else ()
        return tuple(q for q in wanted if q not in self.refused)

    def adopt(self, query: str, output: Sequence[str] | None) -> None:
        """The answer to ``$#`` or ``$G`` (None: the firmware refused the query)."""
        if output is None:
            self.refused.add(query)
        elif query == "$#" and (offsets := parse_work_offsets(output)) is not None:
            self.systems, self.g92 = offsets
        elif query == "$G":
            self.coordinate = parse_coordinate_system(output)

    def offset(self, parsed: ParsedLine | None) -> Offset | None:
        """The offset in effect for ``parsed`` (a ``G54`` in it selects ``G54`` first)."""
        g54 = parsed is not None and 54 in parsed.g_codes
        return work_offset(self.systems, self.g92, 54 if g54 else self.coordinate)

    def reinitialised(self, startup_lines: Sequence[str] | None, *, ran: bool) -> None:
        """A reset or homing: ``G54``, no ``G92``; the startup lines (may have) run."""
        self.coordinate, self.g92 = 54, ZERO_OFFSET if self.systems is not None else None
        if ran and startup_lines_move(startup_lines):
            self.systems = self.g92 = None  # read them again

    def follow(self, parsed: ParsedLine) -> None:
        """A line written: ``G54`` and program end select ``G54``; a line the client could
        not follow that changes the offsets makes them unknown."""
        if 54 in parsed.g_codes or parsed.program_end:
            self.coordinate = 54

    def forget_after(self, parsed: ParsedLine) -> None:
        """An unfollowed line that may change the offsets or the system in effect."""
        if changes_work_offsets(parsed.source):
            self.systems = self.g92 = None
            if any(55 <= code <= 59 for code in parsed.g_codes):
                self.coordinate = None
