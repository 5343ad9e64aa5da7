"""Typed builders for Mirobot command lines, and an offline checker for raw G-code.

Every builder validates its arguments *before* producing anything and returns the canonical line
as ASCII ``bytes`` ending in ``b"\\n"``: upper-case words separated by single spaces, numbers
written by :func:`fmt_number` (never exponent notation, never ``-0``). A bad argument raises
:class:`~mirobot_async.errors.MirobotUsageError` (a ``ValueError``) whose message names the
argument and the allowed range, so nothing malformed can reach the robot.

The offline checker (:func:`check_line`, :func:`check_program`, :class:`ModalState`) lives in
:mod:`mirobot_async._core.validation`, the settings table in :mod:`mirobot_async._core.settings`,
the one parse of a raw line in :mod:`mirobot_async._core.line`; their names stay importable from
here. Pure module.
"""

from __future__ import annotations

import math
import numbers

from mirobot_async._core.line import MAX_INT_DIGITS, normalize_line, parse_line
from mirobot_async._core.settings import SETTINGS, SettingInfo, setting_problem
from mirobot_async._core.validation import ModalState, check_line, check_program, parse_words
from mirobot_async._core.values import (
    COMMAND_PROFILE,
    FIRMWARE_PROFILES,
    GRIPPER_CLOSE,
    GRIPPER_OPEN,
    JOINT_NAMES,
    JOINT_RANGES,
    MAX_LINE_LENGTH,
    PUMP_BLOW,
    PUMP_OFF,
    PUMP_SUCK,
    PWM_MAX,
    PWM_MIN,
    RAIL_RANGES,
    VALVE_GRIPPER_CLOSE,
    VALVE_GRIPPER_OPEN,
    check_decimals,
    check_firmware,
    fmt_number,
    real_number,
    show_number,
)
from mirobot_async.errors import MirobotUsageError

__all__ = [
    "FIRMWARE_PROFILES",
    "GRIPPER_CLOSE",
    "GRIPPER_OPEN",
    "JOINT_NAMES",
    "JOINT_RANGES",
    "MAX_LINE_LENGTH",
    "PUMP_BLOW",
    "PUMP_OFF",
    "PUMP_SUCK",
    "PWM_MAX",
    "PWM_MIN",
    "RAIL_RANGES",
    "SETTINGS",
    "VALVE_GRIPPER_CLOSE",
    "VALVE_GRIPPER_OPEN",
    "ModalState",
    "SettingInfo",
    "absolute",
    "arc",
    "cartesian_mode",
    "check_line",
    "check_program",
    "clear_alarm",
    "dwell",
    "feed_rate",
    "fmt_number",
    "home",
    "home_axis",
    "home_compact",
    "joint_mode",
    "move_joints",
    "move_pose",
    "normalize_line",
    "parse_words",
    "path_header",
    "path_point",
    "relative",
    "set_gripper",
    "set_hard_limits",
    "set_homing",
    "set_pump",
    "set_setting",
    "set_soft_limits",
    "set_valve",
    "settings_dump",
    "unlock_axes",
    "zero_pose",
]


_POSE_LETTERS = ("X", "Y", "Z", "A", "B", "C")


def _usage(message: str) -> MirobotUsageError:
    return MirobotUsageError(message)


_show = show_number
_check_firmware = check_firmware
_check_decimals = check_decimals
_real = real_number


def _positive(value: object, name: str, decimals: int, what: str) -> str:
    """A strictly positive number, as written on the wire (it must stay > 0 after rounding)."""
    number = real_number(value, name)
    text = fmt_number(number, decimals, name=name)
    if number <= 0:
        raise MirobotUsageError(f"{name}={show_number(number)} must be > 0 ({what})")
    if float(text) <= 0:
        raise MirobotUsageError(
            f"{name}={show_number(number)} must be > 0 ({what}); with {decimals} decimals it is 0"
        )
    return text


def _pwm(value: object, name: str) -> int:
    """An integer PWM value 0..1000."""
    allowed = f"an integer {PWM_MIN}..{PWM_MAX}"
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise MirobotUsageError(f"{name}={value!r} must be {allowed}")
    number = float(value)
    if not math.isfinite(number) or not number.is_integer():
        raise MirobotUsageError(f"{name}={value!r} must be {allowed}")
    if not PWM_MIN <= number <= PWM_MAX:
        raise MirobotUsageError(
            f"{name}={int(number)} is outside {PWM_MIN}..{PWM_MAX} (must be {allowed})"
        )
    return int(number)


