"""Default-deny prediction of a raw line's effect, checked against a safety envelope.

:func:`predict` takes one :class:`~mirobot_async._core.line.ParsedLine` and what is known of the
machine (:class:`MachineState`: modal words, position, base offset) and returns either an
:class:`EnvelopeRefusal` naming the line and the reason, or the :class:`Prediction` of the exact
effect: the state after the line, having checked the whole path against the envelope. A line is let
through only when its effect is modelled; everything else is refused:

- numbers the firmware reads differently from their text, odd ``G``/``M`` forms, repeated
  words, unknown codes and letters, lines the firmware would reject (modal group violations,
  ``G21 M21``/``M21 M3`` orders, arcs without R, ``F0`` with a feed move);
- moves that rely on an unknown mode (M20/M21, G90/G91, G0..G5, **G20/G21 units**), on an
  unknown position or parser position (:class:`ParserPosition`), on an unknown work offset
  (absolute moves), or (absolute ``M20`` on 2021) on an unknown base offset ``$41..$43``;
  a 2021 ``M20 G1`` while ``$35`` is unknown;
- settings that change the geometry or the meaning of numbers (DH lengths, tool offset, steps
  per unit, direction inversion, report units...), storing startup lines (``$N0=``), ``$RST``,
  jogs;
- paths that need more than :data:`~mirobot_async._safety.paths.MAX_PATH_SAMPLES` check samples.

Modelled: units (``G20`` scales every axis word by 25.4, angles too), relative and absolute
words, missing words keeping their value, the parser's own position (a move refused as locked
moves it; a line with ``M20``/``M21`` re-reads the arm's), the work offset (``G54..G59`` +
``G92``) added to absolute words in both modes, the base offset added to absolute ``M20`` X/Y/Z,
the firmware's IK branch and the rapid joint move ("wrist snap") to it before an ``M20``
``G1``/``G2``/``G3``/``G5`` path, the classic ``M20 G1`` (2021: with ``$35=0``) as a joint-space
move, J4/J6 kept continuous along a path, ``G5`` gate moves (with ``$49`` known), the soft limits
``$20``/``$130..$146`` (the envelope narrowed to them: no line it passes is dropped by the
firmware, so the next line starts where predicted), every ``$H...`` variant as homing (then the
stored startup lines run), ``$M``, program end. What the firmware stores is read by the guard
(:mod:`mirobot_async._safety.firmware_memory`). Pure module.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Final

from mirobot_async._core.acceptance import ARC_START_UNKNOWN, line_fate
from mirobot_async._core.line import CodeWord, ParsedLine, parse_line
from mirobot_async._core.modal import HOMED, LineCheck, MotionModes, modes_of
from mirobot_async._safety.cartesian import CartesianEnd, cartesian_path, point_to_point
from mirobot_async._safety.firmware_memory import (
    PARSER_UNKNOWN,
    SOFT_LIMIT_SETTINGS,
    ZERO_OFFSET,
    Offset,
    ParserPosition,
    apply_startup_lines,
    soft_limit_ranges,
    with_setting,
)
from mirobot_async._safety.paths import as_pose
from mirobot_async.errors import MirobotUsageError, RefusalReason
from mirobot_async.kinematics import Joints, Pose, forward

if TYPE_CHECKING:
    from mirobot_async._safety.envelope import Envelope

__all__ = [
    "HARMLESS_SETTINGS",
    "MAX_AXIS_VALUE",
    "PARSER_UNKNOWN",
    "EnvelopeRefusal",
    "MachineState",
    "ParserPosition",
    "Prediction",
    "combine",
    "predict",
    "state_after_refusal",
]

MM_PER_INCH: Final = 25.4
MAX_AXIS_VALUE: Final = 100_000.0
"""Axis words beyond this (mm or degrees, after units) are refused before any computation."""

HARMLESS_SETTINGS: Final = frozenset(
    {0, 1, 4, 5, 6, 10, 11, 12, 21, 22, 23, 24, 25, 26, 27, 28}
    | set(range(110, 117))
    | set(range(120, 127))
)
"""Settings that do not change where a line moves the arm (rates, homing, reports). The soft
limits ``$20``, ``$130..$146`` and the 2021 ``$35`` are followed: they decide which moves the
firmware drops and how ``M20 G1`` moves."""
_LINEAR_G1: Final = 35
_BASE_OFFSET: Final = {41: 0, 42: 1, 43: 2}
_GATE_LIFT: Final = 49
_ALLOWED_G: Final = frozenset({0, 1, 2, 3, 4, 5, 17, 20, 21, 40, 54, 61, 90, 91, 94})
_ALLOWED_M: Final = frozenset({0, 1, 2, 3, 4, 5, 8, 9, 20, 21, 30, 50})
_ALLOWED_LETTERS: Final = frozenset("XYZABCDFPSERNT")
_G_GROUPS: Final = {
    **dict.fromkeys((0, 1, 2, 3, 5), "motion"),
    **dict.fromkeys((4,), "non-modal"),
    **dict.fromkeys((17,), "plane"),
    **dict.fromkeys((20, 21), "units"),
    **dict.fromkeys((40,), "cutter"),
    **dict.fromkeys((54,), "coordinates"),
    **dict.fromkeys((61,), "path"),
    **dict.fromkeys((90, 91), "distance"),
    **dict.fromkeys((93, 94), "feed mode"),
}
_M_GROUPS: Final = {
    **dict.fromkeys((0, 1, 2, 30), "flow"),
    **dict.fromkeys((3, 4, 5), "spindle"),
    **dict.fromkeys((8, 9), "coolant"),
    **dict.fromkeys((20, 21), "coordinate mode"),
    **dict.fromkeys((50,), "unlock"),
}
_ZERO: Final[Joints] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

_KNOWN_FAMILIES: Final = ("2021", "classic")
"""The families whose motion semantics are known (manuals, oracle); on others (2024) what
differs between them is refused (docs/2024-profile.md)."""


@dataclass(frozen=True, slots=True)
class MachineState:
    """What is known of the machine before a line (``None``: unknown)."""

    modes: MotionModes = field(default_factory=MotionModes)
    joints: Joints | None = None
    """Joint angles where the queued motion ends (degrees)."""
    pose: Pose | None = None
    """The parser's commanded Cartesian pose (``M20`` ``G91`` words add to it); default: the
    forward kinematics of ``joints``."""
    rail: float | None = None
    base_offset: tuple[float, float, float] | None = None
    """``$41..$43`` (2021: added to absolute ``M20`` X/Y/Z; ``(0, 0, 0)`` on classic)."""
    gate_lift: float | None = None
    """``$49``, the lift of a ``G5`` gate move (2021)."""
    firmware: str | None = None
    """``"2021"``, ``"classic"``, ``"2024"`` or None (unknown: features of one profile are
    refused; on 2024 what the evidence does not show: ``M20 G1`` unless ``$$`` lists ``$35``
    (then as 2021), ``$M``, arcs, gate moves, a non-zero base offset, ``$35``/``$41..$43``/
    ``$49``)."""
    parser: ParserPosition | None = None
    """The parser's position when it differs from ``joints``/``pose`` (None: the same)."""
    work_offset: Offset | None = ZERO_OFFSET
    """The work offset in effect (``G54..G59`` + ``G92``, axis-word order X..D), added by the
    firmware to absolute targets in both modes; None: unknown (absolute moves are refused)."""
    startup_lines: tuple[str, ...] | None = ()
    """The stored ``$N0``/``$N1`` lines, run after homing (None: unknown)."""
    linear_g1: bool | None = True
    """2021 ``$35``: ``M20 G1`` is a straight line (else, and always on classic, a joint move)."""
    soft_limits: tuple[float, ...] | None = None
    """``($20, $130..$136, $140..$146)``: targets outside them are refused like the envelope's
    own bounds (the firmware would drop them); None: not applied."""


