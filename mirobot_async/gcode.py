"""Typed builders for Mirobot command lines, and an offline checker for raw G-code.

Every builder validates its arguments *before* producing anything and returns the canonical line
as ASCII ``bytes`` ending in ``b"\\n"``: upper-case words separated by single spaces, numbers
written by :func:`fmt_number` (never exponent notation, never ``-0``). A bad argument raises
:class:`~mirobot_async.errors.MirobotUsageError` (a ``ValueError``) whose message names the
argument and the allowed range, so nothing malformed can reach the robot.

:func:`check_line` / :func:`check_program` look at raw lines the way the firmware's parser would
(PROTOCOL.md sections 2, 6 and 7) and return human-readable problems; ``mirobot check FILE`` uses
them. This module is pure: no I/O, no asyncio, no serial.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Final, Literal

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

# --------------------------------------------------------------------------------------------
# Constants
# --------------------------------------------------------------------------------------------

FIRMWARE_PROFILES: Final = ("2021", "classic")
"""The two firmware generations (PROTOCOL.md section 1)."""

MAX_LINE_LENGTH: Final = 80
"""Longest line the firmware accepts after dropping spaces and comments (``Line overflow``)."""

PWM_MIN: Final = 0
PWM_MAX: Final = 1000

PUMP_OFF: Final = 0
PUMP_BLOW: Final = 500
PUMP_SUCK: Final = 1000
GRIPPER_OPEN: Final = 40
"""Servo gripper on PWM 1 (``M3 S40``), from the 2021 manual section 2.2.2."""
GRIPPER_CLOSE: Final = 60
"""Servo gripper on PWM 1 (``M3 S60``), from the 2021 manual section 2.2.2."""
VALVE_GRIPPER_OPEN: Final = 65
"""Older gripper on PWM 2 (``M4 E65``), from the V1.1 manual command 14."""
VALVE_GRIPPER_CLOSE: Final = 40
"""Older gripper on PWM 2 (``M4 E40``), from the V1.1 manual command 14."""

JOINT_NAMES: Final = ("J1", "J2", "J3", "J4", "J5", "J6")

JOINT_RANGES: Final[dict[str, tuple[float, float]]] = {
    "J1": (-100.0, 160.0),
    "J2": (-30.0, 70.0),
    "J3": (-170.0, 60.0),
    "J4": (-350.0, 350.0),
    "J5": (-205.0, 36.0),
    "J6": (-360.0, 360.0),
}
"""Joint soft-limit ranges in degrees (PROTOCOL.md section 7, the default ``$130..$146``)."""

RAIL_RANGES: Final[dict[str, tuple[float, float]]] = {
    "2021": (0.0, 500.0),
    "classic": (-1000.0, 1000.0),
}
"""Rail (D axis) range in mm per firmware profile."""

_JOINT_LETTERS: Final = ("X", "Y", "Z", "A", "B", "C")
_POSE_LETTERS: Final = ("X", "Y", "Z", "A", "B", "C")

# --------------------------------------------------------------------------------------------
# Number formatting and argument validation
# --------------------------------------------------------------------------------------------


def _usage(message: str) -> MirobotUsageError:
    return MirobotUsageError(message)


def _show(value: float) -> str:
    """A number for an error message: short, exact enough, never exponent notation."""
    if not math.isfinite(value):
        return repr(value)
    return fmt_number(value, 6)


def _check_firmware(firmware: object) -> str:
    if firmware not in FIRMWARE_PROFILES:
        raise _usage(f"firmware={firmware!r} is not one of {', '.join(FIRMWARE_PROFILES)}")
    return str(firmware)


def _check_decimals(decimals: object) -> int:
    if isinstance(decimals, bool) or not isinstance(decimals, int) or not 0 <= decimals <= 9:
        raise _usage(f"decimals={decimals!r} must be an integer 0..9")
    return decimals


def _real(value: object, name: str) -> float:
    """``value`` as a finite float, or MirobotUsageError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise _usage(f"{name}={value!r} must be a number")
    result = float(value)
    if not math.isfinite(result):
        raise _usage(f"{name}={result!r} must be a finite number")
    return result


