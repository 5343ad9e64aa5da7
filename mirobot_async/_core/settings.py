"""The ``$N`` settings of each firmware profile: meaning, unit and allowed values.

:data:`SETTINGS` is the table (PROTOCOL.md section 7, GRBL 0.9j, the vendor manuals);
:func:`setting_problem` says why a value is wrong for a setting. Pure module: no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final, Literal

from mirobot_async._core.values import FIRMWARE_PROFILES, show_number

__all__ = [
    "SETTINGS",
    "STATUS_MASK",
    "STATUS_MASK_NEEDED",
    "SettingInfo",
    "SettingKind",
    "setting_problem",
]

SettingKind = Literal["bool", "int", "float"]

STATUS_MASK: Final = 10
"""``$10``, the status report mask."""
STATUS_MASK_NEEDED: Final = 1 | 32
"""The bits of ``$10`` a status report needs to be read: the angles and pose (1), the PWM values
(32). The others (Motion_MODE 64, Buf 4, RX 8, Lim 16, 2) only add fields the client skips."""


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
        SettingInfo(10, "status report mask", "", "int", STATUS_MASK_NEEDED, 255),
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
    if profile in ("2021", "2024"):
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
    if profile == "2024":  # EVIDENCE-NEWER.md 1: what its $$ lists beyond the 2021 manual
        s += [
            SettingInfo(44, "line discard number (2024)", ""),
            SettingInfo(45, "rail / conveyor mode (2024)", ""),
            SettingInfo(51, "(2024; meaning not in the evidence)", ""),
            SettingInfo(52, "colour sensor (2024)", ""),
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
    if profile in ("2021", "2024"):
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


def setting_problem(number: int, value: float, profile: str, *, in_line: bool) -> str | None:
    """Why ``$number=value`` is bad on ``profile``, or None.

    Messages name the builder's arguments (``number=``, ``value=``) or, with ``in_line``, the
    words of the line (``$20=2``).
    """
    info = SETTINGS[profile].get(number)
    if info is None:
        subject = f"${number}" if in_line else f"number={number}"
        return f"{subject} is not a known $ setting of the {profile!r} firmware"
    if in_line:
        subject = f"${number}={show_number(value)} ({info.description})"
    else:
        subject = f"value={show_number(value)} for ${number} ({info.description})"
    if profile == "classic" and value < 0:
        return f"{subject}: classic firmware rejects negative values: 'Value < 0'"
    if info.kind == "bool":
        return None if value in (0, 1) else f"{subject} must be 0 or 1"
    if info.kind == "int" and not value.is_integer():
        return f"{subject} must be an integer"
    if (
        number == STATUS_MASK
        and 0 <= value <= 255
        and int(value) & STATUS_MASK_NEEDED != STATUS_MASK_NEEDED
    ):
        return (
            f"{subject}: status reports would lack the angles (1) or the PWM values (32), and "
            "the client could read no status any more; keep both bits (default 99)"
        )
    low, high = info.minimum, info.maximum
    if (low is not None and value < low) or (high is not None and value > high):
        low_text = "" if low is None else show_number(low)
        high_text = "" if high is None else show_number(high)
        return f"{subject} is outside {low_text}..{high_text}"
    return None