@dataclass(frozen=True, slots=True)
class Prediction:
    """The exact effect of a line the envelope allows."""

    line: ParsedLine
    state: MachineState
    """The machine after the line."""
    moves: bool
    """The line moves the arm (or homes it)."""
    snap: Joints | None = None
    """The rapid joint move's target before a Cartesian path (firmware IK branch), if any."""
    model_joints: Joints | None = None
    """End joints of the emulator's model when :attr:`state` has none because the wrist snap
    may turn J4/J6 either way (the pose is known; the client reads the joints from a status)."""
    samples: int = 0
    """Path samples checked."""


@dataclass(frozen=True, slots=True)
class EnvelopeRefusal:
    """A line the envelope refuses: it leaves the envelope or cannot be predicted."""

    line: ParsedLine
    reason: str
    """Why, naming the line."""

    def error(self) -> MirobotUsageError:
        """The refusal as the error ``send()`` raises."""
        return MirobotUsageError(self.reason)


class _Refuse(Exception):
    """Internal: abandon the prediction with a reason."""


def _what(parsed: ParsedLine, what: str | None) -> str:
    return what if what is not None else f"line {parsed.source.strip() or parsed.text!r}"


def predict(
    envelope: Envelope,
    line: str | bytes | ParsedLine,
    state: MachineState,
    *,
    what: str | None = None,
) -> Prediction | EnvelopeRefusal:
    """Predict and check one line (see the module docstring); never raises for the line."""
    parsed = line if isinstance(line, ParsedLine) else parse_line(line)
    name = _what(parsed, what)
    try:
        if parsed.kind == "empty":
            return Prediction(parsed, state, False)
        if parsed.kind == "dollar":
            return _dollar(envelope, parsed, state, name)
        return _gcode(envelope, parsed, state, name)
    except (_Refuse, MirobotUsageError) as exc:
        text = str(exc)
        if name not in text:
            text = f"{text} ({name})"
        return EnvelopeRefusal(parsed, text)


