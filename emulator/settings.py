"""The ``$`` settings of the virtual Mirobot: numbers, defaults per profile, ``$$`` formatting.

Pure data and string formatting, used by :mod:`mirobot_emulator.firmware`.

Sources: PROTOCOL.md section 7 (the Mirobot settings and their defaults), GRBL 0.9j's
``report.c`` (the ``$N=value (description)`` layout: floats with 3 decimals, integers and masks
plain, masks followed by their 8 binary digits) and the vendor's open firmware source (the
descriptions of the robot settings ``$28..$43``).

Axis settings are grouped by the firmware's axis letters a..g = J4, J5, J6, D (rail), J1, J2,
J3: ``$110`` is the max rate of J4, ``$114`` the one of J1.

**ASSUMED** here (each in one table or function below):

* ``$0..$6``, ``$11..$13``, ``$23``, ``$26``, ``$28`` and the classic ``$100..$106`` defaults are
  the open firmware's.
* The 2021 steps per degree of J1..J6 (``$100..$102``, ``$104..$106``) are classic's (56.73,
  113.33, 64, 16, 22.22, 11.11), not the 2021 manual's table (38.482, 113.1, 40, 32, 22.712,
  11.356): a device log outranks a manual, and the 2021 manual's own device printout
  (``vectors.json`` ``corrupted_status_lines[0]``: J1..J6 = 90.005, 30.001, -20.000, 10.000,
  19.982, 45.005) is 5106, 3400, -1280, 160, 444, 500 whole steps of the classic grid on all six
  axes and lies on the manual's grid on none (J1 would read 90.016). The rail's ``$103`` stays
  the manual's 211.111 (no 2021 device output shows the rail's grid).
* The classic profile (firmware 20191228_2) has GRBL's settings, ``$28``, the axis groups
  ``$100..$156``; the DH lengths are not settings there (PROTOCOL 7).
* Both profiles have ``$28`` and ``$150..$156`` (calibration, "reset distance"); the classic
  lines are the ones the classic firmware prints (checked against it).
* The 2021 profile adds ``$29..$36``, ``$41..$43``, ``$46..$50`` and ``$160..$166`` (backlash)
  with the 2021 manual's defaults (also for ``$150..$156``); the open firmware's ``$37..$40`` are
  not in the 2021 manual and absent.
* The open firmware prints a ``Settings for robot:`` header line inside ``$$``; it is left out so
  that every dump line is ``$N=value (description)`` (PROTOCOL 7).
* Descriptions of settings the open firmware does not have (``$46..$50``, ``$140..$146``,
  ``$160..$166``) are written in the same style.
* Which settings accept a negative value: none on classic (``error: Value < 0``, PROTOCOL 6);
  on 2021 the ones that are signed quantities (``SIGNED_2021``: L, base and tool offsets).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

__all__ = [
    "AXIS_LETTERS",
    "PROFILES",
    "SIGNED_2021",
    "SettingSpec",
    "default_settings",
    "format_dump",
    "format_setting",
    "format_value",
    "grbl_float",
    "spec",
    "specs",
]

PROFILES: Final = ("classic", "2021", "2024")

AXIS_LETTERS: Final = "abcdefg"
"""Firmware axis letters of the axis settings: a..g = J4, J5, J6, D, J1, J2, J3."""


@dataclass(frozen=True, slots=True)
class SettingSpec:
    """One setting: its number, default, ``$$`` description and printing style."""

    number: int
    default: float
    description: str
    kind: str = "float"  # "float" (3 decimals), "int" (plain integer), "mask" (int + binary)


def _s(number: int, default: float, description: str, kind: str = "float") -> SettingSpec:
    return SettingSpec(number, float(default), description, kind)


# GRBL 0.9j basics, with the Mirobot's defaults (open firmware defaults_generic.h; PROTOCOL 7).
_GRBL_BASICS: Final = (
    _s(0, 10, "step pulse, usec", "int"),
    _s(1, 0, "step idle delay, msec", "int"),
    _s(2, 0, "step port invert mask", "mask"),
    _s(3, 119, "dir port invert mask", "mask"),
    _s(4, 0, "step enable invert, bool", "int"),
    _s(5, 0, "limit pins invert, bool", "int"),
    _s(6, 0, "probe pin invert, bool", "int"),
    _s(10, 99, "status report mask", "mask"),
    _s(11, 0.010, "junction deviation, mm"),
    _s(12, 0.002, "arc tolerance, mm"),
    _s(13, 0, "report inches, bool", "int"),
    _s(20, 1, "soft limits, bool", "int"),
    _s(21, 1, "hard limits, bool", "int"),
    _s(22, 1, "homing cycle, bool", "int"),
    _s(23, 48, "homing dir invert mask", "mask"),
    _s(24, 1500, "homing feed, mm/min"),
    _s(25, 2000, "homing seek, mm/min"),
    _s(26, 250, "homing debounce, msec", "int"),
    _s(27, 12, "homing pull-off, mm"),
)

# Mirobot robot settings of the 2021 profile (descriptions of $28..$43 as the open firmware
# prints them; defaults from the 2021 manual).
_ROBOT_2021: Final = (
    _s(29, 127.0, "D1 Link length"),
    _s(30, 29.69, "A1 Link length"),
    _s(31, 108.0, "A2 Link length"),
    _s(32, 20.0, "A3 Link length"),
    _s(33, 168.98, "D4 Link length"),
    _s(34, -24.28, "L Link length"),
    _s(35, 1, "Use interpolation or not"),
    _s(36, 10, "Number of interpolation", "int"),
    _s(41, 0, "X offset"),
    _s(42, 0, "Y offset"),
    _s(43, 0, "Z offset"),
    _s(46, 0, "Tool X offset"),
    _s(47, 0, "Tool Y offset"),
    _s(48, 0, "Tool Z offset"),
    _s(49, 30, "G05 lift height"),
    _s(50, 0, "Tool type", "int"),
)

# Axis groups: (base number, description suffix, classic defaults a..g, 2021 defaults a..g).
_AXIS_GROUPS: Final = (
    (100, ", step/mm", (16.0, 22.22, 11.11, 200.0, 56.73, 113.33, 64.0),
     (16.0, 22.22, 11.11, 211.111, 56.73, 113.33, 64.0)),  # see the module docstring
    (110, " max rate, mm/min", (1800, 1500, 2500, 500, 2000, 2000, 2000),
     (1800, 1500, 2500, 500, 1800, 1500, 1800)),
    (120, " accel, mm/sec^2", (50,) * 7, (50,) * 7),
    (130, " max travel, mm", (350, 36, 360, 1000, 160, 70, 60), (350, 36, 360, 500, 160, 70, 60)),
    (140, " min travel, mm", (350, 205, 360, 1000, 100, 30, 170),
     (350, 205, 360, 0, 100, 30, 170)),
)  # fmt: skip

# Calibration ("reset distance" in the open firmware; the classic defaults and lines as the
# classic firmware prints them in ``$$``) and the 2021 backlash compensation: (base, suffix,
# classic defaults or None when the classic firmware lacks the group, 2021 defaults).
_AXIS_GROUPS_EXTRA: Final = (
    (150, " reset distance", (45, 45, 0, 0, 45, 45, 45), (73, 30, 0, 0, 100, 32, 57)),
    (160, " backlash, mm", None, (0,) * 7),
)

_ROBOT_2024: Final = (
    _s(44, 0, "Line discard number", "int"),
    _s(45, 0, "Rail/conveyor mode", "int"),
    _s(51, 0, "Reserved", "int"),
    _s(52, 0, "Colour sensor", "int"),
)
"""What the 2024 family's ``$$`` lists beyond the 2021 manual (EVIDENCE-NEWER.md 1: ``$44`` line
discard number, ``$45`` rail/conveyor mode, ``$51``, ``$52`` colour sensor). ASSUMED: their
defaults (0), kinds (integers) and descriptions (the capture's meanings, not its words; ``$51``
has none)."""

_HOMING_POS_DIR: Final = _s(28, 65, "homing pos dir invert mask", "mask")
"""``$28`` on both profiles (the classic ``$$`` lists it too)."""

SIGNED_2021: Final = frozenset({34, 41, 42, 43, 46, 47, 48})
"""ASSUMED: the 2021 settings that accept a negative value (L, base offsets, tool offsets)."""


def _build(profile: str) -> dict[int, SettingSpec]:
    table: dict[int, SettingSpec] = {s.number: s for s in _GRBL_BASICS}
    table[_HOMING_POS_DIR.number] = _HOMING_POS_DIR
    if profile in ("2021", "2024"):
        table.update({s.number: s for s in _ROBOT_2021})
    if profile == "2024":
        table.update({s.number: s for s in _ROBOT_2024})
    for base, suffix, classic, modern in _AXIS_GROUPS:
        values = classic if profile == "classic" else modern
        for k, letter in enumerate(AXIS_LETTERS):
            table[base + k] = _s(base + k, values[k], f"{letter}{suffix}")
    for base, suffix, classic_extra, modern_extra in _AXIS_GROUPS_EXTRA:
        extra = classic_extra if profile == "classic" else modern_extra
        if extra is None:
            continue
        for k, letter in enumerate(AXIS_LETTERS):
            table[base + k] = _s(base + k, extra[k], f"{letter}{suffix}")
    return dict(sorted(table.items()))


_TABLES: Final = {profile: _build(profile) for profile in PROFILES}


def _check_profile(profile: str) -> None:
    if profile not in _TABLES:
        raise ValueError(f"unknown firmware profile {profile!r} (use 'classic', '2021' or '2024')")


def specs(profile: str) -> Mapping[int, SettingSpec]:
    """Every setting of ``profile`` by number, in ``$$`` order."""
    _check_profile(profile)
    return _TABLES[profile]


def spec(profile: str, number: int) -> SettingSpec | None:
    """The setting ``number`` of ``profile``, or None when the profile has no such setting."""
    _check_profile(profile)
    return _TABLES[profile].get(number)


def default_settings(profile: str) -> dict[int, float]:
    """A fresh copy of the factory settings of ``profile``."""
    return {n: s.default for n, s in specs(profile).items()}


def grbl_float(value: float, decimals: int = 3) -> str:
    """GRBL's ``printFloat``: ``decimals`` places, rounded half up on the magnitude, a ``-`` only
    for values below zero (so ``-0.0`` prints ``0.000`` but ``-0.0001`` prints ``-0.000``)."""
    if not math.isfinite(value):
        return "nan" if value != value else ("-inf" if value < 0 else "inf")
    scaled = math.floor(abs(value) * 10**decimals + 0.5)
    whole, frac = divmod(scaled, 10**decimals)
    text = f"{whole}.{frac:0{decimals}d}" if decimals else f"{whole}."
    return f"-{text}" if value < 0 else text


def _uint8(value: float) -> int:
    """GRBL stores integer settings in a uint8_t (values wrap modulo 256)."""
    return int(value) % 256 if value == value and abs(value) < 2**63 else 0


def format_value(number: int, value: float, profile: str) -> str:
    """``value`` of setting ``number`` as ``$$`` prints it (``99``, ``1500.000``)."""
    setting = spec(profile, number)
    kind = setting.kind if setting is not None else "float"
    if kind == "float":
        return grbl_float(value)
    if number == 26:  # uint16_t in GRBL (homing debounce)
        return str(int(value) % 65536 if abs(value) < 2**63 else 0)
    return str(_uint8(value))


def format_setting(number: int, value: float, profile: str) -> str:
    """One ``$$`` line without its line ending: ``$10=99 (status report mask:01100011)``."""
    setting = spec(profile, number)
    if setting is None:
        raise KeyError(number)
    text = format_value(number, value, profile)
    if setting.kind == "mask":
        return f"${number}={text} ({setting.description}:{_uint8(value):08b})"
    return f"${number}={text} ({setting.description})"


def format_dump(values: Mapping[int, float], profile: str) -> list[str]:
    """The lines of ``$$`` (without line endings), in firmware order."""
    return [format_setting(n, values[n], profile) for n in specs(profile)]
