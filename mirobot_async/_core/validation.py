"""One validation of raw lines: what ``mirobot check`` reports is what ``send()`` refuses.

:func:`line_problems` judges one :class:`~mirobot_async._core.line.ParsedLine` the way the
firmware's parser would (PROTOCOL.md sections 2, 6 and 7: filtering, comments, the 80-byte limit,
words, modal groups, settings) plus the ranges of PWM values and of absolute ``M21`` joint targets,
and numbers the firmware reads differently from how they are written (``X0000000030`` is 0,
``M16404`` is ``M20``), and lines that would end elsewhere streamed than sent one at a time
(an ``M20``/``M21`` restarts from where the arm is: :class:`~mirobot_async._core.modal.Chaining`;
raised as :class:`~mirobot_async.errors.MotionChainError`). :func:`check_line` /
:func:`check_program` return those problems as text (the CLI's ``check``);
:func:`validate_line` raises them as one :class:`~mirobot_async.errors.MirobotUsageError` (the
client's ``send()`` and ``stream()``, whose
opt-out is explicit). Pure module: no I/O.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Final

from mirobot_async._core.acceptance import MODAL_GROUP, UNDEFINED_FEED, Fate, line_fate
from mirobot_async._core.line import (
    MAX_LINE_LENGTH,
    REALTIME_BYTES,
    CodeWord,
    ParsedLine,
    Word,
    parse_line,
)
from mirobot_async._core.modal import HOMED, POWER_ON_FEED, Chaining, MotionModes
from mirobot_async._core.settings import setting_problem
from mirobot_async._core.values import (
    COMMAND_PROFILE,
    JOINT_NAMES,
    JOINT_RANGES,
    PWM_MAX,
    PWM_MIN,
    RAIL_RANGES,
    check_firmware,
    show_number,
)
from mirobot_async.errors import (
    InvalidLineError,  # defined with the error tree
    MirobotUsageError,
    MotionChainError,
)

__all__ = [
    "InvalidLineError",
    "ModalState",
    "check_line",
    "check_program",
    "line_problems",
    "may_differ_by_profile",
    "parse_words",
    "validate_line",
]

_KNOWN_LETTERS: Final = frozenset("GMXYZABCDFPSERN")
_JOINT_LETTERS: Final = ("X", "Y", "Z", "A", "B", "C")
_G_CODES: Final[dict[str, frozenset[int]]] = {
    "classic": frozenset({0, 1, 4, 21, 90, 91}),
    "2021": frozenset({0, 1, 2, 3, 4, 5, 21, 90, 91}),
    "2024": frozenset({0, 1, 2, 3, 4, 5, 21, 90, 91}),  # ASSUMED: the 2021 manual's
}
_M_CODES: Final = frozenset({2, 3, 4, 5, 20, 21, 30, 50})
_G_GROUPS: Final[dict[int, str]] = {
    0: "motion",
    1: "motion",
    2: "motion",
    3: "motion",
    5: "motion",
    4: "dwell",
    21: "units",
    90: "distance",
    91: "distance",
}
_M_GROUPS: Final[dict[int, str]] = {
    20: "coordinate mode",
    21: "coordinate mode",
    2: "program end",
    30: "program end",
    3: "PWM 1",
    4: "PWM 2",
    5: "PWM 1",
    50: "unlock",
}
_REALTIME: Final[dict[str, str]] = {
    "?": "a status request",
    "!": "a feed hold",
    "~": "a cycle start",
    "%": "a soft reset of the robot",
    "@": "the safety door (it stops reading lines until '~')",
}
_ODD_SOURCE: Final = re.compile("[\r\n" + re.escape(REALTIME_BYTES) + "]|[^\x00-\x7e]")
"""A character :func:`_syntax_problems` reports: a line break, a realtime byte, not ASCII."""
_DOLLAR_SIMPLE: Final = frozenset({"$", "$$", "$#", "$G", "$I", "$N", "$C", "$X", "$H", "$HH"})
_DOLLAR_2021: Final = frozenset({*(f"$H{n}" for n in range(8)), "$HE", "$M"})


@dataclass(slots=True)
class ModalState:
    """Parser state that persists between lines (modal words), as after power-on or reset.

    :func:`check_line` updates it in place so that consecutive lines are judged in context.
    """

    cartesian: bool | None = False
    """``M20`` in effect (else ``M21``, the power-on default); ``None``: unknown."""
    relative: bool | None = False
    """``G91`` in effect (else ``G90``, the power-on default); ``None``: unknown."""
    motion: int | None = 0
    """The motion code in effect (``G0`` at power-on); ``None``: unknown."""
    chain: Chaining = field(default_factory=Chaining)
    """Which joints may still move and which the parser took from where the arm was (see
    :class:`~mirobot_async._core.modal.Chaining`): a line reading those is reported."""
    feed: float | None = POWER_ON_FEED
    """The feed rate in effect (0 after homing: a ``G1`` without ``F`` is refused); None:
    unknown."""
    inverse_time: bool | None = False
    """``G93`` in effect; None: unknown."""

    @classmethod
    def unknown(cls) -> ModalState:
        """Nothing known (a client on an arm in use): mode-dependent ranges are checked only
        when the line states its modes."""
        return cls(None, None, None, feed=None)

    @classmethod
    def of(cls, modes: MotionModes, chain: Chaining) -> ModalState:
        """The state of a client whose modes are ``modes`` (a new object)."""
        return cls(
            modes.cartesian, modes.relative, modes.motion, chain, modes.feed, modes.inverse_time
        )

    def copy(self) -> ModalState:
        """An equal state (a new object)."""
        return replace(self)

    def modes(self) -> MotionModes:
        """The motion modes (units: mm; ``G20`` is refused by the check)."""
        return MotionModes(
            self.cartesian, self.relative, self.motion, False, self.feed, self.inverse_time
        )

    def take(self, modes: MotionModes) -> None:
        """Follow ``modes`` (the modes after a line, as the firmware leaves them)."""
        self.cartesian, self.relative, self.motion = modes.cartesian, modes.relative, modes.motion
        self.feed, self.inverse_time = modes.feed, modes.inverse_time


def parse_words(line: str | bytes) -> list[tuple[str, float]]:
    """The G-code words of a line as (letter, value) pairs, in order: ``"G1X10 f200"`` ->
    ``[("G", 1.0), ("X", 10.0), ("F", 200.0)]`` (values as the firmware reads them). Raises
    MirobotUsageError on syntax errors and on ``$`` commands (which are not words)."""
    parsed = parse_line(line)
    if parsed.kind == "dollar":
        raise MirobotUsageError(f"line={parsed.text!r} is a $ command, not G-code words")
    if parsed.syntax_error is not None:
        raise MirobotUsageError(f"line={parsed.text!r}: {_syntax_text(parsed)}")
    return [(word.letter, word.value) for word in parsed.words]


def _syntax_text(parsed: ParsedLine) -> str:
    error = parsed.syntax_error
    if error == "Expected command letter":
        at = len("".join(str(w) for w in parsed.words))
        return f"expected a command letter at {parsed.text[at : at + 8]!r} ('{error}')"
    if error == "Bad number format":
        at = len("".join(str(w) for w in parsed.words))
        letter = parsed.text[at : at + 1]
        return f"the letter {letter} is not followed by a number ('{error}')"
    return f"'{error}'"


def _range_text(low: float, high: float) -> str:
    return f"{show_number(low)}..{show_number(high)}"


def _lossy(word: Word) -> str:
    return (
        f"{word}: the firmware keeps only 8 digits (leading zeros count) and reads it as "
        f"{show_number(word.value)}; write it with at most 8 digits"
    )


def _check_dollar(parsed: ParsedLine, profile: str, state: ModalState, problems: list[str]) -> None:
    norm = parsed.text
    dollar = parsed.dollar
    assert dollar is not None
    if norm in _DOLLAR_SIMPLE or norm in _DOLLAR_2021:
        if norm in _DOLLAR_2021 and COMMAND_PROFILE[profile] != "2021":
            problems.append(f"{norm} needs the 2021 firmware")
            return
        if dollar.kind == "homing":
            state.take(HOMED)
        return
    if norm.startswith(("$N0=", "$N1=")) or norm in ("$RST=$", "$RST=#", "$RST=*"):
        return
    if dollar.kind == "homing":
        problems.append(
            f"{norm} is not a documented homing command, but the firmware homes the arm for it"
        )
        return
    if dollar.kind != "setting":
        if dollar.error == "Invalid statement" and norm[1:].isdigit():
            problems.append(f"{norm} has no '=value' ('Invalid statement')")
        elif dollar.error == "Bad number format" and "=" in norm:
            problems.append(f"{norm}: the value is not a number ('Bad number format')")
        else:
            problems.append(f"unknown $ command {norm!r} ('Invalid statement')")
        return
    assert dollar.number is not None and dollar.value is not None
    if not dollar.canonical:
        problems.append(
            f"{norm}: the firmware reads this as ${dollar.number}={show_number(dollar.value)}; "
            "write it in that form"
        )
        return
    problem = setting_problem(dollar.number, dollar.value, profile, in_line=True)
    if problem is not None:
        problems.append(problem)


def _code_problem(word: CodeWord, profile: str) -> str | None:
    if word.fraction_error:
        return f"{word} is not an integer command ('Invalid gcode ID:23')"
    if not word.canonical:
        return (
            f"{word} is read by the firmware as {word.letter}{word.code}; "
            f"write {word.letter}{word.code}"
        )
    code = word.code
    if word.letter == "G" and code == 20:
        return (
            "G20 switches to inches: every later number would be read in inches "
            "(this library works in mm; not supported)"
        )
    known = _G_CODES[profile] if word.letter == "G" else _M_CODES
    if code not in known:
        if word.letter == "G" and code in _G_CODES["2021"]:
            return f"{word} needs the 2021 firmware"
        return f"{word} is not a Mirobot command ('Unsupported command')"
    return None


def _check_gcode(parsed: ParsedLine, profile: str, state: ModalState, problems: list[str]) -> None:
    found, modes = _gcode_verdict(parsed.source, profile, state.modes())
    problems.extend(found)
    state.take(modes)


@lru_cache(maxsize=1024)
def _gcode_verdict(
    source: str, profile: str, modes: MotionModes
) -> tuple[tuple[str, ...], MotionModes]:
    """:func:`_judge_gcode` of the line ``source`` from a state with these modes: its problems
    and the modes after it. Remembered (the last 1024): assumes the verdict is a pure function
    of the text, the profile and the modes (a program repeats its lines)."""
    state = ModalState.of(modes, Chaining())
    problems: list[str] = []
    _judge_gcode(parse_line(source), profile, state, problems)
    return tuple(problems), state.modes()


def _judge_gcode(parsed: ParsedLine, profile: str, state: ModalState, problems: list[str]) -> None:
    """The problems of a G-code line (its words, then the firmware's verdict on it from
    ``state``), and ``state`` as the firmware leaves it."""
    fate = line_fate(parsed, state.modes(), profile)
    _word_problems(parsed, profile, state, problems)
    if fate.accepted is False and not any(
        str(fate.why) in problem or (fate.word is not None and fate.word in problem)
        for problem in problems
    ):  # (said once: a word already reported is why the firmware stops there)
        problems.append(_fate_problem(fate))
    state.take(fate.modes)


def _word_problems(
    parsed: ParsedLine, profile: str, state: ModalState, problems: list[str]
) -> None:
    if parsed.syntax_error is not None:
        problems.append(_syntax_text(parsed))
        return
    groups: dict[str, CodeWord] = {}  # the first word of each modal group
    values: dict[str, float] = {}
    motion: int | None = None
    dwell_seen = False
    new_cartesian: bool | None = None
    new_relative: bool | None = None
    for word in parsed.words:
        letter, value = word.letter, word.value
        if word.lossy:
            problems.append(_lossy(word))
        if isinstance(word, CodeWord):
            problem = _code_problem(word, profile)
            if problem is not None:
                problems.append(problem)
                continue
            code = word.code
            group = (_G_GROUPS if letter == "G" else _M_GROUPS)[code]
            if group in groups:
                first = groups[group]
                problems.append(
                    f"{first.letter}{first.code} and {letter}{code} are in the same modal group "
                    "('Modal group violation')"
                )
                continue
            groups[group] = word
            if letter == "G":
                if group == "motion":
                    motion = code
                    state.motion = code
                elif code == 4:
                    dwell_seen = True
                elif group == "distance":
                    new_relative = code == 91
            elif code in (20, 21):
                new_cartesian = code == 20
            continue
        if letter not in _KNOWN_LETTERS:
            problems.append(
                f"{word}: the letter {letter} is not used by the Mirobot "
                "(the firmware ignores or refuses it)"
            )
            continue
        if letter in values:
            problems.append(f"the word {letter} appears twice in the line (repeated word)")
            continue
        values[letter] = value
        if not math.isfinite(value):
            problems.append(f"{word} is too large a number for the firmware")
        elif letter in "FPS" and value < 0:
            problems.append(f"{word} is negative ('Value < 0')")
        elif letter in "SE" and (not value.is_integer() or not PWM_MIN <= value <= PWM_MAX):
            problems.append(f"{word}: PWM must be an integer {PWM_MIN}..{PWM_MAX}")

    cartesian = state.cartesian if new_cartesian is None else new_cartesian
    is_relative = state.relative if new_relative is None else new_relative

    if "F" in values and values["F"] == 0 and motion in (1, 2, 3):
        problems.append(f"G{motion} with F0 ('Undefined feed rate')")
    if dwell_seen and "P" not in values:
        problems.append("G4 needs P<seconds>")
    if "P" in values and not dwell_seen:
        problems.append("P is only used by G4 (unused word)")
    if motion in (2, 3):
        _check_arc(motion, values, cartesian is not False, is_relative is True, problems)
    elif "R" in values:
        problems.append("R is only used by G2/G3 arcs (unused word)")

    if cartesian is False and is_relative is False and not dwell_seen and parsed.axis_letters:
        for letter, joint in zip(_JOINT_LETTERS, JOINT_NAMES, strict=True):
            if letter in values:
                low, high = JOINT_RANGES[joint]
                if not low <= values[letter] <= high:
                    problems.append(
                        f"{joint}={show_number(values[letter])} is outside {_range_text(low, high)}"
                    )
        if "D" in values:
            low, high = RAIL_RANGES[profile]
            if not low <= values["D"] <= high:
                problems.append(
                    f"rail D={show_number(values['D'])} is outside {_range_text(low, high)}"
                )

    if new_cartesian is not None:
        state.cartesian = new_cartesian
    if new_relative is not None:
        state.relative = new_relative


def _fate_problem(fate: Fate) -> str:
    """The firmware's refusal of a line, said with the fix where there is one."""
    word = fate.word
    if fate.why == MODAL_GROUP and word is not None and word[0] == "M":
        return (
            f"{word} after another G or M word: the firmware refuses this order ('{fate.why}'); "
            "write M3/M4/M5/M20/M21/M50 first in the line, or use two lines"
        )
    if fate.why == UNDEFINED_FEED:
        return (
            "no feed rate in effect for this move (after homing or F0): the firmware refuses "
            f"it ('{fate.why}'); add F<speed> to the line"
        )
    return fate.problem