def fmt_number(value: float, decimals: int = 3, *, name: str = "value") -> str:
    """Write ``value`` rounded to ``decimals`` places as compactly as possible.

    Trailing zeros and a trailing dot are removed, exponent notation is never used
    (``1e-05`` -> ``"0"``) and negative zero is written ``"0"``. NaN and infinities raise
    MirobotUsageError naming ``name``: the firmware would read them as garbage.
    """
    number = _real(value, name)
    places = _check_decimals(decimals)
    text = f"{number:.{places}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    if text == "-0":
        text = "0"
    return text


def _positive(value: object, name: str, decimals: int, what: str) -> str:
    """A strictly positive number, as written on the wire (it must stay > 0 after rounding)."""
    number = _real(value, name)
    text = fmt_number(number, decimals, name=name)
    if number <= 0:
        raise _usage(f"{name}={_show(number)} must be > 0 ({what})")
    if float(text) <= 0:
        raise _usage(
            f"{name}={_show(number)} must be > 0 ({what}); with {decimals} decimals it is 0"
        )
    return text


def _pwm(value: object, name: str) -> int:
    """An integer PWM value 0..1000."""
    allowed = f"an integer {PWM_MIN}..{PWM_MAX}"
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise _usage(f"{name}={value!r} must be {allowed}")
    number = float(value)
    if not math.isfinite(number) or not number.is_integer():
        raise _usage(f"{name}={value!r} must be {allowed}")
    if not PWM_MIN <= number <= PWM_MAX:
        raise _usage(f"{name}={int(number)} is outside {PWM_MIN}..{PWM_MAX} (must be {allowed})")
    return int(number)


def _flag(value: object, name: str) -> int:
    if value is True or value is False or value in (0, 1):
        return 1 if value else 0
    raise _usage(f"{name}={value!r} must be True/False (or 1/0)")


def _finish(words: list[str]) -> bytes:
    """Join words into the canonical line; enforce the firmware's line-length limit."""
    text = " ".join(words)
    compact = len(text) - text.count(" ")
    if compact > MAX_LINE_LENGTH:
        raise _usage(
            f"the line {text!r} is {compact} bytes without spaces; the firmware accepts at most "
            f"{MAX_LINE_LENGTH} ('Line overflow'): use fewer decimals or split the command"
        )
    return text.encode("ascii") + b"\n"


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
) -> bytes:
    """Joint-space move ``M21 G90|G91 G0|G1 X.. Y.. Z.. A.. B.. C.. D.. [F..]``.

    Angles in degrees (J1..J6 = X..C), rail in mm (D). Without ``speed`` the move is ``G0`` (every
    joint at its max rate); with ``speed`` (deg/min) it is ``G1 F<speed>``. Omitted joints stay.
    Absolute targets are checked against :data:`JOINT_RANGES` / :data:`RAIL_RANGES` when
    ``check_limits`` (relative ones cannot be checked without the current position).
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
    words = ["M21", "G91" if relative else "G90"]
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
) -> bytes:
    """Cartesian move ``M20 G90|G91 G0|G1 X.. Y.. Z.. A.. B.. C.. [F..]`` (mm, degrees).

    ``linear=False`` is point-to-point (``G0``, joints at max rates; ``speed`` is optional and only
    sets the modal feed). ``linear=True`` is a straight line (``G1``) at ``speed`` mm/min, which is
    then required: a G1 without F fails with ``Undefined feed rate`` after homing.
    Reachability is not checked here (see :mod:`mirobot_async.envelope`).
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
    words = ["M20", "G91" if relative else "G90", "G1" if linear else "G0", *axis_words]
    if feed is not None:
        words.append("F" + feed)
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
    if profile != "2021":
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
    if profile != "2021":
        raise _usage(f"home_axis ($H0..$H7) needs the 2021 firmware, not firmware={profile!r}")
    if isinstance(axis, bool) or not isinstance(axis, int) or not 0 <= axis <= 7:
        raise _usage(f"axis={axis!r} must be an integer 0..7")
    return f"$H{axis}\n".encode("ascii")


def home_compact(*, firmware: str = "2021") -> bytes:
    """``$HE``: compact homing (J2, J3 first, then J1, J4, J5) to avoid hitting nearby objects.

    2021 firmware only (2021 manual section 2.1.1).
    """
    profile = _check_firmware(firmware)
    if profile != "2021":
        raise _usage(f"home_compact ($HE) needs the 2021 firmware, not firmware={profile!r}")
    return b"$HE\n"


