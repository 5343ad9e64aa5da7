"""Pure motion model of the virtual Mirobot: an 18-block planner with trapezoidal timing.

No asyncio, no OS calls, no clock of its own: time only moves when the caller runs
:meth:`Planner.advance`. Everything here is in JOINT order (J1..J6 in degrees, then the rail D in
mm); the firmware's axis-letter order (a..g = J4, J5, J6, D, J1, J2, J3) only appears in
:meth:`AxisLimits.from_settings`, :func:`letters_to_joints` and :func:`joints_to_letters`.

The model (PROTOCOL.md section 9)
---------------------------------
* A :class:`Block` is a path parameterised by a coordinate ``s`` in ``[0, length]``
  (:meth:`Block.position_at` maps ``s`` to the joint vector) plus a 1-D velocity profile along
  ``s`` (:class:`Profile`): piecewise constant acceleration, trapezoidal (accelerate at ``accel``,
  cruise at ``speed``, decelerate at ``accel``) or triangular when the block is too short to reach
  ``speed``. From rest, the duration is::

      trapezoid (length >= speed**2 / accel):  T = length / speed + speed / accel
      triangle  (length <  speed**2 / accel):  T = 2 * sqrt(length / accel)

* :func:`joint_block` (``M21`` moves, ``M20 G0``, ``$M``): coordinated, linear in joint space, all
  axes start and stop together. ``s`` is the Euclidean norm of the joint-space displacement
  (degrees and rail millimetres mixed, as GRBL mixes its axes). With ``u_i = |delta_i| / length``::

      speed = min(F / 60, min_i (max_rate_i / 60) / u_i)    (F = None, i.e. G0: no F term)
      accel = min_i accel_i / u_i

  so the limiting axis runs exactly at its max rate / acceleration and no axis exceeds its own.
* :func:`path_block` (``M20 G1`` lines, 2021 ``G2/G3`` arcs): ``s`` is the tool's path length in mm
  and ``position_at(s)`` is ``poses(s / length)``, the caller's IK of the interpolated pose, so the
  reported pose stays exactly on the path. Speed: ``F / 60`` mm/s, reduced so that no joint exceeds
  its max rate at any of the sampled points (the joint rates are ``v * dq_i/ds``, ``dq_i/ds`` from
  finite differences between samples). **ASSUMED** Cartesian acceleration: the same scaling as a
  joint move, ``accel = min_i accel_i / max|dq_i/ds|`` (mm/s^2), so the tangential part of every
  joint's acceleration stays within its limit. The centripetal term ``v^2 d2q/ds2`` is ignored.
* :func:`dwell_block` (``G4 P``) and the homing search are *timed* blocks: ``s`` is seconds,
  constant rate 1, no acceleration.
* :func:`homing_blocks`: ``home_search`` block(s) (state ``Home``) then a ``home_pulloff`` joint
  move (state ``Run``) to the calibrated zero at G0 rates.
* :class:`Planner`: 18 slots (the running block included), blocks run in order, each from rest to
  rest. Feed hold, resume, abort (soft reset), all with explicit time.

**ASSUMED** points this module implements (each lives in one named constant or function)
--------------------------------------------------------------------------------------------
* Every block starts and ends at rest (PROTOCOL 9): no junction speeds between blocks.
* Cartesian acceleration of ``path_block`` derived from the joint accelerations (above).
* A Cartesian block with zero tool travel (pure re-orientation, ``M20 G1 A10``) is timed along the
  joint-space path instead: ``s`` = joint-space distance, ``F`` read as deg/min.
* ``G4`` dwell reports ``Run`` (the planner is busy), and a feed hold pauses the dwell timer.
* Homing: the reported joints stay where they were during the switch search (the firmware does
  not track its position while seeking); ``$H`` searches all axes at once for ``search_seconds``;
  ``$HH`` searches J1..J5 one after another (2021 manual), each for
  ``SEQUENTIAL_SEARCH_FRACTION * search_seconds`` (so 2.5x as long as ``$H``); the pull-off then
  moves the homed axes (J1..J6) to 0 at G0 rates; the rail keeps its position unless asked
  (2021 ``$H7``). Feed hold is ignored during homing (as GRBL ignores it in its homing
  cycle).
* Feed hold shows ``Hold`` at once, while still decelerating (GRBL 0.9 does the same); ``~`` while
  still decelerating re-accelerates from the current speed. A hold with an empty planner is
  ignored; a hold that decelerates exactly onto the end of the last block ends in ``idle``.
* Settings of 0 (or less) for a max rate or an acceleration are clamped to
  ``MIN_MAX_RATE`` / ``MIN_ACCEL`` by :meth:`AxisLimits.from_settings` (GRBL would divide by 0).

Not modelled
------------
GRBL's look-ahead (junction deviation, blending consecutive blocks without stopping), step
quantisation (the real arm reports angles rounded to motor steps, PROTOCOL 8.4), the stepper
segment buffer and AMASS, jerk, the centripetal joint acceleration on curved joint paths, the
``$36`` point count of the real firmware's line interpolation (here the pose is exact at every
instant), lost steps / stalls, motor load, homing switch physics and feed overrides. Limits
(soft/hard) and IK reachability are the firmware's business, not this module's.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import ClassVar, Final

__all__ = [
    "ARM_AXES",
    "AXES",
    "LETTER_TO_JOINT",
    "RAIL",
    "SEQUENTIAL_SEARCH_FRACTION",
    "ZERO",
    "AxisLimits",
    "Block",
    "DwellBlock",
    "HomeSearchBlock",
    "JointBlock",
    "PathBlock",
    "Planner",
    "PlannerFull",
    "Profile",
    "Vec7",
    "dwell_block",
    "homing_blocks",
    "joint_block",
    "joints_to_letters",
    "letters_to_joints",
    "path_block",
]

AXES: Final = 7
"""J1..J6 (degrees) and the rail D (mm), in joint order."""

Vec7 = tuple[float, float, float, float, float, float, float]

ZERO: Final[Vec7] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

LETTER_TO_JOINT: Final[tuple[int, ...]] = (3, 4, 5, 6, 0, 1, 2)
"""Firmware axis letter a..g (settings ``$110 + k``, status angles) -> joint index."""

SNAP_SECONDS: Final = 1e-9
"""A block whose remaining time is below this is finished (float error never runs forever)."""

SNAP_FRACTION: Final = 1e-9
"""A feed hold whose stopping distance reaches this close to the block's end stops on the end."""