def _check_arc(
    motion: int, values: dict[str, float], cartesian: bool, is_relative: bool, problems: list[str]
) -> None:
    name = f"G{motion}"
    if not cartesian:
        problems.append(f"{name} is an arc in the XY plane: it needs Cartesian mode (M20)")
    if "R" not in values:
        problems.append(f"{name} needs R<radius>")
        return
    radius = values["R"]
    if radius <= 0:
        problems.append(
            f"{name} R{show_number(radius)}: the radius must be > 0 ('Arc radius error')"
        )
        return
    if "X" not in values and "Y" not in values:
        problems.append(f"{name} needs X and/or Y (the end point)")
        return
    if is_relative:
        chord = math.hypot(values.get("X", 0.0), values.get("Y", 0.0))
        if chord == 0:
            problems.append(f"{name} with a zero chord: a full circle is impossible with R")
        elif chord > 2 * radius + 1e-9:
            problems.append(
                f"{name}: the chord {show_number(chord)} mm is longer than "
                f"2R = {show_number(2 * radius)} ('Arc radius error')"
            )


def line_problems(
    parsed: ParsedLine, *, firmware: str = "2021", state: ModalState | None = None
) -> list[str]:
    """Problems the firmware would have with one parsed line, as human-readable messages.

    ``state`` is the modal state before the line (power-on defaults when omitted) and is updated
    in place, with the modes as the firmware leaves them (accepted or refused:
    :func:`~mirobot_async._core.acceptance.line_fate`, whose refusals are problems too: a
    ``G1`` without ``F`` after homing, ``G90 M21``).
    A line that would end elsewhere streamed than sent after the arm stopped is a problem too
    (the last one; :class:`~mirobot_async._core.modal.Chaining`). An empty list means no problem
    found.
    """
    state = ModalState() if state is None else state
    problems, chain = _problems(parsed, check_firmware(firmware), state)
    return problems if chain is None else [*problems, chain]


