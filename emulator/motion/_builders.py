"""Builders of planner blocks from what a G-code line asks: joint moves, Cartesian paths,
dwells and homing."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from typing import Final

from ._axes import ARM_AXES, AXES, RAIL, AxisLimits, Steps7, Vec7, finite_vec7, norm, sub, vec7
from ._blocks import (
    Block,
    DwellBlock,
    HomeSearchBlock,
    JointBlock,
    PathBlock,
    limits_quantiser,
)

PATH_START_TOLERANCE: Final = 1e-3
"""Largest per-axis gap allowed between ``poses(0)`` and the ``start`` given to a path."""

DEFAULT_PATH_STEP_MM: Final = 2.0
"""Paths are sampled (path_block) or cut (path_blocks) every this many mm by default."""

MIN_PATH_SAMPLES: Final = 8
MAX_PATH_SAMPLES: Final = 1000

SEQUENTIAL_ORDER: Final[tuple[tuple[int, ...], ...]] = ((0,), (1,), (2,), (3,), (4,))
"""``$HH``: J1..J5 one after another (2021 manual, 2.1.1)."""

SEQUENTIAL_SEARCH_FRACTION: Final = 0.5
"""ASSUMED: one group of a sequential homing searches for this fraction of ``search_seconds``."""


def _joint(start: Vec7, end: Vec7, feed: float | None, limits: AxisLimits, kind: str) -> JointBlock:
    start = finite_vec7(start, "start")
    end = finite_vec7(end, "end")
    if limits.steps is not None:
        first, last = limits.to_steps(start), limits.to_steps(end)
        return _joint_in_steps(first, last, feed, limits, kind)
    _check_feed(feed)
    return _joint_between(start, end, None, feed, limits, kind)


def _check_feed(feed: float | None) -> None:
    if feed is not None and not (math.isfinite(feed) and feed > 0.0):
        raise ValueError(f"feed must be a positive number of deg/min (or None for G0): {feed}")


_RECENT_BLOCKS: dict[tuple[Steps7, Steps7, float | None, str], tuple[AxisLimits, JointBlock]] = {}
"""The last 64 joint blocks built, by their whole steps, feed and kind, with the limits they
were built with: assumes a block is never changed once built and is a pure function of these
(a stream going back and forth shares them)."""
_RECENT_BLOCKS_MAX: Final = 64


def _joint_in_steps(
    first: Steps7, last: Steps7, feed: float | None, limits: AxisLimits, kind: str
) -> JointBlock:
    _check_feed(feed)
    key = (first, last, feed, kind)
    recent = _RECENT_BLOCKS.get(key)
    if recent is not None and recent[0] is limits:
        return recent[1]
    block = _joint_between_steps(first, last, feed, limits, kind)
    if len(_RECENT_BLOCKS) >= _RECENT_BLOCKS_MAX:
        _RECENT_BLOCKS.clear()
    _RECENT_BLOCKS[key] = (limits, block)
    return block


def _joint_between_steps(
    first: Steps7, last: Steps7, feed: float | None, limits: AxisLimits, kind: str
) -> JointBlock:
    delta_steps = (last[0] - first[0], last[1] - first[1], last[2] - first[2],
                   last[3] - first[3], last[4] - first[4], last[5] - first[5],
                   last[6] - first[6])  # fmt: skip
    start, end = limits.from_steps(first), limits.from_steps(last)
    assert limits.steps is not None  # (whole steps come from limits with steps)
    return _joint_between(start, end, (first, delta_steps, limits.steps), feed, limits, kind)


def _joint_between(
    start: Vec7,
    end: Vec7,
    steps: tuple[Steps7, Steps7, Vec7] | None,
    feed: float | None,
    limits: AxisLimits,
    kind: str,
) -> JointBlock:
    delta = sub(end, start)
    length = norm(delta)
    if length == 0.0:
        block = JointBlock(kind, start, end, 0.0, 1.0, 1.0, steps=steps, delta=delta)
        block.junction_deviation = limits.junction_deviation
        return block
    speed = math.inf if feed is None else feed / 60.0
    accel = math.inf
    max_rate, axis_accel = limits.max_rate, limits.accel
    for i, di in enumerate(delta):
        if not di:
            continue  # (a share of 0)
        share = abs(di) / length
        if share > 0.0:
            # ``min(speed, x)`` keeps ``speed`` unless ``x < speed``: the same comparison
            x = max_rate[i] / 60.0 / share
            if x < speed:
                speed = x
            x = axis_accel[i] / share
            if x < accel:
                accel = x
    d = delta  # floats (of floats), so ``d[i] / length`` is the float JointBlock would make
    unit = (d[0] / length, d[1] / length, d[2] / length, d[3] / length, d[4] / length,
            d[5] / length, d[6] / length)  # fmt: skip
    block = JointBlock(
        kind, start, end, length, speed, accel, steps=steps, delta=delta, direction=unit
    )
    block.junction_deviation = limits.junction_deviation
    return block


def joint_block_in_steps(
    first: Steps7, last: Steps7, feed: float | None, limits: AxisLimits
) -> Block:
    """:func:`joint_block` between two whole-step points: ``first`` and ``last`` are what
    ``limits.to_steps`` gave for its start and end (so both are finite)."""
    return _joint_in_steps(first, last, feed, limits, "move")


def joint_block(start: Vec7, end: Vec7, feed: float | None, limits: AxisLimits) -> Block:
    """Coordinated joint move (kind ``"move"``), GRBL's block in joint space.

    ``feed``: deg/min along the joint-space vector (Euclidean norm of the displacement), reduced
    so that no axis exceeds its max rate; ``None`` (G0) = the highest speed within every max rate.
    The acceleration is scaled the same way from the per-axis accelerations. With steps per
    degree in ``limits`` both ends are rounded to whole motor steps (C ``lround``) and the length
    is that of the rounded displacement (so ``X10`` is 567 steps = 9.995 degrees on J1).
    """
    return _joint(start, end, feed, limits, "move")


def _path_samples(length: float) -> int:
    n = math.ceil(length / DEFAULT_PATH_STEP_MM)
    return min(max(n, MIN_PATH_SAMPLES), MAX_PATH_SAMPLES)


def _sampled(
    start: Vec7, poses: Callable[[float], Vec7], length_mm: float, feed_mm_min: float, n: int
) -> list[Vec7]:
    if not (math.isfinite(length_mm) and length_mm >= 0.0):
        raise ValueError(f"path length must be finite and >= 0: {length_mm}")
    if not (math.isfinite(feed_mm_min) and feed_mm_min > 0.0):
        raise ValueError(f"feed must be a positive number of mm/min: {feed_mm_min}")
    if n < 1:
        raise ValueError(f"samples must be >= 1: {n}")
    qs = [finite_vec7(poses(k / n), "poses(u)") for k in range(n + 1)]
    gap = max(abs(a - b) for a, b in zip(qs[0], start, strict=True))
    if gap > PATH_START_TOLERANCE:
        raise ValueError(f"poses(0) = {qs[0]} is not the start {start} (gap {gap:.6g})")
    qs[0] = start
    return qs


def path_block(
    start: Vec7,
    poses: Callable[[float], Vec7],
    length_mm: float,
    feed_mm_min: float,
    limits: AxisLimits,
    kind: str = "line",
    samples: int | None = None,
) -> Block:
    """Cartesian line or arc in ONE block: ``poses(u)``, ``u`` in [0, 1], is the JOINT vector
    at fraction u. The planner stops before and after it; prefer :func:`path_blocks`.

    The tool moves at ``feed_mm_min`` along the path, reduced so that no joint exceeds its max
    rate at any of the ``samples + 1`` sampled points (default: one sample every
    ``DEFAULT_PATH_STEP_MM`` mm, between ``MIN_PATH_SAMPLES`` and ``MAX_PATH_SAMPLES``).
    Acceleration (ASSUMED): ``min_i accel_i / max|dq_i/ds|`` mm/s^2.

    ``poses`` is called ``samples + 1`` times here (a ``ValueError`` from it, e.g. an
    unreachable sample, propagates: refuse the line before any motion) and then once per
    :meth:`Block.position_at`. ``poses(0)`` must agree with ``start`` within
    ``PATH_START_TOLERANCE`` (else ``ValueError``); the block ends exactly at ``poses(1)``
    (rounded to whole steps when ``limits`` has steps).
    With ``length_mm == 0`` (pure re-orientation) the block is timed along the joint-space path,
    ``feed_mm_min`` read as deg/min (ASSUMED).
    """
    start = finite_vec7(start, "start")
    n = _path_samples(length_mm) if samples is None else int(samples)
    qs = _sampled(start, poses, length_mm, feed_mm_min, n)
    quantise = limits_quantiser(limits)
    if quantise is not None:
        qs[-1] = quantise(qs[-1])
    end = qs[-1]
    length = length_mm
    if length == 0.0:
        length = math.fsum(norm(sub(b, a)) for a, b in itertools.pairwise(qs))
        if length == 0.0:
            return PathBlock(kind, start, end, 0.0, 1.0, 1.0, poses, qs, quantise)
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
    return PathBlock(kind, start, end, length, speed, accel, poses, qs, quantise)


def path_blocks(
    start: Vec7,
    poses: Callable[[float], Vec7],
    length_mm: float,
    feed_mm_min: float,
    limits: AxisLimits,
    kind: str = "line",
    segments: int | None = None,
) -> list[Block]:
    """A Cartesian line or arc cut into ``segments`` joint-space blocks that blend.

    Segment ``k`` runs in a straight joint-space line from ``poses(k / n)`` to
    ``poses((k + 1) / n)`` (rounded to whole steps) with a joint feed chosen so that the tool
    covers the segment's ``length_mm / n`` at ``feed_mm_min`` (then reduced by the max rates as
    for any joint block). Default ``segments``: one every ``DEFAULT_PATH_STEP_MM`` mm, at least
    1, at most ``MAX_PATH_SAMPLES``. With ``length_mm == 0`` (pure re-orientation) the feed is
    read as deg/min along the joint path (ASSUMED). ``ValueError`` as :func:`path_block`.
    """
    start = finite_vec7(start, "start")
    if segments is None:
        n = min(max(math.ceil(length_mm / DEFAULT_PATH_STEP_MM), 1), MAX_PATH_SAMPLES)
    else:
        n = int(segments)
    qs = _sampled(start, poses, length_mm, feed_mm_min, n)
    blocks: list[Block] = []
    current = start
    for k in range(1, n + 1):
        target = limits.quantise(qs[k])
        joint_length = norm(sub(target, current))
        feed = feed_mm_min * joint_length * n / length_mm if length_mm > 0.0 else feed_mm_min
        if feed <= 0.0 or not math.isfinite(feed):
            feed = feed_mm_min
        block = _joint(current, target, feed, limits, kind)
        if block.length > 0.0 or k == n:
            blocks.append(block)
        current = block.end
    return [b for b in blocks if b.length > 0.0] or blocks[-1:]


def dwell_block(seconds: float, at: Vec7) -> Block:
    """``G4 P<seconds>``: occupies the planner for ``seconds`` without moving (state Run)."""
    if not (math.isfinite(seconds) and seconds >= 0.0):
        raise ValueError(f"dwell must be a finite number of seconds >= 0: {seconds}")
    return DwellBlock("dwell", finite_vec7(at, "at"), seconds)


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
    start = limits.quantise(finite_vec7(start, "start"))
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
    target = vec7(0.0 if i in homed else start[i] for i in range(AXES))
    blocks.append(_joint(start, target, None, limits, "home_pulloff"))
    return blocks