def zero_pose(*, firmware: str = "2021") -> bytes:
    """``$M``: rapid move of every joint to its nominal 0 deg (2021 firmware only)."""
    profile = _check_firmware(firmware)
    if profile != "2021":
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


# --------------------------------------------------------------------------------------------
# Settings
# --------------------------------------------------------------------------------------------

SettingKind = Literal["bool", "int", "float"]


@dataclass(frozen=True, slots=True)
class SettingInfo:
    """What one ``$N`` setting means and which values it takes."""

    number: int
    description: str
    unit: str = ""
    kind: SettingKind = "float"
    minimum: float | None = None
    maximum: float | None = None


# Axis settings are grouped by the firmware's axis letters a..g = J4, J5, J6, D, J1, J2, J3.
_SETTING_AXES: Final = (
    ("J4", "deg"),
    ("J5", "deg"),
    ("J6", "deg"),
    ("rail D", "mm"),
    ("J1", "deg"),
    ("J2", "deg"),
    ("J3", "deg"),
)


def _build_settings(profile: str) -> dict[int, SettingInfo]:
    """The known settings of one firmware profile (PROTOCOL.md section 7, GRBL 0.9j, manuals)."""
    s: list[SettingInfo] = [
        SettingInfo(0, "step pulse time", "us", "int", 3, 255),
        SettingInfo(1, "step idle delay", "ms", "int", 0, 255),
        SettingInfo(2, "step port invert mask", "", "int", 0, 255),
        SettingInfo(3, "direction port invert mask", "", "int", 0, 255),
        SettingInfo(4, "step enable invert", "", "bool"),
        SettingInfo(5, "limit pins invert", "", "bool"),
        SettingInfo(6, "probe pin invert", "", "bool"),
        SettingInfo(10, "status report mask", "", "int", 0, 255),
        SettingInfo(11, "junction deviation", "mm", "float", 0),
        SettingInfo(12, "arc tolerance", "mm", "float", 0),
        SettingInfo(13, "report in inches", "", "bool"),
        SettingInfo(20, "soft limits", "", "bool"),
        SettingInfo(21, "hard limits (switches on J1..J3)", "", "bool"),
        SettingInfo(22, "homing cycle enabled", "", "bool"),
        SettingInfo(23, "homing direction invert mask", "", "int", 0, 255),
        SettingInfo(24, "homing feed (slow, locating the switch)", "deg/min", "float", 0),
        SettingInfo(25, "homing seek (fast, finding the switch)", "deg/min", "float", 0),
        SettingInfo(26, "homing switch debounce", "ms", "int", 0, 65535),
        SettingInfo(27, "homing pull-off", "deg", "float", 0),
    ]
    if profile == "2021":
        s += [
            SettingInfo(28, "direction of motion after homing (axis mask)", "", "int", 0, 255),
            SettingInfo(29, "DH length D1", "mm"),
            SettingInfo(30, "DH length A1", "mm"),
            SettingInfo(31, "DH length A2", "mm"),
            SettingInfo(32, "DH length A3", "mm"),
            SettingInfo(33, "DH length D4", "mm"),
            SettingInfo(34, "DH length L (D6, flange offset)", "mm"),
            SettingInfo(35, "G1 linear interpolation enabled", "", "bool"),
            SettingInfo(36, "G1 interpolation points", "", "int", 1),
            SettingInfo(41, "base origin offset X", "mm"),
            SettingInfo(42, "base origin offset Y", "mm"),
            SettingInfo(43, "base origin offset Z", "mm"),
            SettingInfo(46, "tool offset X (flange frame)", "mm"),
            SettingInfo(47, "tool offset Y (flange frame)", "mm"),
            SettingInfo(48, "tool offset Z (flange frame)", "mm"),
            SettingInfo(49, "G05 lift height", "mm", "float", 0),
            SettingInfo(
                50, "tool type (0 none, 1 suction cup, 2 gripper, 3 soft gripper)", "", "int", 0, 3
            ),
        ]
    groups = (
        (100, "steps per {u}", "steps/{u}"),
        (110, "max rate", "{u}/min"),
        (120, "acceleration", "{u}/s^2"),
        (130, "max travel, positive side", "{u}"),
        (140, "max travel, magnitude of the negative side", "{u}"),
    )
    for base, what, unit in groups:
        for offset, (axis, axis_unit) in enumerate(_SETTING_AXES):
            s.append(
                SettingInfo(
                    base + offset,
                    f"{what.format(u=axis_unit)} {axis}",
                    unit.format(u=axis_unit),
                    "float",
                    0,
                )
            )
    if profile == "2021":
        # The 2021 manual lists $150 twice: J4 calibration (3.9) and backlash switch (3.10).
        for offset, (axis, axis_unit) in enumerate(_SETTING_AXES):
            s.append(SettingInfo(150 + offset, f"calibration position {axis}", axis_unit))
        for offset, (axis, axis_unit) in enumerate(_SETTING_AXES):
            s.append(SettingInfo(160 + offset, f"backlash compensation {axis}", axis_unit))
    return {info.number: info for info in s}