# --------------------------------------------------------------------------------------------
# $ lines


def _dollar(envelope: Envelope, parsed: ParsedLine, state: MachineState, what: str) -> Prediction:
    dollar = parsed.dollar
    assert dollar is not None
    kind = dollar.kind
    if kind in ("help", "query", "unlock"):
        return Prediction(parsed, state, False)
    if kind == "homing":
        # ASSUMED: homing passes; its path to the switches cannot be bounded. It re-initialises
        # the parser (oracle: G0 G21 G90 after any $H...); $H and $HH leave the rail alone.
        # After a successful homing the stored startup lines run (oracle: $N0=G91, $H -> G91ok).
        keeps_rail = parsed.text in ("$H", "$HH")
        after = replace(
            state,
            modes=apply_startup_lines(HOMED, state.startup_lines, certain=True),
            joints=None,
            pose=None,
            rail=state.rail if keeps_rail else None,
            parser=None,
        )
        return Prediction(parsed, after, True)
    if kind == "zero":
        if state.firmware == "classic":
            return Prediction(parsed, state, False)  # the classic firmware refuses $M
        if state.firmware != "2021":
            raise _Refuse(f"$M on the {state.firmware} firmware is not known to the envelope")
        envelope.check_joints(_ZERO, start=state.joints, what=what)
        pose = forward(_ZERO, envelope.dh, envelope.tool)
        return Prediction(parsed, replace(state, joints=_ZERO, pose=pose), True)
    if kind == "setting":
        return _setting(parsed, state, what)
    reasons = {
        "jog": "jog lines ($J) are not checked by the envelope",
        "startup": "a startup line ($N0=/$N1=) runs at every reset: the envelope cannot follow it",
        "restore": "$RST restores settings (the base offset, the geometry): the envelope cannot "
        "follow it",
    }
    raise _Refuse(reasons.get(kind, f"{parsed.text!r} is not a $ command the envelope knows"))


def _setting(parsed: ParsedLine, state: MachineState, what: str) -> Prediction:
    dollar = parsed.dollar
    assert dollar is not None and dollar.number is not None and dollar.value is not None
    number, value = dollar.number, dollar.value
    if not dollar.canonical:
        raise _Refuse(
            f"{parsed.text} is read by the firmware as ${number}={value:g}; write it that way"
        )
    if number in HARMLESS_SETTINGS:
        return Prediction(parsed, state, False)
    if number in SOFT_LIMIT_SETTINGS:
        if state.soft_limits is None:
            return Prediction(parsed, state, False)
        after = replace(state, soft_limits=with_setting(state.soft_limits, number, value))
        return Prediction(parsed, after, False)
    if number == _LINEAR_G1 and state.firmware == "2021":
        return Prediction(parsed, replace(state, linear_g1=value != 0), False)
    if state.firmware == "2021" and number in _BASE_OFFSET:
        if state.base_offset is None:
            return Prediction(parsed, state, False)
        offset = list(state.base_offset)
        offset[_BASE_OFFSET[number]] = value
        after = replace(state, base_offset=(offset[0], offset[1], offset[2]))
        return Prediction(parsed, after, False)
    if state.firmware == "2021" and number == _GATE_LIFT and value >= 0:
        return Prediction(parsed, replace(state, gate_lift=value), False)
    if number in _BASE_OFFSET or number == _GATE_LIFT:
        raise _Refuse(f"${number} changes where later moves go and the firmware profile is unknown")
    raise _Refuse(
        f"${number} changes the arm's geometry or how positions are read: the envelope cannot "
        "follow it (send it with check_envelope=False, then reconnect)"
    )


