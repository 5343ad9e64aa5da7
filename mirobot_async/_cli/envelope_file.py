"""Envelope files: a workspace safety envelope written as TOML (``mirobot run --envelope FILE``).

The fields are those of :class:`~mirobot_async._safety.envelope.Envelope`, each optional::

    rail = [0, 500]             # mm, the D axis
    tool = [0, 0, 60]           # mm, the tool offset of the arm's settings ($46..$48)

    [box]                       # the tool point, mm, in the arm's base frame
    x = [100, 280]
    y = [-200, 200]
    z = [20, inf]               # inf / -inf: that side is open

    [joints]                    # degrees; may only narrow the firmware's ranges
    1 = [-90, 90]
    3 = [-30, 60]

Anything else (an unknown key or table, a range that is reversed, not two numbers, or wider
than the firmware's joint range) is a :class:`~mirobot_async.errors.MirobotUsageError` naming
the file and the key. The kinematic model is the firmware profile's (``DH_CLASSIC`` or
``DH_2021``). Reads the file with :mod:`tomllib`; no other I/O.
"""

from __future__ import annotations

import math
import os
import tomllib
from collections.abc import Mapping
from typing import Final

from mirobot_async._safety.envelope import Bound, Envelope
from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import DH, DH_2021, DH_CLASSIC

__all__ = ["ENVELOPE_KEYS", "describe_envelope", "load_envelope"]

ENVELOPE_KEYS: Final = ("box", "joints", "rail", "tool")
"""The top-level keys an envelope file may have."""
_BOX_KEYS: Final = ("x", "y", "z")
_JOINT_KEYS: Final = ("1", "2", "3", "4", "5", "6")
_MODELS: Final[Mapping[str, DH]] = {"classic": DH_CLASSIC, "2021": DH_2021, "2024": DH_2021}


def _number(value: object) -> float | None:
    """A TOML number as a float, None if it is not one (a bool is not a number)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)


def _range(value: object, where: str) -> Bound:
    """``[min, max]``: two numbers, min <= max; ``-inf`` / ``inf`` leave that side open."""
    if not isinstance(value, list) or len(value) != 2:
        raise MirobotUsageError(f"{where} = {value!r} must be [min, max], two numbers")
    low, high = _number(value[0]), _number(value[1])
    if low is None or high is None:
        raise MirobotUsageError(f"{where} = {value!r} must be [min, max], two numbers")
    if math.isnan(low) or math.isnan(high) or low == math.inf or high == -math.inf:
        raise MirobotUsageError(
            f"{where} = {value!r}: only the min may be -inf and only the max inf (an open side)"
        )
    if low > high:
        raise MirobotUsageError(f"{where} = {value!r}: min is above max (reversed range)")
    return (None if low == -math.inf else low, None if high == math.inf else high)


def _table(value: object, where: str, keys: tuple[str, ...]) -> dict[str, Bound]:
    if not isinstance(value, dict):
        raise MirobotUsageError(f"{where} = {value!r} must be a table ([{where}])")
    out: dict[str, Bound] = {}
    for key, item in value.items():
        if key not in keys:
            raise MirobotUsageError(f"{where}.{key}: unknown key (allowed: {', '.join(keys)})")
        out[key] = _range(item, f"{where}.{key}")
    return out


def _tool(value: object, where: str) -> tuple[float, float, float]:
    numbers = [_number(v) for v in value] if isinstance(value, list) else []
    if len(numbers) != 3 or any(n is None or not math.isfinite(n) for n in numbers):
        raise MirobotUsageError(f"{where} = {value!r} must be [x, y, z], three finite numbers (mm)")
    x, y, z = (float(n) for n in numbers if n is not None)
    return (x, y, z)


def load_envelope(path: str | os.PathLike[str], *, firmware: str = "classic") -> Envelope:
    """The :class:`Envelope` described by the TOML file at ``path``, on the kinematic model of
    the ``firmware`` profile (``"classic"`` or ``"2021"``). Raises MirobotUsageError naming the
    file (and the key) when it cannot be read or says anything else than an envelope."""
    name = os.fspath(path)
    model = _MODELS.get(firmware)
    if model is None:
        raise MirobotUsageError(
            f"firmware={firmware!r}: the envelope's model is 'classic' or '2021'"
        )
    try:
        with open(name, "rb") as file:
            data = tomllib.load(file)
    except OSError as err:
        raise MirobotUsageError(
            f"{name}: cannot read the envelope: {err.strerror or err}"
        ) from None
    except tomllib.TOMLDecodeError as err:
        raise MirobotUsageError(f"{name}: not a TOML file: {err}") from None
    except UnicodeDecodeError as err:
        raise MirobotUsageError(f"{name}: not a TOML file (not UTF-8): {err}") from None
    try:
        for key in data:
            if key not in ENVELOPE_KEYS:
                raise MirobotUsageError(
                    f"{key}: unknown key or table (allowed: {', '.join(ENVELOPE_KEYS)})"
                )
        box = _table(data.get("box", {}), "box", _BOX_KEYS)
        joints = _table(data.get("joints", {}), "joints", _JOINT_KEYS)
        rail = _range(data["rail"], "rail") if "rail" in data else None
        tool = _tool(data["tool"], "tool") if "tool" in data else (0.0, 0.0, 0.0)
        return Envelope(
            x=box.get("x"),
            y=box.get("y"),
            z=box.get("z"),
            joints={int(key): value for key, value in joints.items()} or None,
            rail=rail,
            dh=model,
            tool=tool,
        )
    except MirobotUsageError as err:
        raise MirobotUsageError(f"{name}: {err}") from None


def _side(value: float | None) -> str:
    return "open" if value is None else f"{value:g}"


def describe_envelope(envelope: Envelope) -> str:
    """The envelope in a few words, for messages: ``box x 100..280 mm, z 20..open mm; J1
    -90..90 deg`` (the joint ranges that differ from the firmware's)."""
    from mirobot_async.kinematics import JOINT_LIMITS

    parts = []
    for axis in _BOX_KEYS:
        bound = getattr(envelope, axis)
        if bound is not None and bound != (None, None):
            parts.append(f"{axis} {_side(bound[0])}..{_side(bound[1])} mm")
    text = "box " + ", ".join(parts) if parts else "no box"
    narrowed = [
        f"J{i + 1} {lo:g}..{hi:g} deg"
        for i, (lo, hi) in enumerate(envelope.joint_limits)
        if (lo, hi) != tuple(JOINT_LIMITS[i])
    ]
    if narrowed:
        text += "; " + ", ".join(narrowed)
    if envelope.rail is not None:
        text += f"; rail {_side(envelope.rail[0])}..{_side(envelope.rail[1])} mm"
    return text