SETTINGS: Final[dict[str, dict[int, SettingInfo]]] = {
    profile: _build_settings(profile) for profile in FIRMWARE_PROFILES
}
"""Known ``$N`` settings per firmware profile: ``SETTINGS["2021"][110].description``."""


def _setting_problem(number: int, value: float, profile: str, *, in_line: bool) -> str | None:
    """Why ``$number=value`` is bad on ``profile``, or None.

    Messages name the builder's arguments (``number=``, ``value=``) or, with ``in_line``, the
    words of the line (``$20=2``).
    """
    info = SETTINGS[profile].get(number)
    if info is None:
        subject = f"${number}" if in_line else f"number={number}"
        return f"{subject} is not a known $ setting of the {profile!r} firmware"
    if in_line:
        subject = f"${number}={_show(value)} ({info.description})"
    else:
        subject = f"value={_show(value)} for ${number} ({info.description})"
    if profile == "classic" and value < 0:
        return f"{subject}: classic firmware rejects negative values: 'Value < 0'"
    if info.kind == "bool":
        return None if value in (0, 1) else f"{subject} must be 0 or 1"
    if info.kind == "int" and not value.is_integer():
        return f"{subject} must be an integer"
    low, high = info.minimum, info.maximum
    if (low is not None and value < low) or (high is not None and value > high):
        low_text = "" if low is None else _show(low)
        high_text = "" if high is None else _show(high)
        return f"{subject} is outside {low_text}..{high_text}"
    return None


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
    problem = _setting_problem(number, number_value, profile, in_line=False)
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


# --------------------------------------------------------------------------------------------
# Offline checking of raw lines
# --------------------------------------------------------------------------------------------

_NUMBER_RE: Final = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
_KNOWN_LETTERS: Final = frozenset("GMXYZABCDFPSER")
_AXIS_LETTERS: Final = frozenset("XYZABCD")
_G_CODES: Final[dict[str, frozenset[int]]] = {
    "classic": frozenset({0, 1, 4, 90, 91}),
    "2021": frozenset({0, 1, 2, 3, 4, 5, 90, 91}),
}
_M_CODES: Final = frozenset({2, 3, 4, 5, 20, 21, 30, 50})
_G_GROUPS: Final[dict[int, str]] = {
    0: "motion",
    1: "motion",
    2: "motion",
    3: "motion",
    5: "motion",
    4: "dwell",
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
}
_DOLLAR_SIMPLE: Final = frozenset({"$", "$$", "$#", "$G", "$I", "$N", "$C", "$X", "$H", "$HH"})
_DOLLAR_2021: Final = frozenset({*(f"$H{n}" for n in range(8)), "$HE", "$M"})
_DOLLAR_HOMING: Final = frozenset({"$H", "$HH", "$HE", *(f"$H{n}" for n in range(8))})
_SETTING_RE: Final = re.compile(r"\$(\d+)=(.*)")


@dataclass(slots=True)
class ModalState:
    """Parser state that persists between lines (modal words), as after power-on or reset.

    :func:`check_line` updates it in place so that consecutive lines are judged in context.
    """

    cartesian: bool = False
    """``M20`` in effect (else ``M21``, the power-on default)."""
    relative: bool = False
    """``G91`` in effect (else ``G90``, the power-on default)."""