def _problems(parsed: ParsedLine, profile: str, state: ModalState) -> tuple[list[str], str | None]:
    """The problems of :func:`line_problems`, and apart from them the chaining problem."""
    before = state.modes()
    chain = state.chain.problem(parsed, before, profile)
    problems = _syntax_problems(parsed, profile, state)
    state.chain = state.chain.after(parsed, before, profile)
    return problems, chain


def _follow(parsed: ParsedLine, profile: str, state: ModalState) -> str | None:
    """What :func:`_problems` does to ``state`` (and its chaining problem), without judging
    the rest of the line: for :func:`~mirobot_async._core.stream_verdict.first_restart`, which
    reports only chaining. Keep in step with :func:`_check_dollar` and :func:`_check_gcode` (a
    unit test compares them)."""
    before = state.modes()
    chain = state.chain.problem(parsed, before, profile)
    if parsed.syntax_error is None:
        if parsed.kind == "gcode":
            _follow_gcode(parsed, profile, state)
        elif parsed.kind == "dollar":
            norm = parsed.text
            assert parsed.dollar is not None
            if (
                parsed.dollar.kind == "homing"
                and (norm in _DOLLAR_SIMPLE or norm in _DOLLAR_2021)
                and (norm not in _DOLLAR_2021 or COMMAND_PROFILE[profile] == "2021")
            ):
                state.take(HOMED)
    state.chain = state.chain.after(parsed, before, profile)
    return chain