# --------------------------------------------------------------------------------------------
# G-code lines


def _validate_words(parsed: ParsedLine, state: MachineState) -> None:
    """Refuse what the firmware reads differently or rejects, and what is not modelled."""
    if parsed.syntax_error is not None:
        raise _Refuse(f"the firmware rejects this line ({parsed.syntax_error!r})")
    groups: dict[str, str] = {}
    for word in parsed.words:
        if word.lossy:
            raise _Refuse(f"{word} has more than 8 digits: the firmware reads it as {word.value:g}")
        if not math.isfinite(word.value):
            raise _Refuse(f"{word} is not a number the firmware can use")
        if isinstance(word, CodeWord):
            if not word.canonical:
                shown = f"{word.letter}{word.code}"
                raise _Refuse(
                    f"{word} is not a plain command number (the firmware reads it as {shown} "
                    "or refuses it); write it plainly"
                )
            table = _ALLOWED_G if word.letter == "G" else _ALLOWED_M
            if word.code not in table:
                raise _Refuse(f"{word} is not a code the envelope can check")
            if word.letter == "G" and word.code in (2, 3, 5) and state.firmware != "2021":
                raise _Refuse(f"{word} needs the 2021 firmware (or the profile is unknown)")
            group = (_G_GROUPS if word.letter == "G" else _M_GROUPS)[word.code]
            key = word.letter + group
            if key in groups:
                raise _Refuse(f"{groups[key]} and {word} in one line ('Modal group violation')")
            groups[key] = str(word)
        elif word.letter not in _ALLOWED_LETTERS:
            raise _Refuse(f"the letter {word.letter} is not one the envelope can check")
    if parsed.repeated:
        raise _Refuse(f"the word {parsed.repeated[0]} appears twice (the firmware rejects it)")
    values = parsed.values
    for letter in "FPSE":
        if values.get(letter, 0.0) < 0:
            raise _Refuse(f"{letter} is negative (the firmware says 'Value < 0')")
    if 4 in parsed.g_codes and "P" not in values:
        raise _Refuse("G4 needs P (the firmware rejects it)")


def _gcode(envelope: Envelope, parsed: ParsedLine, state: MachineState, what: str) -> Prediction:
    _validate_words(parsed, state)
    # the firmware's verdict: a line it refuses runs nothing (and on classic its M20/M21 still
    # switches the mode), so the lines behind it would start where nobody predicted
    fate = line_fate(parsed, state.modes, state.firmware)
    if fate.accepted is False:
        raise _Refuse(fate.problem)
    envelope = with_soft_limits(envelope, state.soft_limits)
    modes = modes_of(parsed, state.modes)
    after_modes = fate.modes
    axes = dict(parsed.axis_words)
    pose = state.pose
    parser = state.parser
    if parsed.coordinate_mode is not None:
        parser = None  # oracle: a line with M20/M21 re-reads the parser's position from the arm
    if pose is None and state.joints is not None:
        pose = forward(state.joints, envelope.dh, envelope.tool)
    if parsed.coordinate_mode == 20 or state.modes.cartesian is not True:
        # the firmware re-reads the commanded pose from the joints on M20 (and in joint mode)
        pose = None if state.joints is None else forward(state.joints, envelope.dh, envelope.tool)
    elif parser is not None and parser.joints is None:
        pose = None  # the commanded pose is unknown (see ParserPosition)
    base = replace(state, pose=pose, parser=parser)
    if not axes:
        if parsed.motion in (2, 3, 5):
            raise _Refuse(f"G{parsed.motion} without axis words: the firmware rejects it")
        if fate.accepted is None:
            raise _Refuse(fate.problem)
        return Prediction(parsed, replace(base, modes=after_modes), False)
    missing = modes.missing()
    if missing:
        raise _Refuse(
            f"the line relies on the {' and '.join(missing)}, which "
            f"{'is' if len(missing) == 1 else 'are'} unknown; "
            f"state {'it' if len(missing) == 1 else 'them'} in the line (or in a line before)"
        )
    if fate.accepted is None and fate.why != ARC_START_UNKNOWN:  # (the arc's own check)
        raise _Refuse(fate.problem)
    scale = MM_PER_INCH if modes.inches else 1.0
    for letter, value in axes.items():
        axes[letter] = value * scale
        if abs(axes[letter]) > MAX_AXIS_VALUE:
            raise _Refuse(f"{letter}{value:g} is far outside any range of the arm")
    motion = modes.motion
    feed = parsed.value("F")
    if motion in (1, 2, 3, 5) and feed == 0.0:
        raise _Refuse(f"G{motion} with F0: the firmware says 'Undefined feed rate'")
    relative = modes.relative is True
    if not relative:
        _add_work_offset(axes, state.work_offset)
    lost = parser is not None and parser.joints is None
    if lost and (relative or not all(k in axes for k in _WORDS)):
        raise _Refuse(
            "the firmware's parser position is unknown (after an alarm, a lost reply or a "
            "refused move): a relative move or one that leaves out an axis needs it; "
            "state M20/M21 in the line (the firmware then re-reads the arm's position)"
        )
    parser_rail = base.rail if parser is None else parser.rail
    rail = _rail_target(envelope, axes, relative, parser_rail, what)
    if modes.cartesian:
        return _cartesian(envelope, parsed, base, after_modes, axes, rail, what)
    if motion not in (0, 1):
        raise _Refuse(f"G{motion} needs Cartesian mode (M20): the firmware rejects it")
    problem = envelope.rail_problem(rail, what)
    if problem is not None:
        raise _Refuse(problem)
    start = state.joints if parser is None else parser.joints
    if not any(k in axes for k in "XYZABC") and parser is None:
        return Prediction(parsed, replace(base, modes=after_modes, rail=rail), True)
    target = combine(axes, relative, start, "current joint angles")
    q: Joints = (target[0], target[1], target[2], target[3], target[4], target[5])
    envelope.check_joints(q, rail, start=state.joints, what=what)
    after = replace(
        base,
        modes=after_modes,
        joints=q,
        pose=forward(q, envelope.dh, envelope.tool),
        rail=rail,
        parser=None,
    )
    return Prediction(parsed, after, True)


