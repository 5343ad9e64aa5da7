"""Planner blocks: a path ``position_at(s)``, ``s`` in ``[0, length]``, and its nominal timing.

* :class:`JointBlock`: a straight line in joint space; ``s`` is the joint-space distance
  (degrees and rail millimetres mixed, as GRBL mixes its axes). With motor steps
  (:attr:`AxisLimits.steps`) its ends are whole steps and its positions are the step counts of
  GRBL's Bresenham line: the dominant axis has made ``floor(N * s / length)`` of its ``N``
  steps and every other axis its proportional share, rounded.
* :class:`PathBlock`: a Cartesian path in one block, ``s`` in mm of tool travel.
* :class:`DwellBlock` / :class:`HomeSearchBlock`: timed blocks, ``s`` is seconds.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from math import copysign

from ._axes import AXES, AxisLimits, Steps7, Vec7, lerp, sub, vec7
from ._profile import Profile, braking, constant_rate, trapezoid


class Block:
    """One planner block: a path ``position_at(s)``, ``s`` in ``[0, length]``, and its timing.

    ``speed`` (units of s per second) and ``accel`` (per s^2) are the nominal cruise speed and
    acceleration; ``profile`` is the nominal from-rest profile and ``duration`` its total time.
    ``direction_in`` / ``direction_out`` are the joint-space unit vectors at the two ends of a
    block that can blend with its neighbours (None: the planner stops before and after it);
    ``junction_deviation`` is the ``$11`` the block was planned with.
    """

    __slots__ = (
        "accel",
        "direction_in",
        "direction_out",
        "end",
        "junction_deviation",
        "kind",
        "length",
        "profile",
        "speed",
        "start",
        "timed",
    )

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
        self.direction_in: Vec7 | None = None
        self.direction_out: Vec7 | None = None
        self.junction_deviation = 0.0
        if timed:
            self.profile = self._profile_from(0.0, 0.0, 0.0)
        else:  # = self._profile_from(0.0, 0.0, 0.0): s = 0.0, v = min(0.0, speed) = 0.0
            self.profile = trapezoid(0.0, length, 0.0, 0.0, speed, accel)

    @property
    def duration(self) -> float:
        """Total time of the nominal (from rest to rest) profile, seconds."""
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

    def profile_from(self, s: float, v: float = 0.0, v_out: float = 0.0) -> Profile:
        """A profile covering ``[s, length]`` that starts at speed ``v`` and ends at ``v_out``."""
        if (
            s == 0.0
            and v == 0.0
            and v_out == 0.0
            and copysign(1.0, s) + copysign(1.0, v) + copysign(1.0, v_out) == 3.0
        ):
            return self.profile  # from rest to rest: the nominal profile (profiles are immutable)
        return self._profile_from(s, v, v_out)

    def _profile_from(self, s: float, v: float, v_out: float) -> Profile:
        s = min(max(s, 0.0), self.length)
        if self.timed:
            return constant_rate(s, self.length)
        return trapezoid(s, self.length, min(v, self.speed), v_out, self.speed, self.accel)

    def stop_profile(self, s: float, v: float) -> Profile:
        """Feed hold: from ``s`` at speed ``v``, decelerate at ``accel`` (timed blocks stop at
        once); the profile reaches the block's end with the speed left if it cannot stop."""
        s = min(max(s, 0.0), self.length)
        if self.timed:
            return Profile(s, 0.0, (), s)
        return braking(s, v, self.accel, self.length)

    def __repr__(self) -> str:
        return (
            f"<{type(self).__name__} {self.kind} length={self.length:.6g} "
            f"duration={self.duration:.6g}s end={self.end}>"
        )


class JointBlock(Block):
    """Straight line in joint space from ``start`` to ``end``; ``s`` = joint-space distance.

    ``steps``: the move in whole motor steps (``start_steps``, ``delta_steps``) when the limits
    have steps per degree; positions are then whole steps (see the module docstring).
    """

    __slots__ = ("_delta", "_events", "_per_step", "delta_steps", "start_steps")

    def __init__(
        self,
        kind: str,
        start: Vec7,
        end: Vec7,
        length: float,
        speed: float,
        accel: float,
        *,
        steps: tuple[Steps7, Steps7, Vec7] | None = None,
        delta: Vec7 | None = None,
        direction: Vec7 | None = None,
    ) -> None:
        """``delta``: ``end - start`` when the caller has it (the builders do); ``direction``:
        ``delta / length`` in floats, likewise."""
        self._delta = sub(end, start) if delta is None else delta
        self.start_steps: Steps7 | None = None
        self.delta_steps: Steps7 | None = None
        self._events = 0
        self._per_step: Vec7 | None = None
        if steps is not None:
            first, delta, per_degree = steps
            self.start_steps = first
            self.delta_steps = delta
            self._events = max(map(abs, delta))
            self._per_step = _per_step(per_degree)
        super().__init__(kind, start, end, length, speed, accel)
        if direction is not None:
            self.direction_in = self.direction_out = direction
        elif length > 0.0:
            d = self._delta
            unit = (float(d[0] / length), float(d[1] / length), float(d[2] / length),
                    float(d[3] / length), float(d[4] / length), float(d[5] / length),
                    float(d[6] / length))  # fmt: skip
            self.direction_in = unit
            self.direction_out = unit

    def position_at(self, s: float) -> Vec7:
        if s <= 0.0:
            return self.start
        if s >= self.length:
            return self.end
        if self.start_steps is None or self.delta_steps is None or self._per_step is None:
            return lerp(self.start, self._delta, s / self.length)
        n = self._events
        k = min(int(n * s / self.length), n)
        half = n // 2
        per = self._per_step
        first = self.start_steps
        out = [0.0] * AXES
        for i, d in enumerate(self.delta_steps):
            done = (k * abs(d) + half) // n
            out[i] = (first[i] + (done if d >= 0 else -done)) * per[i]
        return vec7(out)


class PathBlock(Block):
    """A Cartesian path: ``position_at(s) = poses(s / length)`` (rounded to whole steps when
    ``quantise`` is given).

    If ``poses`` raises ``ValueError`` between two samples (the path grazes the workspace
    boundary between them), the joints are interpolated linearly between the two samples instead.
    The planner stops before and after a path block (its ``s`` is tool millimetres, not joint
    degrees); :func:`~mirobot_emulator.motion.path_blocks` cuts a path into joint blocks that
    blend.
    """

    __slots__ = ("_cache_q", "_cache_s", "_poses", "_quantise", "samples")

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
        quantise: Callable[[Vec7], Vec7] | None = None,
    ) -> None:
        self._poses = poses
        self._quantise = quantise
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
            q = vec7(self._poses(u))
        except ValueError:
            n = len(self.samples) - 1
            k = min(int(u * n), n - 1)
            a = self.samples[k]
            q = lerp(a, sub(self.samples[k + 1], a), u * n - k)
        if self._quantise is not None:
            q = self._quantise(q)
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


def _per_step(per_degree: Vec7) -> Vec7:
    """``1 / per_degree`` per axis."""
    return vec7(1.0 / x for x in per_degree)


def limits_quantiser(limits: AxisLimits) -> Callable[[Vec7], Vec7] | None:
    """The step rounding of ``limits`` (None for an ideal machine)."""
    return None if limits.steps is None else limits.quantise
