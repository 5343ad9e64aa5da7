"""Constants and number handling shared by the line builders, the checker and the envelope.

Ranges of the joints, the rail and the PWM outputs, the firmware profiles, and
:func:`fmt_number`, which writes numbers the way the firmware reads them back (no exponent, no
``-0``). Pure module: no I/O.
"""

from __future__ import annotations

import math
import numbers
from typing import Final

from mirobot_async._core.line import MAX_LINE_LENGTH
from mirobot_async.errors import MirobotUsageError

__all__ = [
    "COMMAND_PROFILE",
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
    "VALVE_GRIPPER_CLOSE",
    "VALVE_GRIPPER_OPEN",
    "check_decimals",
    "check_firmware",
    "command_profile",
    "fmt_number",
    "real_number",
    "show_number",
]

FIRMWARE_PROFILES: Final = ("2021", "classic", "2024")
"""The firmware families (PROTOCOL.md section 1; 2024: EVIDENCE-NEWER.md, docs/2024-profile.md)."""

COMMAND_PROFILE: Final[dict[str, str]] = {"2021": "2021", "classic": "classic", "2024": "2021"}
"""The manual whose commands, geometry and settings a family follows. **ASSUMED** for 2024:
the evidence shows its replies, banner, settings list and states, nothing of its commands or
geometry, and its message table is the 2021 one renumbered (docs/2024-profile.md)."""

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
    "2024": (0.0, 500.0),
}
"""Rail (D axis) range in mm per firmware profile."""


def show_number(value: float) -> str:
    """A number for an error message: short, exact enough, never exponent notation."""
    if not math.isfinite(value):
        return repr(value)
    return fmt_number(value, 6)


def check_firmware(firmware: object) -> str:
    if firmware not in FIRMWARE_PROFILES:
        raise MirobotUsageError(
            f"firmware={firmware!r} is not one of {', '.join(FIRMWARE_PROFILES)}"
        )
    return str(firmware)


def command_profile(firmware: object) -> str:
    """``"2021"`` or ``"classic"``: the manual whose commands the family ``firmware`` follows
    (:data:`COMMAND_PROFILE`); MirobotUsageError for an unknown family."""
    return COMMAND_PROFILE[check_firmware(firmware)]


def check_decimals(decimals: object) -> int:
    if isinstance(decimals, bool) or not isinstance(decimals, int) or not 0 <= decimals <= 9:
        raise MirobotUsageError(f"decimals={decimals!r} must be an integer 0..9")
    return decimals


def real_number(value: object, name: str) -> float:
    """``value`` as a finite float, or MirobotUsageError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise MirobotUsageError(f"{name}={value!r} must be a number")
    result = float(value)
    if not math.isfinite(result):
        raise MirobotUsageError(f"{name}={result!r} must be a finite number")
    return result


def fmt_number(value: float, decimals: int = 3, *, name: str = "value") -> str:
    """Write ``value`` rounded to ``decimals`` places as compactly as possible.

    Trailing zeros and a trailing dot are removed, exponent notation is never used
    (``1e-05`` -> ``"0"``) and negative zero is written ``"0"``. NaN and infinities raise
    MirobotUsageError naming ``name``: the firmware would read them as garbage.
    """
    number = real_number(value, name)
    places = check_decimals(decimals)
    text = f"{number:.{places}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    if text == "-0":
        text = "0"
    return text