_WORDS: Final = "XYZABC"


def _add_work_offset(axes: dict[str, float], offset: tuple[float, ...] | None) -> None:
    """Absolute words: the firmware adds the work offset in effect (``G54..G59`` + ``G92``)."""
    if offset is None:
        raise _Refuse(
            "an absolute move needs the work offset in effect (G54..G59 + G92), which is "
            "unknown; it is read ($#, $G) before a move (or state G54 in the line)"
        )
    for k, delta in zip("XYZABCD", offset, strict=True):
        if k in axes:
            axes[k] += delta


def with_soft_limits(envelope: Envelope, values: tuple[float, ...] | None) -> Envelope:
    """``envelope`` narrowed to the firmware's soft limits (``$20=1``, ``$130..$146``), so that
    no line it lets through is one the firmware drops (the next lines would start elsewhere)."""
    ranges = soft_limit_ranges(values)
    if ranges is None:
        return envelope
    return _narrowed(envelope, ranges)


def _narrowed(envelope: Envelope, ranges: tuple[tuple[float, float], ...]) -> Envelope:
    # ASSUMED: the firmware's own rounding (float32) never drops a target within LIMIT_TOL
    # (1e-6 deg) of a soft limit that the envelope lets through.
    joints: dict[int, tuple[float, float]] = {}
    for i, ((lo, hi), (soft_lo, soft_hi)) in enumerate(
        zip(envelope.joint_limits, ranges[:6], strict=True)
    ):
        joints[i + 1] = (max(lo, soft_lo), min(hi, soft_hi))
        if joints[i + 1][0] > joints[i + 1][1]:
            raise _Refuse(f"the soft limits ($130..$146) leave J{i + 1} no range")
    rail_lo, rail_hi = ranges[6]
    if envelope.rail is not None:
        env_lo, env_hi = envelope.rail
        rail_lo = rail_lo if env_lo is None else max(env_lo, rail_lo)
        rail_hi = rail_hi if env_hi is None else min(env_hi, rail_hi)
    if rail_lo > rail_hi:
        raise _Refuse("the soft limits ($133/$143) leave the rail no range")
    return replace(envelope, joints=joints, rail=(rail_lo, rail_hi))


def _rail_target(
    envelope: Envelope, axes: dict[str, float], relative: bool, rail: float | None, what: str
) -> float | None:
    if "D" not in axes:
        return rail
    if not relative:
        return axes["D"]
    if rail is not None:
        return rail + axes["D"]
    if envelope.rail is not None:
        raise _Refuse("a relative rail move needs the current rail position, which is unknown")
    return None