def _flag(value: object, name: str) -> int:
    if value is True or value is False or value in (0, 1):
        return 1 if value else 0
    raise MirobotUsageError(f"{name}={value!r} must be True/False (or 1/0)")


def _finish(words: list[str]) -> bytes:
    """Join words into the canonical line; enforce the firmware's line-length limit."""
    text = " ".join(words)
    compact = len(text) - text.count(" ")
    if compact > MAX_LINE_LENGTH:
        raise MirobotUsageError(
            f"the line {text!r} is {compact} bytes without spaces; the firmware accepts at most "
            f"{MAX_LINE_LENGTH} ('Line overflow'): use fewer decimals or split the command"
        )
    for word in words:
        # Builders write plain numbers (fmt_number: sign, digits, one dot), so a word's digits
        # are its text after the letter; no re-parse of a line built here.
        if len(word) > MAX_INT_DIGITS + 1 and _lossy_number(word[1:]):
            value = parse_line(word).words[0].value
            raise MirobotUsageError(
                f"{word} in {text!r} has more than 8 digits: the firmware keeps only 8 "
                f"(leading zeros count) and would read {show_number(value)}"
            )
    return text.encode("ascii") + b"\n"


def _lossy_number(number: str) -> bool:
    """A number written by :func:`fmt_number` that the firmware reads otherwise: a digit past
    the 8th (leading zeros count) that is not zero (as
    :func:`~mirobot_async._core.line.read_number`)."""
    digits = number.lstrip("+-").replace(".", "", 1)
    return len(digits) > MAX_INT_DIGITS and digits[MAX_INT_DIGITS:].strip("0") != ""


# --------------------------------------------------------------------------------------------
# Motion
# --------------------------------------------------------------------------------------------


def move_joints(
    j1: float | None = None,
    j2: float | None = None,
    j3: float | None = None,
    j4: float | None = None,
    j5: float | None = None,
    j6: float | None = None,
    rail: float | None = None,
    *,
    speed: float | None = None,
    relative: bool = False,
    check_limits: bool = True,
    firmware: str = "2021",
    decimals: int = 3,
    mode_word: bool = True,
) -> bytes:
    """Joint-space move ``M21 G90|G91 G0|G1 X.. Y.. Z.. A.. B.. C.. D.. [F..]``.

    Angles in degrees (J1..J6 = X..C), rail in mm (D). Without ``speed`` the move is ``G0`` (every
    joint at its max rate); with ``speed`` (deg/min) it is ``G1 F<speed>``. Omitted joints stay.
    Absolute targets are checked against :data:`JOINT_RANGES` / :data:`RAIL_RANGES` when
    ``check_limits`` (relative ones cannot be checked without the current position).

    ``mode_word=False`` leaves ``M21`` out, for a line streamed while ``M21`` is in effect: the
    firmware restarts a line that carries ``M20``/``M21`` from where the arm is at that moment,
    not from where the queued motion ends (:class:`~mirobot_async._core.modal.Chaining`).
    """
    profile = _check_firmware(firmware)
    places = _check_decimals(decimals)
    targets = (
        ("j1", "X", j1, "J1"),
        ("j2", "Y", j2, "J2"),
        ("j3", "Z", j3, "J3"),
        ("j4", "A", j4, "J4"),
        ("j5", "B", j5, "J5"),
        ("j6", "C", j6, "J6"),
        ("rail", "D", rail, None),
    )
    axis_words: list[str] = []
    for name, letter, value, joint in targets:
        if value is None:
            continue
        text = fmt_number(value, places, name=name)
        if check_limits and not relative:
            sent = float(text)
            if joint is not None:
                low, high = JOINT_RANGES[joint]
                if not low <= sent <= high:
                    raise _usage(
                        f"{name}={_show(sent)} is outside the joint range "
                        f"{_show(low)}..{_show(high)} deg"
                    )
            else:
                low, high = RAIL_RANGES[profile]
                if not low <= sent <= high:
                    raise _usage(
                        f"{name}={_show(sent)} is outside the rail range "
                        f"{_show(low)}..{_show(high)} mm (firmware {profile!r})"
                    )
        axis_words.append(letter + text)
    if not axis_words:
        raise _usage("move_joints needs at least one of j1..j6 or rail")
    words = ["M21"] if mode_word else []
    words.append("G91" if relative else "G90")
    if speed is None:
        words.append("G0")
        words += axis_words
    else:
        feed = _positive(speed, "speed", places, "deg/min")
        words.append("G1")
        words += axis_words
        words.append("F" + feed)
    return _finish(words)


