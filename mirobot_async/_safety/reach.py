"""Which Cartesian targets of a program the arm cannot reach (``mirobot check``, ``run``).

The firmware solves an ``M20`` target with its inverse kinematics (the same as the emulator's:
:func:`mirobot_async.kinematics.inverse`, firmware branch) and drops a target it cannot solve
(``GOAL OUT OF WORKSPACE...``), one whose joints leave their ranges (soft limits on, the factory
``$20=1``: ``Soft limit triggered``), and goes elsewhere for one whose wrist centre lies behind
the shoulder. :func:`unreachable_targets` follows a program's modes (the firmware's verdict on
each line: :func:`~mirobot_async._core.acceptance.line_fate`) and the commanded pose word by
word, and judges a target only when the program itself gives all six coordinates: absolute
words, or relative ones added to coordinates it stated before. Where a coordinate is unknown
(at the start, after a joint move, homing or a refused target) it says nothing rather than
guess; after a line that changes offsets or geometry (``G10 G28 G30 G92 G54..G59``, a ``$``
setting) it judges no more. The factory geometry of the profile is assumed (no base or tool
offset). Only the target is judged, not the path to it (``G1``/``G2``/``G3`` samples: the
envelope). Pure module (numpy).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Final

from mirobot_async._core.acceptance import line_fate
from mirobot_async._core.line import ParsedLine, parse_line
from mirobot_async._core.modal import MotionModes, modes_of
from mirobot_async._core.values import check_firmware
from mirobot_async.errors import BehindShoulder, OutOfLimits, Unreachable
from mirobot_async.kinematics import DH_2021, DH_CLASSIC, JOINT_LIMITS, Pose, inverse

__all__ = ["unreachable_targets"]

_POSE_LETTERS: Final = "XYZABC"
_OFFSET_CODES: Final = frozenset({10, 28, 30, 92, *range(54, 60)})
_TARGET_MOTIONS: Final = frozenset({0, 1, 2, 3, 5})
_UNKNOWN: Final[tuple[float | None, ...]] = (None,) * 6


def _show(pose: Pose) -> str:
    return " ".join(f"{k}{v:g}" for k, v in zip(_POSE_LETTERS, pose, strict=True))


def _problem(pose: Pose, firmware: str) -> str | None:
    dh = DH_CLASSIC if firmware == "classic" else DH_2021
    target = f"the Cartesian target {_show(pose)}"
    try:
        inverse(pose, dh, "firmware", limits=JOINT_LIMITS)
    except BehindShoulder as err:
        return f"{target}: {err}"
    except OutOfLimits as err:
        return (
            f"{target} is out of the joint ranges ({err}): the firmware drops it with soft "
            "limits on ($20=1: 'Soft limit triggered'), else drives a joint past its range"
        )
    except Unreachable:
        return (
            f"{target} is unreachable: the firmware's inverse kinematics has no solution and "
            "drops the move ('GOAL OUT OF WORKSPACE')"
        )
    return None


def unreachable_targets(
    lines: Iterable[str | bytes], *, firmware: str = "2021", start: MotionModes | None = None
) -> list[tuple[int, str]]:
    """(1-based line number, problem) for each ``M20`` target the arm cannot reach, from the
    modes ``start`` (default: power-on), see the module docstring."""
    profile = check_firmware(firmware)
    modes = MotionModes() if start is None else start
    pose = _UNKNOWN
    found: list[tuple[int, str]] = []
    for number, line in enumerate(lines, start=1):
        parsed = parse_line(line)
        if parsed.kind == "dollar":
            assert parsed.dollar is not None
            if parsed.dollar.kind in ("setting", "restore", "unknown"):
                break  # the geometry or the offsets may change: judge no more
            if parsed.is_homing:
                pose = _UNKNOWN
            continue
        if parsed.kind != "gcode" or parsed.syntax_error is not None:
            continue
        if _OFFSET_CODES.intersection(parsed.g_codes):
            break
        fate = line_fate(parsed, modes, profile)
        if fate.accepted is not False:
            pose, problem = _follow(parsed, modes, pose, profile)
            if problem is not None:
                found.append((number, problem))
        modes = fate.modes
    return found


def _follow(
    parsed: ParsedLine, modes: MotionModes, pose: tuple[float | None, ...], firmware: str
) -> tuple[tuple[float | None, ...], str | None]:
    """The commanded pose after ``parsed`` (run from ``modes``) and its target's problem."""
    words = parsed.axis_words
    if not any(k in words for k in _POSE_LETTERS) or parsed.dwell_seconds is not None:
        return pose, None
    line_modes = modes_of(parsed, modes)
    if (
        line_modes.cartesian is not True
        or line_modes.motion not in _TARGET_MOTIONS
        or line_modes.relative is None
        or line_modes.inches is not False
    ):
        return _UNKNOWN, None  # a joint move, or modes unknown: where the tool ends is unknown
    target: list[float | None] = list(pose)
    for index, letter in enumerate(_POSE_LETTERS):
        value = words.get(letter)
        if value is None:
            continue
        known = target[index]
        if line_modes.relative:
            target[index] = None if known is None else known + value
        else:
            target[index] = value
    values = [v for v in target if v is not None]
    if len(values) < 6:
        return tuple(target), None
    full: Pose = (values[0], values[1], values[2], values[3], values[4], values[5])
    problem = _problem(full, firmware)
    # a dropped target is the parser's pose, not the arm's: an M20 line re-reads the arm's
    return (_UNKNOWN if problem is not None else tuple(target)), problem