def combine(
    axes: dict[str, float], relative: bool, base: tuple[float, ...] | None, name: str
) -> tuple[float, ...]:
    """Target from axis words X..C: missing words stay, relative words add."""
    letters = "XYZABC"
    if base is None:
        if relative or not all(k in axes for k in letters):
            kind = "relative move" if relative else "move that leaves out an axis"
            raise _Refuse(f"a {kind} needs the {name}, which are unknown; query the status first")
        return tuple(axes[k] for k in letters)
    return tuple(
        (b + axes.get(k, 0.0)) if relative else axes.get(k, b)
        for k, b in zip(letters, base, strict=True)
    )


def _cartesian(
    envelope: Envelope,
    parsed: ParsedLine,
    base: MachineState,
    after_modes: MotionModes,
    axes: dict[str, float],
    rail: float | None,
    what: str,
) -> Prediction:
    """An ``M20`` line with axis words: target (units, offset, relative), then the move."""
    problem = envelope.rail_problem(rail, what)
    if problem is not None:
        raise _Refuse(problem)
    modes = modes_of(parsed, base.modes)
    relative = modes.relative is True
    if not any(k in axes for k in "XYZABC"):
        return Prediction(parsed, replace(base, modes=after_modes, rail=rail), True)
    if not relative and any(k in axes for k in "XYZ"):
        offset = base.base_offset
        if offset is None:
            raise _Refuse(
                "an absolute M20 move needs the base offset ($41..$43), which is unknown; "
                "read the settings ($$) first"
            )
        if base.firmware not in _KNOWN_FAMILIES and any(offset):
            raise _Refuse(
                f"whether the {base.firmware} firmware adds the base offset ($41..$43 = "
                f"{offset}) to an absolute M20 target is not known; set it to 0"
            )
        for k, delta in zip("XYZ", offset, strict=True):
            if k in axes:
                axes[k] += delta
    target = as_pose(combine(axes, relative, base.pose, "current pose"))
    motion = modes.motion
    end: CartesianEnd
    if motion == 1 and base.firmware not in _KNOWN_FAMILIES and base.linear_g1 is None:
        raise _Refuse(
            f"how M20 G1 moves on the {base.firmware} firmware is not known (its $$ lists no "
            "$35, the 2021 switch between a straight line and a joint move)"
        )
    if motion == 1 and base.firmware == "2021" and base.linear_g1 is None:
        raise _Refuse("how M20 G1 moves depends on $35, which is unknown; read the settings first")
    # oracle: the classic firmware (and the 2021 one with $35=0) runs M20 G1 in joint space
    joint_g1 = base.firmware == "classic" or base.linear_g1 is False
    if motion == 0 or (motion == 1 and joint_g1):
        end = point_to_point(envelope, base.joints, target, what)
    else:
        if base.joints is None or base.pose is None:
            raise _Refuse(
                f"a Cartesian G{motion} path needs the current position, which is unknown; "
                "query the status first"
            )
        end = cartesian_path(
            envelope,
            base.joints,
            base.pose,
            target,
            motion or 0,
            radius=parsed.value("R"),
            gate_lift=base.gate_lift,
            what=what,
        )
    after = replace(base, modes=after_modes, joints=end.joints, pose=target, rail=rail, parser=None)
    return Prediction(
        parsed, after, True, snap=end.snap, samples=end.samples, model_joints=end.model_joints
    )


def state_after_refusal(
    state: MachineState,
    before: MachineState,
    check: LineCheck | None,
    reason: RefusalReason | None,
) -> MachineState:
    """``state`` (the arm back where ``before`` had it) after the firmware dropped the motion
    of the line predicted as ``check``, with the parser where the firmware leaves it (oracle):
    a soft limit leaves it; locked, a joint-mode line moves it to the refused target, and a
    Cartesian one (or an unreachable Cartesian target) moves the commanded pose; anything
    else leaves it unknown."""
    state = replace(state, parser=before.parser)
    if reason is RefusalReason.SOFT_LIMIT:
        return state
    if check is None:
        return replace(state, parser=PARSER_UNKNOWN)
    if check.modes.cartesian:
        if reason in (RefusalReason.LOCKED, RefusalReason.UNREACHABLE) and check.pose is not None:
            return replace(state, pose=check.pose, parser=None)
        return replace(state, parser=PARSER_UNKNOWN)
    if reason is RefusalReason.LOCKED and check.joints is not None:
        return replace(state, parser=ParserPosition(check.joints, check.rail))
    return replace(state, parser=PARSER_UNKNOWN)