def move_pose(
    x: float | None = None,
    y: float | None = None,
    z: float | None = None,
    rx: float | None = None,
    ry: float | None = None,
    rz: float | None = None,
    *,
    speed: float | None = None,
    linear: bool = False,
    relative: bool = False,
    decimals: int = 3,
    mode_word: bool = True,
) -> bytes:
    """Cartesian move ``M20 G90|G91 G0|G1 X.. Y.. Z.. A.. B.. C.. [F..]`` (mm, degrees).

    ``linear=False`` is point-to-point (``G0``, joints at max rates; ``speed`` is optional and only
    sets the modal feed). ``linear=True`` is a straight line (``G1``) at ``speed`` mm/min, which is
    then required: a G1 without F fails with ``Undefined feed rate`` after homing.
    Reachability is not checked here (see :mod:`mirobot_async._safety.envelope`).
    ``mode_word=False`` leaves ``M20`` out (as in :func:`move_joints`).
    """
    places = _check_decimals(decimals)
    values = (("x", x), ("y", y), ("z", z), ("rx", rx), ("ry", ry), ("rz", rz))
    axis_words = [
        letter + fmt_number(value, places, name=name)
        for (name, value), letter in zip(values, _POSE_LETTERS, strict=True)
        if value is not None
    ]
    if not axis_words:
        raise _usage("move_pose needs at least one of x, y, z, rx, ry, rz")
    if linear and speed is None:
        raise _usage(
            "speed is required with linear=True (mm/min): "
            "a G1 without F fails with 'Undefined feed rate' after homing"
        )
    feed = None if speed is None else _positive(speed, "speed", places, "mm/min")
    words = ["M20"] if mode_word else []
    words += ["G91" if relative else "G90", "G1" if linear else "G0", *axis_words]
    if feed is not None:
        words.append("F" + feed)
    return _finish(words)


def path_header(
    *,
    joints: bool,
    speed: float | None,
    linear: bool = True,
    decimals: int = 3,
    mode_word: bool = True,
) -> bytes:
    """The modal line of a path, stated once: ``M21|M20 G90 G0|G1 G21 [F..]``.

    The points follow as :func:`path_point` lines without ``M20``/``M21``: the firmware
    restarts a line that carries ``M20``/``M21`` from where the arm is at that moment, so
    streamed full lines would swing back. ``linear`` with ``speed=None`` is refused (``G1``
    needs a feed rate); joint paths use ``G1`` with a speed (deg/min), else ``G0``.
    ``mode_word=False`` leaves ``M21``/``M20`` out too (the mode is in effect already).
    """
    places = _check_decimals(decimals)
    if not joints and linear and speed is None:
        raise _usage("speed is required with linear=True (mm/min)")
    motion = "G1" if (speed is not None and (joints or linear)) else "G0"
    words = ["M21" if joints else "M20"] if mode_word else []
    words += ["G90", motion, "G21"]
    if speed is not None:
        words.append("F" + _positive(speed, "speed", places, "deg/min" if joints else "mm/min"))
    return _finish(words)


def path_point(
    values: tuple[float | None, ...],
    *,
    joints: bool,
    motion: str,
    firmware: str = "2021",
    decimals: int = 3,
) -> bytes:
    """One point of a path after :func:`path_header`: ``G0|G1 X.. Y.. Z.. A.. B.. C.. [D..]``.

    ``values`` are x, y, z, rx, ry, rz (mm, degrees) or, with ``joints``, j1..j6 and the rail
    (degrees, mm); ``None`` entries stay. Absolute joint targets are checked against the joint
    and rail ranges (:class:`MirobotUsageError`).
    """
    places = _check_decimals(decimals)
    letters = ("X", "Y", "Z", "A", "B", "C", "D")
    names = (
        ("j1", "j2", "j3", "j4", "j5", "j6", "rail")
        if joints
        else ("x", "y", "z", "rx", "ry", "rz")
    )
    if len(values) > len(names):
        raise _usage(f"a path point has at most {len(names)} values, not {len(values)}")
    words = [motion]
    for index, value in enumerate(values):
        if value is None:
            continue
        text = fmt_number(value, places, name=names[index])
        if joints:
            low, high = (
                RAIL_RANGES[_check_firmware(firmware)]
                if index == 6
                else JOINT_RANGES[JOINT_NAMES[index]]
            )
            if not low <= float(text) <= high:
                raise _usage(
                    f"{names[index]}={_show(float(text))} is outside {_show(low)}..{_show(high)}"
                )
        words.append(letters[index] + text)
    if len(words) == 1:
        raise _usage("a path point needs at least one coordinate")
    return _finish(words)