START_TOLERANCE: Final = 1e-6
"""Largest per-axis gap allowed between a pushed block's start and the planner's planned end."""

PATH_START_TOLERANCE: Final = 1e-3
"""Largest per-axis gap allowed between ``poses(0)`` and the ``start`` given to path_block."""

MIN_MAX_RATE: Final = 1.0
"""ASSUMED floor (deg/min) for a max-rate setting of 0 or less."""

MIN_ACCEL: Final = 1.0
"""ASSUMED floor (deg/s^2) for an acceleration setting of 0 or less."""

DEFAULT_PATH_STEP_MM: Final = 2.0
"""path_block samples the path every this many mm (PROTOCOL 9) when ``samples`` is not given."""

MIN_PATH_SAMPLES: Final = 8
MAX_PATH_SAMPLES: Final = 1000

ARM_AXES: Final[tuple[int, ...]] = (0, 1, 2, 3, 4, 5)
RAIL: Final = 6

SEQUENTIAL_ORDER: Final[tuple[tuple[int, ...], ...]] = ((0,), (1,), (2,), (3,), (4,))
"""``$HH``: J1..J5 one after another (2021 manual, 2.1.1)."""

SEQUENTIAL_SEARCH_FRACTION: Final = 0.5
"""ASSUMED: one group of a sequential homing searches for this fraction of ``search_seconds``."""

HOLDABLE_KINDS: Final = frozenset({"move", "line", "arc", "dwell"})
"""Blocks a feed hold acts on (homing ignores it)."""


# --------------------------------------------------------------------------------------------
# Vectors and limits


def _vec7(values: Iterable[float]) -> Vec7:
    v = tuple(float(x) for x in values)
    if len(v) != AXES:
        raise ValueError(f"expected {AXES} values (J1..J6, rail), got {len(v)}")
    return (v[0], v[1], v[2], v[3], v[4], v[5], v[6])


def _finite_vec7(values: Iterable[float], what: str) -> Vec7:
    v = _vec7(values)
    if not all(math.isfinite(x) for x in v):
        raise ValueError(f"{what} must be finite, got {v}")
    return v


