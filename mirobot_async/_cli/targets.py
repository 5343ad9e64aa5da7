"""KEY=VALUE targets of ``mirobot move``: ``j1=30 j2=-5`` or ``x=200 z=150``."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final

from mirobot_async._cli.exits import CliError

__all__ = ["JOINT_KEYS", "POSE_KEYS", "parse_assignments"]

JOINT_KEYS: Final = ("j1", "j2", "j3", "j4", "j5", "j6", "rail")
POSE_KEYS: Final = ("x", "y", "z", "rx", "ry", "rz")


def _parse_number(item: str, text: str) -> float:
    try:
        number = float(text)
    except ValueError:
        raise CliError(f"{item}: {text.strip()!r} is not a number") from None
    if not math.isfinite(number):
        raise CliError(f"{item}: the value must be a finite number")
    return number


_KEY_ALIASES: Final = {"d": "rail", "a": "rx", "b": "ry", "c": "rz"}


def parse_assignments(items: Sequence[str], keys: Sequence[str], what: str) -> dict[str, float]:
    """``["j1=10", "j3=-5.5"]`` -> ``{"j1": 10.0, "j3": -5.5}``; keys are case-insensitive.

    ``keys`` are the allowed names (plus the aliases ``d`` for ``rail`` and ``a``/``b``/``c`` for
    ``rx``/``ry``/``rz`` when those are allowed); ``what`` names them in messages ("joint").
    Raises :class:`CliError` for a malformed item, an unknown or repeated key, a value that is
    not a finite number, or no item at all. Ranges are checked by the
    :mod:`~mirobot_async._core.gcode` builders.
    """
    allowed = ", ".join(keys)
    example = f"{keys[0]}=10"
    if not items:
        raise CliError(f"give at least one {what} target as KEY=VALUE ({allowed}), e.g. {example}")
    values: dict[str, float] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip().lower()
        key = _KEY_ALIASES.get(key, key) if _KEY_ALIASES.get(key) in keys else key
        if not sep or not key:
            raise CliError(f"{item!r} is not KEY=VALUE (e.g. {example}); keys: {allowed}")
        if key not in keys:
            raise CliError(f"unknown {what} {key!r} in {item!r}: use {allowed}")
        if key in values:
            raise CliError(f"{key} is given twice")
        values[key] = _parse_number(item, text)
    return values