def arc(
    x: float,
    y: float,
    radius: float,
    *,
    speed: float,
    clockwise: bool = True,
    relative: bool = False,
    firmware: str = "2021",
    decimals: int = 3,
) -> bytes:
    """Arc in the XY plane ``M20 G90|G91 G2|G3 X.. Y.. R.. F..`` (2021 firmware only).

    ``G2`` is clockwise, ``G3`` counter-clockwise, seen from above; the arc is the minor one.
    With ``relative=True`` the chord is known, so a chord longer than ``2 * radius`` (the
    firmware's ``E116 Arc radius error``) or of length zero is rejected here.
    """
    profile = _check_firmware(firmware)
    if COMMAND_PROFILE[profile] != "2021":
        raise _usage(f"arc (G2/G3) needs the 2021 firmware, not firmware={profile!r}")
    places = _check_decimals(decimals)
    x_text = fmt_number(x, places, name="x")
    y_text = fmt_number(y, places, name="y")
    r_text = _positive(radius, "radius", places, "mm")
    feed = _positive(speed, "speed", places, "mm/min")
    if relative:
        chord = math.hypot(float(x_text), float(y_text))
        if chord == 0:
            raise _usage(
                "a relative arc with x=0 and y=0 has no chord: a full circle is impossible"
            )
        if chord > 2 * float(r_text) + 1e-9:
            raise _usage(
                f"radius={r_text} is too small for the chord {_show(chord)} mm "
                f"(must be >= {_show(chord / 2)}; the firmware says 'Arc radius error')"
            )
    words = [
        "M20",
        "G91" if relative else "G90",
        "G2" if clockwise else "G3",
        "X" + x_text,
        "Y" + y_text,
        "R" + r_text,
        "F" + feed,
    ]
    return _finish(words)


def dwell(seconds: float, *, decimals: int = 3) -> bytes:
    """Pause the motion queue: ``G4 P<seconds>`` (occupies the planner, not the link)."""
    places = _check_decimals(decimals)
    number = _real(seconds, "seconds")
    if number < 0:
        raise _usage(f"seconds={_show(number)} must be >= 0")
    return _finish(["G4", "P" + fmt_number(number, places, name="seconds")])


def feed_rate(speed: float, *, decimals: int = 3) -> bytes:
    """Set the modal feed rate ``F<speed>`` (mm/min in M20, deg/min in M21) for later G1/G2/G3."""
    places = _check_decimals(decimals)
    return _finish(["F" + _positive(speed, "speed", places, "mm/min or deg/min")])


def absolute() -> bytes:
    """``G90``: following coordinates are absolute (the power-on default)."""
    return b"G90\n"


def relative() -> bytes:
    """``G91``: following coordinates are increments."""
    return b"G91\n"


def cartesian_mode() -> bytes:
    """``M20``: following moves are Cartesian (X Y Z mm, A B C = roll pitch yaw)."""
    return b"M20\n"


def joint_mode() -> bytes:
    """``M21``: following moves are joint angles (the power-on default)."""
    return b"M21\n"


# --------------------------------------------------------------------------------------------
# Homing, locking, alarms
# --------------------------------------------------------------------------------------------


def home(sequential: bool = False) -> bytes:
    """``$H`` (all axes together) or ``$HH`` (one after another, J1..J5; slower, safer).

    The ``ok`` comes before the arm is home; completion is ``Idle`` with zero angles.
    """
    return b"$HH\n" if sequential else b"$H\n"