def letters_to_joints(values: Sequence[float]) -> Vec7:
    """Firmware letter order (a..g = J4, J5, J6, D, J1, J2, J3) -> joint order (J1..J6, D)."""
    if len(values) != AXES:
        raise ValueError(f"expected {AXES} values, got {len(values)}")
    out = [0.0] * AXES
    for k, value in enumerate(values):
        out[LETTER_TO_JOINT[k]] = float(value)
    return _vec7(out)


def joints_to_letters(q: Sequence[float]) -> Vec7:
    """Joint order (J1..J6, D) -> firmware letter order (J4, J5, J6, D, J1, J2, J3)."""
    if len(q) != AXES:
        raise ValueError(f"expected {AXES} values, got {len(q)}")
    return _vec7(float(q[j]) for j in LETTER_TO_JOINT)


@dataclass(frozen=True)
class AxisLimits:
    """Per-axis limits in JOINT order. ``max_rate``: deg/min (rail mm/min); ``accel``: deg/s^2."""

    max_rate: Vec7
    accel: Vec7

    def __post_init__(self) -> None:
        for name, values in (("max_rate", self.max_rate), ("accel", self.accel)):
            if len(values) != AXES or not all(math.isfinite(v) and v > 0 for v in values):
                raise ValueError(f"AxisLimits.{name} needs {AXES} finite positive values: {values}")

    @classmethod
    def from_settings(cls, settings: Mapping[int, float]) -> AxisLimits:
        """Build from the firmware settings ``$110..$116`` and ``$120..$126`` (letter order).

        Values <= 0 (or not finite) are clamped to ``MIN_MAX_RATE`` / ``MIN_ACCEL`` (ASSUMED).
        """

        def clamp(value: float, floor: float) -> float:
            return float(value) if math.isfinite(value) and value >= floor else floor

        rates = [clamp(settings[110 + k], MIN_MAX_RATE) for k in range(AXES)]
        accels = [clamp(settings[120 + k], MIN_ACCEL) for k in range(AXES)]
        return cls(letters_to_joints(rates), letters_to_joints(accels))


# --------------------------------------------------------------------------------------------
# 1-D velocity profiles


class Profile:
    """Path coordinate ``s(t)`` for ``t`` in ``[0, duration]``: piecewise constant acceleration.

    Starts at ``s_start`` with speed ``v_start`` and ends at ``s_end`` (exactly) at rest, except
    for the constant-rate profile of timed blocks, which ends at rate 1.
    """

    __slots__ = ("_phases", "duration", "s_end", "s_start", "v_start")

    def __init__(
        self, s_start: float, v_start: float, phases: Sequence[tuple[float, float]], s_end: float
    ) -> None:
        """``phases``: ``(duration, acceleration)`` pairs, in order."""
        self.s_start = s_start
        self.v_start = v_start
        self.s_end = s_end
        table: list[tuple[float, float, float, float]] = []  # (t0, s0, v0, a)
        t, s, v = 0.0, s_start, v_start
        for dt, a in phases:
            if dt <= 0.0:
                continue
            table.append((t, s, v, a))
            t += dt
            s += v * dt + 0.5 * a * dt * dt
            v += a * dt
        self._phases: tuple[tuple[float, float, float, float], ...] = tuple(reversed(table))
        self.duration = t

    def _phase(self, t: float) -> tuple[float, float, float, float]:
        for phase in self._phases:
            if t >= phase[0]:
                return phase
        return self._phases[-1]

    def s_at(self, t: float) -> float:
        """The path coordinate at time ``t`` (clamped to the profile)."""
        if t >= self.duration:
            return self.s_end
        if t <= 0.0:
            return self.s_start
        t0, s0, v0, a = self._phase(t)
        dt = t - t0
        s = s0 + v0 * dt + 0.5 * a * dt * dt
        return self.s_end if s > self.s_end else s

    def v_at(self, t: float) -> float:
        """The speed along ``s`` at time ``t`` (0 after the end, except for timed profiles)."""
        if not self._phases:
            return 0.0
        if t >= self.duration:
            t0, _s0, v0, a = self._phases[0]
            return max(v0 + a * (self.duration - t0), 0.0)
        if t <= 0.0:
            return self.v_start
        t0, _s0, v0, a = self._phase(t)
        return max(v0 + a * (t - t0), 0.0)