def _follow_gcode(parsed: ParsedLine, profile: str, state: ModalState) -> None:
    """The modes :func:`_check_gcode` takes into ``state``: the firmware's (the fate of the
    line, accepted or refused)."""
    state.take(line_fate(parsed, state.modes(), profile).modes)


def _syntax_problems(parsed: ParsedLine, profile: str, state: ModalState) -> list[str]:
    text = parsed.source
    problems: list[str] = []
    if _ODD_SOURCE.search(text) is not None:  # rare: then say which
        if "\n" in text or "\r" in text:
            problems.append("contains a line break: the firmware would see several lines")
        odd = sorted({char for char in text if ord(char) > 0x7E})
        if odd:
            problems.append(f"contains characters outside printable ASCII: {''.join(odd)!r}")
        for char in sorted({char for char in text if char in REALTIME_BYTES}):
            problems.append(
                f"contains {char!r}, which the firmware takes at once as {_REALTIME[char]} "
                "and removes from the line"
            )
    if parsed.open_comment:
        problems.append("a '(' comment is not closed: the rest of the line is ignored")
    if parsed.syntax_error == "Line overflow":
        problems.append(
            f"the line is {len(parsed.text)} bytes after removing spaces and comments; "
            f"the firmware limit is {MAX_LINE_LENGTH} ('Line overflow')"
        )
        return problems
    if parsed.kind == "dollar":
        _check_dollar(parsed, profile, state, problems)
    elif parsed.kind == "gcode":
        _check_gcode(parsed, profile, state, problems)
    return problems


