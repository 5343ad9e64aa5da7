"""One-dimensional velocity profiles along a block's path coordinate ``s``.

A :class:`Profile` is piecewise constant acceleration. :func:`trapezoid` is GRBL's block
profile: accelerate from the entry speed, cruise at the nominal speed, decelerate to the exit
speed (or a triangle when the block is too short to reach the nominal speed). :func:`braking`
is a feed hold: decelerate at the block's acceleration, ending either at rest inside the block
or at the block's end with the speed that is left (the hold then continues in the next block).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final

SNAP_FRACTION: Final = 1e-9
"""A feed hold whose stopping distance reaches this close to the block's end stops on the end."""


class Profile:
    """Path coordinate ``s(t)`` for ``t`` in ``[0, duration]``: piecewise constant acceleration.

    Starts at ``s_start`` with speed ``v_start`` and ends at ``s_end`` (exactly) with speed
    ``v_end``.
    """

    __slots__ = ("_phases", "duration", "s_end", "s_start", "v_end", "v_start")

    def __init__(
        self,
        s_start: float,
        v_start: float,
        phases: Sequence[tuple[float, float]],
        s_end: float,
        v_end: float | None = None,
    ) -> None:
        """``phases``: ``(duration, acceleration)`` pairs, in order; ``v_end`` defaults to the
        speed the phases end with (a profile without phases ends at ``v_end`` or at rest)."""
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
        if v_end is None:
            v_end = max(v, 0.0) if table else 0.0
        self.v_end = v_end

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

    def phases(self) -> list[tuple[float, float]]:
        """The ``(duration, acceleration)`` pairs, in order."""
        table = list(reversed(self._phases))
        if not table:
            return []  # a block without motion (a feed hold on it found no phases)
        ends = [row[0] for row in table[1:]] + [self.duration]
        return [(end - row[0], row[3]) for row, end in zip(table, ends, strict=True)]

    def window(self, t_from: float, t_to: float) -> list[tuple[float, float]]:
        """The phases between ``t_from`` and ``t_to`` (clipped to the profile), in order."""
        out: list[tuple[float, float]] = []
        t = 0.0
        for dt, a in self.phases():
            lo, hi = max(t, t_from), min(t + dt, t_to)
            if hi > lo:
                out.append((hi - lo, a))
            t += dt
        return out

    def v_at(self, t: float) -> float:
        """The speed along ``s`` at time ``t`` (``v_end`` from the end on)."""
        if t >= self.duration:
            return self.v_end
        if t <= 0.0:
            return self.v_start
        t0, _s0, v0, a = self._phase(t)
        return max(v0 + a * (t - t0), 0.0)


def constant_rate(s0: float, s_end: float) -> Profile:
    """Timed blocks (dwell, homing search): ``s`` is seconds, rate 1."""
    return Profile(s0, 1.0, ((s_end - s0, 0.0),), s_end, 1.0)


def trapezoid(
    s0: float, s_end: float, v_in: float, v_out: float, v_nom: float, accel: float
) -> Profile:
    """From ``s0`` at ``v_in`` to ``s_end`` at ``v_out``, never above ``max(v_nom, v_in)``.

    The planner guarantees that ``v_out`` is reachable; float error (or a feed hold resumed
    during its final deceleration) is absorbed by braking or accelerating a hair harder so that
    the block still ends exactly at ``s_end`` with ``v_out``.
    """
    d = s_end - s0
    v_in = max(v_in, 0.0)
    v_out = max(v_out, 0.0)
    if d <= 0.0:
        return Profile(s0, v_in, (), max(s0, s_end), v_out)
    if v_in * v_in - v_out * v_out >= 2.0 * accel * d:
        dec = (v_in * v_in - v_out * v_out) / (2.0 * d)
        return Profile(s0, v_in, (((v_in - v_out) / dec, -dec),), s_end, v_out)
    if v_out * v_out - v_in * v_in >= 2.0 * accel * d:
        acc = (v_out * v_out - v_in * v_in) / (2.0 * d)
        return Profile(s0, v_in, (((v_out - v_in) / acc, acc),), s_end, v_out)
    peak = min(v_nom, math.sqrt(accel * d + 0.5 * (v_in * v_in + v_out * v_out)))
    peak = max(peak, v_in, v_out)
    d_acc = (peak * peak - v_in * v_in) / (2.0 * accel)
    d_dec = (peak * peak - v_out * v_out) / (2.0 * accel)
    d_cruise = max(d - d_acc - d_dec, 0.0)
    return Profile(
        s0,
        v_in,
        (
            ((peak - v_in) / accel, accel),
            (d_cruise / peak, 0.0),
            ((peak - v_out) / accel, -accel),
        ),
        s_end,
        v_out,
    )


def braking(s0: float, v0: float, accel: float, s_limit: float) -> Profile:
    """Feed hold: decelerate from ``v0`` at ``accel``; stop before ``s_limit`` if there is room,
    else reach ``s_limit`` with the speed that is left (``v_end``; 0 within ``SNAP_FRACTION``)."""
    if v0 <= 0.0:
        return Profile(s0, 0.0, (), s0, 0.0)
    if s0 >= s_limit:
        return Profile(s_limit, v0, (), s_limit, v0)
    d = v0 * v0 / (2.0 * accel)
    room = s_limit - s0
    if d >= room - SNAP_FRACTION * max(1.0, s_limit):
        if d <= room + SNAP_FRACTION * max(1.0, s_limit):  # stops on the end: land exactly
            dec = v0 * v0 / (2.0 * room)
            return Profile(s0, v0, ((v0 / dec, -dec),), s_limit, 0.0)
        v_left = math.sqrt(v0 * v0 - 2.0 * accel * room)
        return Profile(s0, v0, (((v0 - v_left) / accel, -accel),), s_limit, v_left)
    return Profile(s0, v0, ((v0 / accel, -accel),), s0 + d, 0.0)


STOPPED: Final = Profile(0.0, 0.0, (), 0.0)
"""The profile of a block that has not started (held before it began)."""