def _move_profile(s0: float, s_end: float, v0: float, vmax: float, accel: float) -> Profile:
    """From ``s0`` at speed ``v0`` to rest at ``s_end``: trapezoid or triangle."""
    d = s_end - s0
    if d <= 0.0:
        return Profile(s0, 0.0, (), max(s0, s_end))
    if v0 <= 0.0:
        v0 = 0.0
    stop = v0 * v0 / (2.0 * accel)
    if stop >= d:
        # Only reachable through float error (a resume during the final deceleration): brake a
        # hair harder so that the block still ends exactly at its end.
        dec = v0 * v0 / (2.0 * d)
        return Profile(s0, v0, ((v0 / dec, -dec),), s_end)
    peak = max(min(vmax, math.sqrt(accel * d + 0.5 * v0 * v0)), v0)
    d_acc = (peak * peak - v0 * v0) / (2.0 * accel)
    d_dec = peak * peak / (2.0 * accel)
    d_cruise = max(d - d_acc - d_dec, 0.0)
    return Profile(
        s0,
        v0,
        (((peak - v0) / accel, accel), (d_cruise / peak, 0.0), (peak / accel, -accel)),
        s_end,
    )


def _stop_profile(s0: float, v0: float, accel: float, s_limit: float) -> Profile:
    """Decelerate from ``v0`` at ``accel`` to rest, never beyond ``s_limit``."""
    if v0 <= 0.0 or s0 >= s_limit:
        return Profile(s0, 0.0, (), min(s0, s_limit))
    d = v0 * v0 / (2.0 * accel)
    room = s_limit - s0
    if d >= room - SNAP_FRACTION * max(1.0, s_limit):
        dec = v0 * v0 / (2.0 * room)
        return Profile(s0, v0, ((v0 / dec, -dec),), s_limit)
    return Profile(s0, v0, ((v0 / accel, -accel),), s0 + d)


# --------------------------------------------------------------------------------------------
# Blocks


class Block:
    """One planner block: a path ``position_at(s)``, ``s`` in ``[0, length]``, and its timing.

    ``speed`` (units of s per second) and ``accel`` (per s^2) are the nominal cruise speed and
    acceleration; ``profile`` is the nominal from-rest profile and ``duration`` its total time.
    """

    __slots__ = ("accel", "end", "kind", "length", "profile", "speed", "start", "timed")

    timed: bool

    def __init__(
        self,
        kind: str,
        start: Vec7,
        end: Vec7,
        length: float,
        speed: float,
        accel: float,
        *,
        timed: bool = False,
    ) -> None:
        if not (math.isfinite(length) and length >= 0.0):
            raise ValueError(f"block length must be finite and >= 0, got {length}")
        if not (speed > 0.0 and accel > 0.0 and math.isfinite(speed)):
            raise ValueError(f"block speed/accel must be positive, got {speed}, {accel}")
        self.kind = kind
        self.start = start
        self.end = end
        self.length = length
        self.speed = speed
        self.accel = accel
        self.timed = timed
        self.profile = self.profile_from(0.0)

    @property
    def duration(self) -> float:
        """Total time of the nominal (from rest) profile, seconds."""
        return self.profile.duration

    def position_at(self, s: float) -> Vec7:
        """Joint vector at path coordinate ``s`` (clamped to ``[0, length]``)."""
        raise NotImplementedError

    def s_at(self, t: float) -> float:
        """Path coordinate ``t`` seconds after the block started (nominal profile)."""
        return self.profile.s_at(t)

    def position_at_time(self, t: float) -> Vec7:
        """Joint vector ``t`` seconds after the block started (nominal profile)."""
        return self.position_at(self.profile.s_at(t))

    def profile_from(self, s: float, v: float = 0.0) -> Profile:
        """A profile covering ``[s, length]`` that starts at speed ``v`` and ends at rest."""
        s = min(max(s, 0.0), self.length)
        if self.timed:
            return Profile(s, 1.0, ((self.length - s, 0.0),), self.length)
        return _move_profile(s, self.length, min(v, self.speed), self.speed, self.accel)

    def stop_profile(self, s: float, v: float) -> Profile:
        """Feed hold: from ``s`` at speed ``v`` to rest at ``accel`` (timed blocks stop at once)."""
        s = min(max(s, 0.0), self.length)
        if self.timed:
            return Profile(s, 0.0, (), s)
        return _stop_profile(s, v, self.accel, self.length)

    def __repr__(self) -> str:
        return (
            f"<{type(self).__name__} {self.kind} length={self.length:.6g} "
            f"duration={self.duration:.6g}s end={self.end}>"
        )


