"""Accepted motion lines into planner blocks (:mod:`mirobot_emulator.motion`): joint moves,
Cartesian lines, arcs and gate moves, checked sample by sample before anything moves."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np

from .. import motion
from ..motion import AxisLimits, Block, Vec7
from . import _codes as c
from ._geometry import Geometry, Pose, Refusal, lerp, pose6, vec7

PATH_SAMPLE_MM: Final = 2.0
"""Cartesian paths are checked (IK, limits) every this many mm ..."""
PATH_SAMPLE_DEG: Final = 2.0
"""... and every this many degrees of orientation change."""

MAX_PATH_CHECK_SAMPLES: Final = 2000
"""ASSUMED cap on the check samples of one path (a huge re-orientation is sampled coarser)."""

MAX_FEED: Final = 1e12
MIN_FEED: Final = 1e-9
"""Clamps for G93 inverse-time feeds that overflow or vanish (units/min)."""

SNAP_TOLERANCE: Final = 1e-4
"""Largest joint gap (deg) between the arm and the IK of its pose that needs no snap move
(without motor steps; with steps, a gap that rounds to no step needs none)."""

PathAt = Callable[[float], tuple[Pose, float]]
Segment = tuple[PathAt, float, int]
"""A path piece: pose and rail at ``u`` in [0, 1], its length (mm), its check samples."""

Planned = tuple[list[Block], Block | None, Vec7]
"""The blocks of a line, the block that ends on a limit switch (if any), the end joints."""


@dataclass
class Arc:
    """An XY arc of the commanded pose: centre, radius, start angle and signed travel."""

    cx: float
    cy: float
    radius: float
    start_angle: float
    travel: float


def sample_count(length: float, turn: float) -> int:
    """Check samples of a path of ``length`` mm turning ``turn`` degrees (capped)."""
    n = max(
        1,
        math.ceil(length / PATH_SAMPLE_MM - 1e-9),
        math.ceil(turn / PATH_SAMPLE_DEG - 1e-9),
    )
    return min(n, MAX_PATH_CHECK_SAMPLES)


def line_segment(p0: Pose, p1: Pose, rail0: float, rail1: float) -> Segment:
    length = math.dist(p0[:3], p1[:3])
    turn = max(abs(b - a) for a, b in zip(p0[3:], p1[3:], strict=True))
    n = sample_count(length, turn)

    def at(u: float) -> tuple[Pose, float]:
        if u >= 1.0:
            return p1, rail1
        return pose6(lerp(p0, p1, u)), rail0 + (rail1 - rail0) * u

    return at, length, n


def arc_segment(arc: Arc, p0: Pose, p1: Pose, rail0: float, rail1: float) -> Segment:
    dz = p1[2] - p0[2]
    length = math.hypot(abs(arc.travel) * arc.radius, dz)
    turn = max(abs(b - a) for a, b in zip(p0[3:], p1[3:], strict=True))
    n = sample_count(length, turn)

    def at(u: float) -> tuple[Pose, float]:
        if u <= 0.0:
            return p0, rail0
        if u >= 1.0:
            return p1, rail1
        angle = arc.start_angle + arc.travel * u
        x = arc.cx + arc.radius * math.cos(angle)
        y = arc.cy + arc.radius * math.sin(angle)
        rest = lerp(p0[2:], p1[2:], u)
        return pose6((x, y, *rest)), rail0 + (rail1 - rail0) * u

    return at, length, n


def _truncated(at: PathAt, fraction: float) -> PathAt:
    """The first ``fraction`` of the path piece ``at``, as a piece of its own."""

    def cut(u: float) -> tuple[Pose, float]:
        return at(u * fraction)

    return cut


def _needs_snap(current: Vec7, ideal: Vec7, limits: AxisLimits) -> bool:
    """Whether the arm at ``current`` must first move to the IK ``ideal`` of its pose."""
    if limits.steps is not None:
        return limits.quantise(ideal) != current
    return max(abs(a - b) for a, b in zip(ideal, current, strict=True)) > SNAP_TOLERANCE


class MoveBuilder:
    """Builds the blocks of one accepted motion line (raises :class:`Refusal`)."""

    def __init__(self, geometry: Geometry, settings: Mapping[int, float]) -> None:
        self.geometry = geometry
        self.settings = settings
        self.last_target: Vec7 = motion.ZERO
        """The joints of the last point-to-point target: a joint line's within the soft
        limits, or the IK of a Cartesian one even when the soft limits refuse it. A Cartesian
        target without a THETA3 leaves them and the soft limits check them (oracle): after
        ``M20 G90 G0 X100 Y0 Z50`` (J2 -59.654: ``Soft limit triggered:Y``) an unreachable
        target prints ``GOAL OUT OF WORKSPACE...THETA3!``, ``Soft limit triggered:Y``, ``ok``;
        after ``M21 G90 X10`` only ``...THETA3!ok``; a refused ``M21 G90 Y80`` stores nothing.
        Power-on: zero; ASSUMED kept by a reset (the firmware's globals)."""

    def linear_lines(self) -> bool:
        """Whether ``M20 G1`` runs a straight Cartesian line: on 2021 with ``$35=1``; on classic
        never (oracle: a joint-space move, its F in deg/min along the joint vector)."""
        return self.geometry.profile == "2021" and self.settings[35] != 0

    def plan(
        self,
        motion_mode: int,
        cart: bool,
        start: Vec7,
        target: Vec7,
        feed: float,
        feed_mode: int,
        arc: Arc | None,
        *,
        cart_start: Pose,
        locked: bool,
        check: bool,
    ) -> Planned:
        """The blocks of a motion line from ``start`` (joints; ``cart_start`` the commanded
        pose there) to ``target`` (joints, or pose + rail when ``cart``)."""
        if not cart:
            if locked:
                raise Refusal(c.TEXT_LOCKED)
            letter = self.geometry.soft_violation(target)
            if letter is None:
                self.last_target = target
            rate = None if motion_mode == 0 else feed
            return self._joint_move(start, target, rate, feed_mode, letter, check=check)
        if motion_mode == 0 or (motion_mode == 1 and not self.linear_lines()):
            try:
                q = self.geometry.ik(target[:6])
            except Refusal as refusal:
                letter = self.geometry.soft_violation(self.last_target)
                if refusal.text == c.TEXT_UNREACHABLE and letter is not None:
                    raise Refusal(refusal.text, then=c.TEXT_SOFT_LIMIT + letter) from None
                raise
            end = vec7((*q, target[6]))
            self.last_target = end
            if locked:
                raise Refusal(c.TEXT_LOCKED)
            rate = None if motion_mode == 0 else feed
            return self.joint_move(start, end, rate, feed_mode, check=check)
        p0 = cart_start
        rail0 = start[6]
        segments: list[Segment] = []
        if motion_mode == 1:
            segments.append(line_segment(p0, pose6(target[:6]), rail0, target[6]))
        elif motion_mode == 5:
            lift = self.settings[49]
            z_top = max(p0[2], target[2]) + lift
            up = (p0[0], p0[1], z_top, p0[3], p0[4], p0[5])
            over = (target[0], target[1], z_top, target[3], target[4], target[5])
            segments.append(line_segment(p0, up, rail0, rail0))
            segments.append(line_segment(up, over, rail0, target[6]))
            segments.append(line_segment(over, pose6(target[:6]), target[6], target[6]))
        else:
            assert arc is not None
            segments.append(arc_segment(arc, p0, pose6(target[:6]), rail0, target[6]))
        kind = "arc" if motion_mode in (2, 3) else "line"
        return self.path_move(
            start, segments, feed, feed_mode, kind=kind, locked=locked, check=check
        )

    def joint_move(
        self, start: Vec7, end: Vec7, feed: float | None, feed_mode: int, *, check: bool
    ) -> Planned:
        """One joint-space block (feed None: rapid); one that runs into a limit switch is two
        collinear blocks split where the switch closes (they blend, so the arm reaches it at
        the speed of the whole move, as GRBL's single block does) and the alarm stops it when
        the first is done."""
        letter = self.geometry.soft_violation(end)
        return self._joint_move(start, end, feed, feed_mode, letter, check=check)

    def _joint_move(
        self,
        start: Vec7,
        end: Vec7,
        feed: float | None,
        feed_mode: int,
        letter: str | None,
        *,
        check: bool,
    ) -> Planned:
        """:meth:`joint_move` with the soft-limit letter of ``end`` known (None: within)."""
        if letter is not None:
            raise Refusal(c.TEXT_SOFT_LIMIT + letter)
        if check:
            return [], None, end
        squares: tuple[float, ...]
        if len(start) == len(end) == 7:  # without a generator
            s, e = start, end
            squares = ((e[0] - s[0]) ** 2, (e[1] - s[1]) ** 2, (e[2] - s[2]) ** 2,
                       (e[3] - s[3]) ** 2, (e[4] - s[4]) ** 2, (e[5] - s[5]) ** 2,
                       (e[6] - s[6]) ** 2)  # fmt: skip
        else:
            squares = tuple((b - a) ** 2 for a, b in zip(start, end, strict=True))
        if not any(squares):  # a length of 0 (fsum, exactly rounded, is 0 only then)
            return [], None, end
        limits = self.geometry.limits()
        steps = None  # the ends in whole steps (their rounding raises for NaN or infinity)
        if limits.steps is not None:
            steps = limits.to_steps(start), limits.to_steps(end)
            if steps[0] == steps[1]:
                # GRBL drops a block of no steps: it takes no planner slot (oracle: a burst of
                # 25 ``M21 G91 X1`` lines ends at J1 1.040, each later line resynchronised near 0)
                return [], None, end
        if feed is not None and feed_mode == 93:
            feed = feed * math.sqrt(math.fsum(squares))  # the length
        if feed is not None and not math.isfinite(feed):
            feed = None  # the max rates limit the motion
        elif feed is not None and feed <= 0.0:
            feed = MIN_FEED
        cut = self.geometry.switch_crossing(start, end, limits, steps)
        try:
            if cut is None and steps is not None:
                return [motion.joint_block_in_steps(*steps, feed, limits)], None, end
            if cut is None:
                return [motion.joint_block(start, end, feed, limits)], None, end
            to_switch = motion.joint_block(start, cut, feed, limits)
            beyond = motion.joint_block(cut, end, feed, limits)
        except ValueError:
            raise Refusal(c.TEXT_UNREACHABLE) from None
        blocks = [to_switch] if beyond.length == 0.0 else [to_switch, beyond]
        return blocks, to_switch, end

    def path_move(
        self,
        start: Vec7,
        segments: Sequence[Segment],
        feed: float,
        feed_mode: int,
        *,
        kind: str = "line",
        locked: bool,
        check: bool,
    ) -> Planned:
        """Check every sample of every segment, then build the blocks (raises Refusal)."""
        geometry = self.geometry
        sampled: list[tuple[PathAt, float, int, Sequence[float], list[Vec7]]] = []
        prev: Sequence[float] = start
        for at, length, n in segments:
            refs = self._samples(at, n, prev)
            sampled.append((at, length, n, prev, refs))
            prev = refs[-1]
        # soft limits on every sample of the whole path first (the IK limits were checked
        # above): with $20=1 a line that would leave the range is refused before it moves, even
        # where a limit switch sits on the range's end
        for *_, refs in sampled:
            for q in refs:
                letter = geometry.soft_violation(q)
                if letter is not None:
                    raise Refusal(c.TEXT_SOFT_LIMIT + letter)
        checked: list[tuple[PathAt, float, list[Vec7]]] = []
        hits_switch = False
        for at, length, n, before, refs in sampled:
            cut = self._switch_cut(refs)
            if cut is not None:  # the path runs into a limit switch: it ends there
                at = _truncated(at, cut)
                refs = self._samples(at, max(1, math.ceil(n * cut)), before)
                checked.append((at, length * cut, refs))
                hits_switch = True
                break
            checked.append((at, length, refs))
        if locked:
            raise Refusal(c.TEXT_LOCKED)
        if check:
            return [], None, checked[-1][2][-1]
        limits = geometry.limits()
        blocks: list[Block] = []
        current = start
        for at, length, refs in checked:
            if _needs_snap(current, refs[0], limits):
                blocks.append(motion.joint_block(current, refs[0], None, limits))
                current = blocks[-1].end
            poses = self._poses_function(at, refs, current)
            still = max(abs(a - b) for a, b in zip(refs[-1], current, strict=True)) == 0.0
            if length == 0.0 and still:
                continue
            rate = feed
            if feed_mode == 93:
                span = length if length > 0.0 else math.dist(refs[0], refs[-1])
                rate = feed * span
            if not math.isfinite(rate):
                rate = MAX_FEED  # an absurd G93 feed: the max rates limit the motion
            elif rate <= 0.0:
                rate = MIN_FEED
            try:
                pieces = motion.path_blocks(
                    current, poses, length, rate, limits, kind=kind, segments=self.segments(kind)
                )
            except ValueError:
                raise Refusal(c.TEXT_UNREACHABLE) from None
            blocks.extend(pieces)
            current = pieces[-1].end
        return blocks, (blocks[-1] if hits_switch and blocks else None), current

    def segments(self, kind: str) -> int | None:
        """Joint-space blocks per Cartesian path: None, one every ``motion.DEFAULT_PATH_STEP_MM``
        mm. ASSUMED: not the 2021 manual's ``$36`` "number of interpolation points" (10), whose
        ten chords of a long line would leave it by more than the status resolution."""
        del kind
        return None

    def _samples(self, at: PathAt, n: int, prev: Sequence[float]) -> list[Vec7]:
        """The joints at ``n + 1`` even steps of a path piece (IK; J4/J6 kept continuous)."""
        refs: list[Vec7] = []
        for k in range(n + 1):
            pose, rail = at(k / n)
            q = self.geometry.unwrap(self.geometry.ik(pose), prev)
            refs.append(vec7((*q, rail)))
            prev = refs[-1]
        return refs

    def _switch_cut(self, refs: Sequence[Vec7]) -> float | None:
        """The fraction of a sampled path where it first runs into a switch, or None."""
        for k in range(1, len(refs)):
            cut = self.geometry.switch_crossing(refs[k - 1], refs[k])
            if cut is None:
                continue
            a, b = refs[k - 1], refs[k]
            span = max(abs(y - x) for x, y in zip(a, b, strict=True))
            f = max(abs(y - x) for x, y in zip(a, cut, strict=True)) / span if span else 0.0
            return (k - 1 + f) / (len(refs) - 1)
        return None

    def _poses_function(
        self, at: PathAt, refs: Sequence[Vec7], start: Vec7
    ) -> Callable[[float], Vec7]:
        """``poses(u)`` for :func:`motion.path_block`: IK of the path, continuous in J4/J6."""
        geometry = self.geometry
        ref_array = np.asarray(refs, dtype=np.float64)
        n = len(refs) - 1

        def poses(u: float) -> Vec7:
            if u <= 0.0:
                return start
            pose, rail = at(u)
            if u >= 1.0:
                return refs[-1]
            k = min(int(u * n), n - 1)
            f = u * n - k
            ref = ref_array[k] + (ref_array[k + 1] - ref_array[k]) * f
            q = geometry.unwrap(geometry.ik(pose, check_limits=False), ref.tolist())
            return vec7((*q, rail))

        def safe(u: float) -> Vec7:
            try:
                return poses(u)
            except Refusal as exc:
                raise ValueError(exc.text) from None

        return safe