_PROFILE_G_CODES: Final = _G_CODES["2021"] - _G_CODES["classic"]
"""G codes only the 2021 profile knows (the other G and M codes are judged alike)."""


def may_differ_by_profile(parsed: ParsedLine, state: ModalState) -> bool:
    """False when :func:`line_problems` certainly finds the same problems for ``parsed`` (from
    ``state``) on both profiles, so a caller that does not know the profile need not judge it
    twice. Conservative: True whenever a profile-dependent rule may apply (``$`` lines, the
    2021-only G codes, the rail's range, and the 2021 path start of a Cartesian line, which
    :class:`~mirobot_async._core.modal.Chaining` reads)."""
    if parsed.kind == "dollar":
        return True
    if parsed.kind != "gcode" or parsed.syntax_error is not None:
        return False
    if "D" in parsed.values or any(code in _PROFILE_G_CODES for code in parsed.g_codes):
        return True
    if not parsed.axis_words:
        return False
    coordinate = parsed.coordinate_mode
    cartesian = state.cartesian if coordinate is None else coordinate == 20
    return cartesian is not False


def check_line(
    line: str | bytes, *, firmware: str = "2021", state: ModalState | None = None
) -> list[str]:
    """Problems the firmware would have with one raw line (see :func:`line_problems`)."""
    return line_problems(parse_line(line), firmware=firmware, state=state)