def _lerp(a: Vec7, d: Vec7, u: float) -> Vec7:
    return (
        a[0] + d[0] * u,
        a[1] + d[1] * u,
        a[2] + d[2] * u,
        a[3] + d[3] * u,
        a[4] + d[4] * u,
        a[5] + d[5] * u,
        a[6] + d[6] * u,
    )


def _sub(a: Vec7, b: Vec7) -> Vec7:
    return (
        a[0] - b[0],
        a[1] - b[1],
        a[2] - b[2],
        a[3] - b[3],
        a[4] - b[4],
        a[5] - b[5],
        a[6] - b[6],
    )


class JointBlock(Block):
    """Straight line in joint space from ``start`` to ``end``; ``s`` = joint-space distance."""

    __slots__ = ("_delta",)

    def __init__(
        self, kind: str, start: Vec7, end: Vec7, length: float, speed: float, accel: float
    ) -> None:
        self._delta = _sub(end, start)
        super().__init__(kind, start, end, length, speed, accel)

    def position_at(self, s: float) -> Vec7:
        if s <= 0.0:
            return self.start
        if s >= self.length:
            return self.end
        return _lerp(self.start, self._delta, s / self.length)


class PathBlock(Block):
    """A Cartesian path: ``position_at(s) = poses(s / length)``.

    If ``poses`` raises ``ValueError`` between two samples (the path grazes the workspace
    boundary between them), the joints are interpolated linearly between the two samples instead.
    """

    __slots__ = ("_cache_q", "_cache_s", "_poses", "samples")

    def __init__(
        self,
        kind: str,
        start: Vec7,
        end: Vec7,
        length: float,
        speed: float,
        accel: float,
        poses: Callable[[float], Vec7],
        samples: Sequence[Vec7],
    ) -> None:
        self._poses = poses
        self.samples: tuple[Vec7, ...] = tuple(samples)
        self._cache_s = 0.0
        self._cache_q = start
        super().__init__(kind, start, end, length, speed, accel)

    def position_at(self, s: float) -> Vec7:
        if s <= 0.0:
            return self.start
        if s >= self.length:
            return self.end
        if s == self._cache_s:
            return self._cache_q
        u = s / self.length
        try:
            q = _vec7(self._poses(u))
        except ValueError:
            n = len(self.samples) - 1
            k = min(int(u * n), n - 1)
            a = self.samples[k]
            q = _lerp(a, _sub(self.samples[k + 1], a), u * n - k)
        self._cache_s, self._cache_q = s, q
        return q


class DwellBlock(Block):
    """``G4 P``: stays at ``start`` for ``length`` seconds (``s`` is time)."""

    __slots__ = ()

    def __init__(self, kind: str, at: Vec7, seconds: float) -> None:
        super().__init__(kind, at, at, seconds, 1.0, math.inf, timed=True)

    def position_at(self, s: float) -> Vec7:
        return self.start


class HomeSearchBlock(DwellBlock):
    """Limit-switch search of homing (state ``Home``); ``axes`` are the joints being searched."""

    __slots__ = ("axes",)

    def __init__(self, at: Vec7, seconds: float, axes: Sequence[int]) -> None:
        self.axes: tuple[int, ...] = tuple(axes)
        super().__init__("home_search", at, seconds)


# --------------------------------------------------------------------------------------------
# Block builders


def _joint(start: Vec7, end: Vec7, feed: float | None, limits: AxisLimits, kind: str) -> JointBlock:
    start = _finite_vec7(start, "start")
    end = _finite_vec7(end, "end")
    if feed is not None and not (math.isfinite(feed) and feed > 0.0):
        raise ValueError(f"feed must be a positive number of deg/min (or None for G0): {feed}")
    delta = _sub(end, start)
    length = math.sqrt(math.fsum(x * x for x in delta))
    if length == 0.0:
        return JointBlock(kind, start, end, 0.0, 1.0, 1.0)
    speed = math.inf if feed is None else feed / 60.0
    accel = math.inf
    for i, di in enumerate(delta):
        share = abs(di) / length
        if share > 0.0:
            speed = min(speed, limits.max_rate[i] / 60.0 / share)
            accel = min(accel, limits.accel[i] / share)
    return JointBlock(kind, start, end, length, speed, accel)


