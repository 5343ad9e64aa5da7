"""Joint vectors, axis order and the per-axis limits of the virtual Mirobot's planner.

Everything here is in JOINT order (J1..J6 in degrees, then the rail D in mm); the firmware's
axis-letter order (a..g = J4, J5, J6, D, J1, J2, J3) only appears in
:meth:`AxisLimits.from_settings`, :func:`letters_to_joints` and :func:`joints_to_letters`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Final

AXES: Final = 7
"""J1..J6 (degrees) and the rail D (mm), in joint order."""

Vec7 = tuple[float, float, float, float, float, float, float]
Steps7 = tuple[int, int, int, int, int, int, int]

ZERO: Final[Vec7] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
_INF: Final = math.inf  # ``-_INF < x < _INF``: x is finite (False for NaN)

LETTER_TO_JOINT: Final[tuple[int, ...]] = (3, 4, 5, 6, 0, 1, 2)
"""Firmware axis letter a..g (settings ``$110 + k``, status angles) -> joint index."""

ARM_AXES: Final[tuple[int, ...]] = (0, 1, 2, 3, 4, 5)
RAIL: Final = 6

MIN_MAX_RATE: Final = 1.0
"""ASSUMED floor (deg/min) for a max-rate setting of 0 or less."""

MIN_ACCEL: Final = 1.0
"""ASSUMED floor (deg/s^2) for an acceleration setting of 0 or less."""

JUNCTION_DEVIATION_SETTING: Final = 11
STEPS_SETTING: Final = 100
MAX_RATE_SETTING: Final = 110
ACCEL_SETTING: Final = 120


def vec7(values: Iterable[float]) -> Vec7:
    """Seven floats as a :data:`Vec7` (``ValueError`` for any other count)."""
    if type(values) is tuple and len(values) == AXES:  # the common case, without a generator
        a, b, c, d, e, f, g = values
        if (type(a) is float and type(b) is float and type(c) is float and type(d) is float
                and type(e) is float and type(f) is float and type(g) is float):  # fmt: skip
            return values  # already seven floats (a tuple is immutable: the same value)
        return (float(a), float(b), float(c), float(d), float(e), float(f), float(g))
    v = tuple(float(x) for x in values)
    if len(v) != AXES:
        raise ValueError(f"expected {AXES} values (J1..J6, rail), got {len(v)}")
    return (v[0], v[1], v[2], v[3], v[4], v[5], v[6])


def finite_vec7(values: Iterable[float], what: str) -> Vec7:
    """:func:`vec7` that also refuses NaN and infinities, naming ``what`` in the error."""
    if type(values) is tuple and len(values) == AXES:  # seven finite floats: the same tuple
        a, b, c, d, e, f, g = values
        if (type(a) is float and type(b) is float and type(c) is float and type(d) is float
                and type(e) is float and type(f) is float and type(g) is float
                and -_INF < a < _INF and -_INF < b < _INF and -_INF < c < _INF
                and -_INF < d < _INF and -_INF < e < _INF and -_INF < f < _INF
                and -_INF < g < _INF):  # fmt: skip
            return values
    v = vec7(values)
    isfinite = math.isfinite
    if not (isfinite(v[0]) and isfinite(v[1]) and isfinite(v[2]) and isfinite(v[3])
            and isfinite(v[4]) and isfinite(v[5]) and isfinite(v[6])):  # fmt: skip
        raise ValueError(f"{what} must be finite, got {v}")
    return v


def sub(a: Vec7, b: Vec7) -> Vec7:
    """``a - b`` per axis."""
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3], a[4] - b[4], a[5] - b[5],
            a[6] - b[6])  # fmt: skip


def lerp(a: Vec7, d: Vec7, u: float) -> Vec7:
    """``a + d * u`` per axis."""
    return (a[0] + d[0] * u, a[1] + d[1] * u, a[2] + d[2] * u, a[3] + d[3] * u,
            a[4] + d[4] * u, a[5] + d[5] * u, a[6] + d[6] * u)  # fmt: skip


def norm(d: Sequence[float]) -> float:
    """Euclidean length (degrees and rail millimetres mixed, as GRBL mixes its axes)."""
    if len(d) == AXES:  # fsum is exactly rounded: the same sum as over a generator
        return math.sqrt(math.fsum((d[0] * d[0], d[1] * d[1], d[2] * d[2], d[3] * d[3],
                                    d[4] * d[4], d[5] * d[5], d[6] * d[6])))  # fmt: skip
    return math.sqrt(math.fsum(x * x for x in d))


def letters_to_joints(values: Sequence[float]) -> Vec7:
    """Firmware letter order (a..g = J4, J5, J6, D, J1, J2, J3) -> joint order (J1..J6, D)."""
    if len(values) != AXES:
        raise ValueError(f"expected {AXES} values, got {len(values)}")
    out = [0.0] * AXES
    for k, value in enumerate(values):
        out[LETTER_TO_JOINT[k]] = float(value)
    return vec7(out)


def joints_to_letters(q: Sequence[float]) -> Vec7:
    """Joint order (J1..J6, D) -> firmware letter order (J4, J5, J6, D, J1, J2, J3)."""
    if len(q) != AXES:
        raise ValueError(f"expected {AXES} values, got {len(q)}")
    return vec7(float(q[j]) for j in LETTER_TO_JOINT)


def round_half_away(x: float) -> int:
    """C's ``lround``: halves go away from zero (Python's ``round`` goes to even)."""
    return math.floor(x + 0.5) if x >= 0.0 else -math.floor(-x + 0.5)


@dataclass(frozen=True)
class AxisLimits:
    """Per-axis limits in JOINT order, and how the planner quantises and blends.

    ``max_rate``: deg/min (rail mm/min); ``accel``: deg/s^2; ``steps``: motor steps per degree
    (rail: per mm), or None for an ideal machine without steps; ``junction_deviation``: GRBL's
    ``$11`` in the same mixed units (0 = stop at every junction between blocks).
    """

    max_rate: Vec7
    accel: Vec7
    steps: Vec7 | None = None
    junction_deviation: float = 0.0

    def __post_init__(self) -> None:
        for name, values in (("max_rate", self.max_rate), ("accel", self.accel)):
            if len(values) != AXES or not all(math.isfinite(v) and v > 0 for v in values):
                raise ValueError(f"AxisLimits.{name} needs {AXES} finite positive values: {values}")
        if self.steps is not None and (
            len(self.steps) != AXES or not all(math.isfinite(v) and v > 0 for v in self.steps)
        ):
            raise ValueError(f"AxisLimits.steps needs {AXES} finite positive values: {self.steps}")
        jd = self.junction_deviation
        if not (math.isfinite(jd) and jd >= 0.0):
            raise ValueError(f"junction_deviation must be finite and >= 0: {jd}")

    @classmethod
    def from_settings(cls, settings: Mapping[int, float]) -> AxisLimits:
        """Build from the firmware settings ``$110..$116``, ``$120..$126`` (letter order) and,
        when present, ``$100..$106`` (steps per degree) and ``$11`` (junction deviation).

        Rates and accelerations <= 0 (or not finite) are clamped to ``MIN_MAX_RATE`` /
        ``MIN_ACCEL`` (ASSUMED). Steps settings that are missing or not all positive mean an
        ideal machine without steps; a missing ``$11`` means 0 (stop at every junction).
        """

        def clamp(value: float, floor: float) -> float:
            return float(value) if math.isfinite(value) and value >= floor else floor

        rates = [clamp(settings[MAX_RATE_SETTING + k], MIN_MAX_RATE) for k in range(AXES)]
        accels = [clamp(settings[ACCEL_SETTING + k], MIN_ACCEL) for k in range(AXES)]
        steps: Vec7 | None = None
        raw = [settings.get(STEPS_SETTING + k) for k in range(AXES)]
        if all(v is not None and math.isfinite(v) and v > 0 for v in raw):
            steps = letters_to_joints([float(v or 0.0) for v in raw])
        jd = float(settings.get(JUNCTION_DEVIATION_SETTING, 0.0))
        if not (math.isfinite(jd) and jd >= 0.0):
            jd = 0.0
        return cls(letters_to_joints(rates), letters_to_joints(accels), steps, jd)

    def to_steps(self, q: Sequence[float]) -> Steps7:
        """Whole motor steps nearest to the joint vector ``q`` (``ValueError`` without steps)."""
        if self.steps is None:
            raise ValueError("these limits have no steps per degree")
        return self._round_steps(q, self.steps)

    @staticmethod
    def _round_steps(q: Sequence[float], s: Vec7) -> Steps7:
        # round_half_away inlined (the hottest call of a joint line)
        floor = math.floor
        x0, x1, x2, x3, x4, x5, x6 = (q[0] * s[0], q[1] * s[1], q[2] * s[2], q[3] * s[3],
                                      q[4] * s[4], q[5] * s[5], q[6] * s[6])  # fmt: skip
        return (floor(x0 + 0.5) if x0 >= 0.0 else -floor(-x0 + 0.5),
                floor(x1 + 0.5) if x1 >= 0.0 else -floor(-x1 + 0.5),
                floor(x2 + 0.5) if x2 >= 0.0 else -floor(-x2 + 0.5),
                floor(x3 + 0.5) if x3 >= 0.0 else -floor(-x3 + 0.5),
                floor(x4 + 0.5) if x4 >= 0.0 else -floor(-x4 + 0.5),
                floor(x5 + 0.5) if x5 >= 0.0 else -floor(-x5 + 0.5),
                floor(x6 + 0.5) if x6 >= 0.0 else -floor(-x6 + 0.5))  # fmt: skip

    def from_steps(self, n: Sequence[int]) -> Vec7:
        """Degrees (rail mm) of the step counts ``n``."""
        if self.steps is None:
            raise ValueError("these limits have no steps per degree")
        s = self.steps
        return (n[0] / s[0], n[1] / s[1], n[2] / s[2], n[3] / s[3], n[4] / s[4], n[5] / s[5],
                n[6] / s[6])  # fmt: skip

    def quantise(self, q: Vec7) -> Vec7:
        """``q`` rounded to whole motor steps (unchanged for an ideal machine)."""
        if self.steps is None:
            return q
        return self.from_steps(self.to_steps(q))