def normalize_line(line: str | bytes) -> str:
    """The line as the firmware's parser sees it: bytes <= 0x20 and ``/`` dropped, letters upper
    case, ``( ... )`` and ``; ...`` comments removed. Realtime bytes (``? ! ~ %``) are removed too.
    """
    text = line.decode("latin-1") if isinstance(line, bytes) else line
    return _normalize(text)[0]


def _normalize(text: str) -> tuple[str, bool]:
    """(normalized text, True if a ``(`` comment was left open)."""
    out: list[str] = []
    in_comment = False
    for char in text:
        if char in _REALTIME:
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


def _tokenize(norm: str) -> tuple[list[tuple[str, float, str]], str | None]:
    """Split a normalized G-code line into (letter, value, number text); stop at the first error."""
    words: list[tuple[str, float, str]] = []
    pos = 0
    while pos < len(norm):
        letter = norm[pos]
        if not "A" <= letter <= "Z":
            return words, (
                f"expected a command letter at {norm[pos : pos + 8]!r} ('Expected command letter')"
            )
        match = _NUMBER_RE.match(norm, pos + 1)
        if match is None:
            return words, (f"the letter {letter} is not followed by a number ('Bad number format')")
        words.append((letter, float(match.group()), match.group()))
        pos = match.end()
    return words, None


def parse_words(line: str | bytes) -> list[tuple[str, float]]:
    """The G-code words of a line as (letter, value) pairs, in order: ``"G1X10 f200"`` ->
    ``[("G", 1.0), ("X", 10.0), ("F", 200.0)]``. Raises MirobotUsageError on syntax errors
    and on ``$`` commands (which are not words)."""
    norm = normalize_line(line)
    if norm.startswith("$"):
        raise _usage(f"line={norm!r} is a $ command, not G-code words")
    words, error = _tokenize(norm)
    if error is not None:
        raise _usage(f"line={norm!r}: {error}")
    return [(letter, value) for letter, value, _ in words]


def _range_text(low: float, high: float) -> str:
    return f"{_show(low)}..{_show(high)}"


def _check_dollar(norm: str, profile: str, state: ModalState, problems: list[str]) -> None:
    if norm in _DOLLAR_SIMPLE or norm in _DOLLAR_2021:
        if norm in _DOLLAR_2021 and profile != "2021":
            problems.append(f"{norm} needs the 2021 firmware")
            return
        if norm in _DOLLAR_HOMING:
            state.cartesian = False
            state.relative = False
        return
    if norm.startswith(("$N0=", "$N1=")) or norm in ("$RST=$", "$RST=#", "$RST=*"):
        return
    match = _SETTING_RE.fullmatch(norm)
    if match is None:
        if re.fullmatch(r"\$\d+", norm):
            problems.append(f"{norm} has no '=value' ('Invalid statement')")
        else:
            problems.append(f"unknown $ command {norm!r} ('Invalid statement')")
        return
    number = int(match.group(1))
    value_text = match.group(2)
    if _NUMBER_RE.fullmatch(value_text) is None:
        problems.append(f"${number}={value_text}: the value is not a number ('Bad number format')")
        return
    problem = _setting_problem(number, float(value_text), profile, in_line=True)
    if problem is not None:
        problems.append(problem)