def joint_block(start: Vec7, end: Vec7, feed: float | None, limits: AxisLimits) -> Block:
    """Coordinated joint move (kind ``"move"``).

    ``feed``: deg/min along the joint-space vector (Euclidean norm of the displacement), reduced
    so that no axis exceeds its max rate; ``None`` (G0) = the highest speed within every max rate.
    The acceleration is scaled the same way from the per-axis accelerations.
    """
    return _joint(start, end, feed, limits, "move")


def _path_samples(length: float) -> int:
    n = math.ceil(length / DEFAULT_PATH_STEP_MM)
    return min(max(n, MIN_PATH_SAMPLES), MAX_PATH_SAMPLES)


def path_block(
    start: Vec7,
    poses: Callable[[float], Vec7],
    length_mm: float,
    feed_mm_min: float,
    limits: AxisLimits,
    kind: str = "line",
    samples: int | None = None,
) -> Block:
    """Cartesian line or arc: ``poses(u)``, ``u`` in [0, 1], is the JOINT vector at fraction u.

    The tool moves at ``feed_mm_min`` along the path, reduced so that no joint exceeds its max
    rate at any of the ``samples + 1`` sampled points (default: one sample every
    ``DEFAULT_PATH_STEP_MM`` mm, between ``MIN_PATH_SAMPLES`` and ``MAX_PATH_SAMPLES``).
    Acceleration (ASSUMED): ``min_i accel_i / max|dq_i/ds|`` mm/s^2.

    ``poses`` is called ``samples + 1`` times here (a ``ValueError`` from it, e.g. an
    unreachable sample, propagates: refuse the line before any motion) and then once per
    :meth:`Block.position_at`. ``poses(0)`` must agree with ``start`` within
    ``PATH_START_TOLERANCE`` (else ``ValueError``); the block ends exactly at ``poses(1)``.
    With ``length_mm == 0`` (pure re-orientation) the block is timed along the joint-space path,
    ``feed_mm_min`` read as deg/min (ASSUMED).
    """
    start = _finite_vec7(start, "start")
    if not (math.isfinite(length_mm) and length_mm >= 0.0):
        raise ValueError(f"path length must be finite and >= 0: {length_mm}")
    if not (math.isfinite(feed_mm_min) and feed_mm_min > 0.0):
        raise ValueError(f"feed must be a positive number of mm/min: {feed_mm_min}")
    n = _path_samples(length_mm) if samples is None else int(samples)
    if n < 1:
        raise ValueError(f"samples must be >= 1: {samples}")
    qs = [_finite_vec7(poses(k / n), "poses(u)") for k in range(n + 1)]
    gap = max(abs(a - b) for a, b in zip(qs[0], start, strict=True))
    if gap > PATH_START_TOLERANCE:
        raise ValueError(f"poses(0) = {qs[0]} is not the start {start} (gap {gap:.6g})")
    qs[0] = start
    end = qs[-1]
    length = length_mm
    if length == 0.0:
        length = math.fsum(
            math.sqrt(math.fsum(x * x for x in _sub(b, a))) for a, b in itertools.pairwise(qs)
        )
        if length == 0.0:
            return PathBlock(kind, start, end, 0.0, 1.0, 1.0, poses, qs)
    ds = length / n
    slope = [0.0] * AXES  # max |dq_i/ds| over the samples
    for a, b in itertools.pairwise(qs):
        for i in range(AXES):
            rate = abs(b[i] - a[i]) / ds
            if rate > slope[i]:
                slope[i] = rate
    speed = feed_mm_min / 60.0
    accel = math.inf
    for i in range(AXES):
        if slope[i] > 0.0:
            speed = min(speed, limits.max_rate[i] / 60.0 / slope[i])
            accel = min(accel, limits.accel[i] / slope[i])
    if math.isinf(accel):  # no joint moves at all: nothing limits the tool; use the gentlest axis
        accel = min(limits.accel)
    return PathBlock(kind, start, end, length, speed, accel, poses, qs)


def dwell_block(seconds: float, at: Vec7) -> Block:
    """``G4 P<seconds>``: occupies the planner for ``seconds`` without moving (state Run)."""
    if not (math.isfinite(seconds) and seconds >= 0.0):
        raise ValueError(f"dwell must be a finite number of seconds >= 0: {seconds}")
    return DwellBlock("dwell", _finite_vec7(at, "at"), seconds)