def home_axis(axis: int, *, firmware: str = "2021") -> bytes:
    """``$H<axis>`` for axis 0..7 (2021 firmware only).

    PROTOCOL.md: ``$H0`` homes arm + rail, ``$H1``..``$H7`` one axis (7 = rail). The 2021 vendor
    manual only documents ``$H7``, as "fast homing of the arm, then axis 7 (rail)".
    """
    profile = _check_firmware(firmware)
    if COMMAND_PROFILE[profile] != "2021":
        raise _usage(f"home_axis ($H0..$H7) needs the 2021 firmware, not firmware={profile!r}")
    if isinstance(axis, bool) or not isinstance(axis, int) or not 0 <= axis <= 7:
        raise _usage(f"axis={axis!r} must be an integer 0..7")
    return f"$H{axis}\n".encode("ascii")


def home_compact(*, firmware: str = "2021") -> bytes:
    """``$HE``: compact homing (J2, J3 first, then J1, J4, J5) to avoid hitting nearby objects.

    2021 firmware only (2021 manual section 2.1.1).
    """
    profile = _check_firmware(firmware)
    if COMMAND_PROFILE[profile] != "2021":
        raise _usage(f"home_compact ($HE) needs the 2021 firmware, not firmware={profile!r}")
    return b"$HE\n"


def zero_pose(*, firmware: str = "2021") -> bytes:
    """``$M``: rapid move of every joint to its nominal 0 deg (2021 firmware only)."""
    profile = _check_firmware(firmware)
    if COMMAND_PROFILE[profile] != "2021":
        raise _usage(f"zero_pose ($M) needs the 2021 firmware, not firmware={profile!r}")
    return b"$M\n"


def unlock_axes() -> bytes:
    """``M50``: release the power-on axis lock without homing."""
    return b"M50\n"


def clear_alarm() -> bytes:
    """``$X``: leave Alarm (does not release the power-on axis lock; see :func:`unlock_axes`)."""
    return b"$X\n"


def settings_dump() -> bytes:
    """``$$``: print every setting as ``$N=value (description)``."""
    return b"$$\n"


def set_setting(number: int, value: float, *, firmware: str = "2021") -> bytes:
    """Write setting ``$<number>=<value>`` after checking it against :data:`SETTINGS`.

    Settings persist in the robot's EEPROM: a wrong value survives power cycles.
    """
    profile = _check_firmware(firmware)
    if isinstance(number, bool) or not isinstance(number, int):
        raise _usage(f"number={number!r} must be an integer setting number")
    if isinstance(value, bool):
        value = int(value)
    number_value = _real(value, "value")
    problem = setting_problem(number, number_value, profile, in_line=False)
    if problem is not None:
        raise _usage(problem)
    return _finish([f"${number}={fmt_number(number_value, 3, name='value')}"])


def set_soft_limits(on: bool) -> bytes:
    """``$20=1|0``: refuse (1) or allow (0) joint targets outside ``$130..$146``."""
    return f"$20={_flag(on, 'on')}\n".encode("ascii")


def set_hard_limits(on: bool) -> bytes:
    """``$21=1|0``: stop with ``ALARM: Hard limit`` when a J1..J3 switch trips."""
    return f"$21={_flag(on, 'on')}\n".encode("ascii")


def set_homing(on: bool) -> bytes:
    """``$22=1|0``: enable or disable the homing cycle."""
    return f"$22={_flag(on, 'on')}\n".encode("ascii")


# --------------------------------------------------------------------------------------------
# Outputs: pump, valve, gripper
# --------------------------------------------------------------------------------------------


def set_pump(pwm: int) -> bytes:
    """``M3 S<pwm>``: PWM 1, integer 0..1000 (pump: 0 off, 500 blow, 1000 suck; servo gripper)."""
    return _finish(["M3", f"S{_pwm(pwm, 'pwm')}"])


def set_valve(pwm: int) -> bytes:
    """``M4 E<pwm>``: PWM 2, integer 0..1000 (valve, or the V1.1 gripper: 65 open, 40 close)."""
    return _finish(["M4", f"E{_pwm(pwm, 'pwm')}"])


def set_gripper(closed: bool, *, legacy: bool = False) -> bytes:
    """Open or close a gripper: the servo gripper on PWM 1 (``M3 S40|S60``, 2021 manual), or with
    ``legacy=True`` the gripper on PWM 2 (``M4 E65|E40``, V1.1 manual)."""
    shut = _flag(closed, "closed")
    if legacy:
        return set_valve(VALVE_GRIPPER_CLOSE if shut else VALVE_GRIPPER_OPEN)
    return set_pump(GRIPPER_CLOSE if shut else GRIPPER_OPEN)