def check_program(
    lines: Iterable[str | bytes], *, firmware: str = "2021", start: MotionModes | None = None
) -> list[tuple[int, str]]:
    """Check the lines of a G-code file in order, as they are streamed (``mirobot run``), from
    the modes ``start`` (default: power-on; :data:`~mirobot_async._core.modal.HOMED` for a
    program run right after homing, whose feed rate is then 0): a line that would end elsewhere
    than when the lines are sent one at a time, each after the arm stopped, is reported with
    the fix (see :class:`~mirobot_async._core.modal.Chaining`).

    Returns (1-based line number, problem) pairs; modal words carry over between lines.
    """
    profile = check_firmware(firmware)
    state = ModalState() if start is None else ModalState.of(start, Chaining())
    found: list[tuple[int, str]] = []
    for number, line in enumerate(lines, start=1):
        found.extend(
            (number, problem) for problem in check_line(line, firmware=profile, state=state)
        )
    return found


def validate_line(
    line: str | bytes | ParsedLine,
    *,
    firmware: str = "2021",
    state: ModalState | None = None,
) -> ParsedLine:
    """The parsed line, or :class:`InvalidLineError` (a
    :class:`~mirobot_async.errors.MirobotUsageError`) listing every problem
    :func:`line_problems` finds (the client's check before writing; ``state`` as there)."""
    parsed = line if isinstance(line, ParsedLine) else parse_line(line)
    profile = check_firmware(firmware)
    problems, chain = _problems(parsed, profile, ModalState() if state is None else state)
    shown = parsed.source.strip() or parsed.text
    if problems:
        raise InvalidLineError(
            f"line {shown!r} refused before sending: {'; '.join(problems)} "
            "(validate=False sends it anyway)",
            tuple(problems),
        )
    if chain is not None:
        raise MotionChainError(shown, f"{chain} (validate=False sends it anyway)")
    return parsed