def homing_blocks(
    start: Vec7,
    search_seconds: float,
    limits: AxisLimits,
    sequential: bool,
    *,
    order: Sequence[Sequence[int]] | None = None,
    axes: Sequence[int] = ARM_AXES,
    home_rail: bool = False,
) -> list[Block]:
    """Homing: ``home_search`` block(s) (state Home, joints stay) then ``home_pulloff`` (Run).

    ``$H``: ``sequential=False``, one search of ``search_seconds`` for all axes at once.
    ``$HH``: ``sequential=True``, one search per group of ``order`` (default J1..J5, one axis at a
    time), each ``SEQUENTIAL_SEARCH_FRACTION * search_seconds`` long (ASSUMED). Other 2021
    variants (2021 manual 2.1.1): ``$HE`` (J2, J3 first, then J1, J4, J5) =
    ``sequential=True, order=((1, 2), (0, 3, 4))``; ``$H7`` (arm at once, then the rail) =
    ``sequential=True, order=(ARM_AXES, (RAIL,)), home_rail=True``; a single axis ``k``
    (if the firmware has it) = ``sequential=False, axes=(k - 1,)``. Without ``home_rail`` (or
    ``RAIL`` in ``axes``) the rail keeps its position.
    The pull-off is a G0 joint move of ``axes`` (default J1..J6) and, with ``home_rail``, the rail
    to 0. Push the returned blocks in order (they need ``len(result)`` free slots).
    """
    start = _finite_vec7(start, "start")
    if not (math.isfinite(search_seconds) and search_seconds >= 0.0):
        raise ValueError(f"search_seconds must be finite and >= 0: {search_seconds}")
    homed = {int(i) for i in axes}
    if home_rail:
        homed.add(RAIL)
    if not homed <= set(range(AXES)):
        raise ValueError(f"axes must be joint indices 0..6: {sorted(homed)}")
    blocks: list[Block] = []
    if sequential:
        groups = SEQUENTIAL_ORDER if order is None else tuple(tuple(g) for g in order)
        for group in groups:
            seconds = search_seconds * SEQUENTIAL_SEARCH_FRACTION
            blocks.append(HomeSearchBlock(start, seconds, group))
    else:
        blocks.append(HomeSearchBlock(start, search_seconds, sorted(homed)))
    target = _vec7(0.0 if i in homed else start[i] for i in range(AXES))
    blocks.append(_joint(start, target, None, limits, "home_pulloff"))
    return blocks


# --------------------------------------------------------------------------------------------
# Planner


class PlannerFull(RuntimeError):
    """push() on a planner with no free slot."""


_STOPPED: Final = Profile(0.0, 0.0, (), 0.0)