def _check_gcode(norm: str, profile: str, state: ModalState, problems: list[str]) -> None:
    words, error = _tokenize(norm)
    if error is not None:
        problems.append(error)
        return
    groups: dict[str, str] = {}
    values: dict[str, float] = {}
    motion: int | None = None
    dwell_seen = False
    new_cartesian: bool | None = None
    new_relative: bool | None = None
    for letter, value, text in words:
        word = letter + text
        if letter not in _KNOWN_LETTERS:
            problems.append(f"{word}: the letter {letter} is not supported ('Unsupported command')")
            continue
        if letter in "GM":
            code = int(value)
            known = _G_CODES[profile] if letter == "G" else _M_CODES
            if not value.is_integer() or code not in known:
                needs_2021 = letter == "G" and value.is_integer() and code in _G_CODES["2021"]
                problems.append(
                    f"{word} needs the 2021 firmware"
                    if needs_2021
                    else f"{word} is not a Mirobot command ('Unsupported command')"
                )
                continue
            group = (_G_GROUPS if letter == "G" else _M_GROUPS)[code]
            canonical = f"{letter}{code}"
            if group in groups:
                problems.append(
                    f"{groups[group]} and {canonical} are in the same modal group "
                    "('Modal group violation')"
                )
                continue
            groups[group] = canonical
            if letter == "G":
                if group == "motion":
                    motion = code
                elif code == 4:
                    dwell_seen = True
                else:
                    new_relative = code == 91
            elif code in (20, 21):
                new_cartesian = code == 20
            continue
        if letter in values:
            problems.append(f"the word {letter} appears twice in the line (repeated word)")
            continue
        values[letter] = value
        if letter in "FPS" and value < 0:
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
        _check_arc(motion, values, cartesian, is_relative, problems)
    elif "R" in values:
        problems.append("R is only used by G2/G3 arcs (unused word)")

    if not cartesian and not is_relative and not dwell_seen:
        for letter, joint in zip(_JOINT_LETTERS, JOINT_NAMES, strict=True):
            if letter in values:
                low, high = JOINT_RANGES[joint]
                if not low <= values[letter] <= high:
                    problems.append(
                        f"{joint}={_show(values[letter])} is outside {_range_text(low, high)}"
                    )
        if "D" in values:
            low, high = RAIL_RANGES[profile]
            if not low <= values["D"] <= high:
                problems.append(f"rail D={_show(values['D'])} is outside {_range_text(low, high)}")

    if new_cartesian is not None:
        state.cartesian = new_cartesian
    if new_relative is not None:
        state.relative = new_relative


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
        problems.append(f"{name} R{_show(radius)}: the radius must be > 0 ('Arc radius error')")
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
                f"{name}: the chord {_show(chord)} mm is longer than 2R = {_show(2 * radius)} "
                "('Arc radius error')"
            )


def check_line(
    line: str | bytes, *, firmware: str = "2021", state: ModalState | None = None
) -> list[str]:
    """Problems the firmware would have with one raw line, as human-readable messages.

    The line is judged like the firmware's parser does (filtering, comments, 80-byte limit,
    words, modal groups, settings) plus joint/rail ranges of absolute ``M21`` moves. ``state`` is
    the modal state before the line (power-on defaults when omitted) and is updated in place.
    Feed-rate state is not checked: ``G1`` without ``F`` depends on what ran before.
    An empty list means no problem found.
    """
    profile = _check_firmware(firmware)
    if state is None:
        state = ModalState()
    text = line.decode("latin-1") if isinstance(line, bytes) else line
    text = text.rstrip("\r\n")
    problems: list[str] = []
    if "\n" in text or "\r" in text:
        problems.append("contains a line break: the firmware would see several lines")
    odd = sorted({char for char in text if ord(char) > 0x7E})
    if odd:
        problems.append(f"contains characters outside printable ASCII: {''.join(odd)!r}")
    for char in sorted({char for char in text if char in _REALTIME}):
        problems.append(
            f"contains {char!r}, which the firmware takes at once as {_REALTIME[char]} "
            "and removes from the line"
        )
    norm, open_comment = _normalize(text)
    if open_comment:
        problems.append("a '(' comment is not closed: the rest of the line is ignored")
    if len(norm) > MAX_LINE_LENGTH:
        problems.append(
            f"the line is {len(norm)} bytes after removing spaces and comments; "
            f"the firmware limit is {MAX_LINE_LENGTH} ('Line overflow')"
        )
        return problems
    if not norm:
        return problems
    if norm.startswith("$"):
        _check_dollar(norm, profile, state, problems)
    else:
        _check_gcode(norm, profile, state, problems)
    return problems


def check_program(lines: Iterable[str | bytes], *, firmware: str = "2021") -> list[tuple[int, str]]:
    """Check the lines of a G-code file in order, from power-on state.

    Returns (1-based line number, problem) pairs; modal words carry over between lines.
    """
    profile = _check_firmware(firmware)
    state = ModalState()
    found: list[tuple[int, str]] = []
    for number, line in enumerate(lines, start=1):
        found.extend(
            (number, problem) for problem in check_line(line, firmware=profile, state=state)
        )
    return found