class Planner:
    """The 18-block planner with an explicit clock.

    Blocks run in order, each from rest to rest. ``state`` is ``"idle"`` (nothing queued),
    ``"home"`` (a ``home_search`` block runs), ``"hold"`` (a feed hold is in effect, from the
    moment it is requested) or ``"run"``.
    """

    CAPACITY: ClassVar[int] = 18

    def __init__(self, position: Vec7) -> None:
        self._position = _finite_vec7(position, "position")
        self._queue: deque[Block] = deque()
        self._profile: Profile = _STOPPED  # profile of the running block (queue head)
        self._t = 0.0  # time since _profile started
        self._held = False

    # ---- queries ---------------------------------------------------------------------------

    @property
    def running(self) -> Block | None:
        """The block at the head of the queue (running, or stopped by a hold)."""
        return self._queue[0] if self._queue else None

    @property
    def blocks(self) -> tuple[Block, ...]:
        """Every queued block, the running one first."""
        return tuple(self._queue)

    @property
    def busy(self) -> bool:
        return bool(self._queue)

    @property
    def free(self) -> int:
        return self.CAPACITY - len(self._queue)

    @property
    def held(self) -> bool:
        return self._held

    @property
    def state(self) -> str:
        if not self._queue:
            return "idle"
        if self._held:
            return "hold"
        if self._queue[0].kind == "home_search":
            return "home"
        return "run"

    @property
    def progress(self) -> float:
        """Path coordinate ``s`` of the running block (0 when idle)."""
        return self._profile.s_at(self._t) if self._queue else 0.0

    @property
    def speed(self) -> float:
        """Current speed along the running block's ``s`` (0 when idle or stopped)."""
        if not self._queue or self._queue[0].timed:
            return 0.0
        return self._profile.v_at(self._t)

    @property
    def position(self) -> Vec7:
        """Current interpolated joint position (J1..J6, rail)."""
        if not self._queue:
            return self._position
        return self._queue[0].position_at(self._profile.s_at(self._t))

    @property
    def planned_position(self) -> Vec7:
        """End of the last queued block: where the next pushed block must start."""
        return self._queue[-1].end if self._queue else self._position

    def estimated_duration(self, block: Block) -> float:
        """Total time of ``block``'s from-rest profile (same as ``block.duration``)."""
        return block.duration

    def time_to_next_change(self) -> float | None:
        """Seconds until the running block ends or a hold finishes decelerating.

        None when idle, and when stopped by a hold (nothing changes until :meth:`resume`).
        """
        if not self._queue:
            return None
        left = max(self._profile.duration - self._t, 0.0)
        if self._held and left <= SNAP_SECONDS:
            return 0.0 if self._profile.s_end >= self._queue[0].length else None
        return left

    def remaining_time(self) -> float:
        """Seconds until the planner is empty if nothing intervenes (``inf`` while held)."""
        if not self._queue:
            return 0.0
        if self._held:
            return math.inf
        rest = max(self._profile.duration - self._t, 0.0)
        return rest + math.fsum(b.duration for b in list(self._queue)[1:])

    # ---- commands --------------------------------------------------------------------------

    def push(self, block: Block) -> None:
        """Queue ``block`` (it starts at once if the planner is idle).

        Raises :class:`PlannerFull` without a free slot, ``ValueError`` if the block does not
        start at :attr:`planned_position` (within ``START_TOLERANCE`` per axis).
        """
        if len(self._queue) >= self.CAPACITY:
            raise PlannerFull(f"planner full ({self.CAPACITY} blocks)")
        planned = self.planned_position
        gap = max(abs(a - b) for a, b in zip(block.start, planned, strict=True))
        if not gap <= START_TOLERANCE:
            raise ValueError(f"block starts at {block.start}, planner ends at {planned}")
        self._queue.append(block)
        if len(self._queue) == 1:
            self._profile = block.profile
            self._t = 0.0

    def advance(self, dt: float) -> None:
        """Move time forward by ``dt`` seconds (``math.inf``: run everything that can run)."""
        if not dt >= 0.0:
            raise ValueError(f"dt must be >= 0, got {dt}")
        remaining = dt
        while self._queue:
            profile = self._profile
            left = profile.duration - self._t
            if remaining < left - SNAP_SECONDS:
                self._t += remaining
                return
            remaining = max(remaining - left, 0.0)
            self._t = profile.duration
            if self._held:
                if profile.s_end < self._queue[0].length:
                    return  # stopped mid-block, waiting for resume()
                self._finish_head()
                if not self._queue:
                    self._held = False  # nothing left to hold
                else:
                    self._profile = _STOPPED
                continue
            self._finish_head()

    def hold(self) -> None:
        """Feed hold ``!``: decelerate the running block to a stop (state ``hold`` at once).

        Ignored when idle, already held, or homing.
        """
        if not self._queue or self._held or self._queue[0].kind not in HOLDABLE_KINDS:
            return
        block = self._queue[0]
        s = self._profile.s_at(self._t)
        v = self._profile.v_at(self._t)
        self._profile = block.stop_profile(s, v)
        self._t = 0.0
        self._held = True

    def resume(self) -> None:
        """Cycle start ``~``: continue the remaining path of the running block (fresh trapezoid
        from the current speed, i.e. from rest once stopped). Ignored when not held."""
        if not self._held:
            return
        self._held = False
        if not self._queue:
            return
        block = self._queue[0]
        if self._profile is _STOPPED:  # held before this block started
            self._profile = block.profile
        else:
            s = self._profile.s_at(self._t)
            v = self._profile.v_at(self._t)
            self._profile = block.profile_from(s, v)
        self._t = 0.0

    def abort(self) -> None:
        """Soft reset: stop at once where the arm is, clear every block and the hold."""
        self._position = self.position
        self._queue.clear()
        self._profile = _STOPPED
        self._t = 0.0
        self._held = False

    def set_position(self, p: Vec7) -> None:
        """Redefine the current position (only while idle; ``RuntimeError`` otherwise)."""
        if self._queue:
            raise RuntimeError("set_position() while blocks are queued")
        self._position = _finite_vec7(p, "position")

    # ---- internals -------------------------------------------------------------------------

    def _finish_head(self) -> None:
        block = self._queue.popleft()
        self._position = block.end
        self._t = 0.0
        self._profile = self._queue[0].profile if self._queue else _STOPPED
