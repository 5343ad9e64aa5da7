"""Cartesian (``M20``) moves as the firmware executes them, checked against an envelope.

A point-to-point ``G0`` is a joint-space move to the firmware-branch IK of the target. A path
(``G1`` line, ``G2``/``G3`` arc, ``G5`` gate: up, across, down) starts, when the joints are not
on the firmware's IK branch of the current pose, with a rapid joint move to that branch (the
"wrist snap"), then follows the path with J4/J6 kept continuous. Every part is checked: the
snap's joint path, every path sample's IK (reachable, within the envelope's joint limits) and
tool point (in the box). The work is bounded
(:data:`~mirobot_async._safety.paths.MAX_PATH_SAMPLES`). Raises
:class:`~mirobot_async.errors.MirobotUsageError` with the reason. Pure module.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from mirobot_async._safety.paths import (
    MAX_PATH_SAMPLES,
    FloatArray,
    arc_plan,
    arc_samples,
    as_pose,
    firmware_ik_rows,
    line_samples,
    line_samples_needed,
    unwrap,
)
from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import JOINT_LIMITS, LIMIT_TOL, Joints, Pose, inverse

if TYPE_CHECKING:
    from mirobot_async._safety.envelope import Envelope

__all__ = ["SNAP_TOLERANCE", "CartesianEnd", "cartesian_path", "point_to_point"]

SNAP_TOLERANCE = 1e-4
"""Largest joint gap (deg) between the arm and the IK of its pose that needs no snap move."""


@dataclass(frozen=True, slots=True)
class CartesianEnd:
    """Where a Cartesian move ends and what was checked on the way."""

    joints: Joints | None
    """The end joints; None when the wrist snap may turn J4/J6 either way (the pose is known)."""
    snap: Joints | None
    """Target of the rapid joint move before the path, when there is one."""
    samples: int
    model_joints: Joints | None = None
    """The end joints of the emulator's model (J4/J6 nearest to the start)."""


def _fmt(values: tuple[float, ...] | list[float]) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in values) + ")"


def firmware_ik(envelope: Envelope, pose: Pose, subject: str, what: str) -> Joints:
    """The firmware-branch IK of ``pose`` within the factory ranges (as the firmware computes)."""
    try:
        return inverse(pose, envelope.dh, "firmware", tool=envelope.tool, limits=JOINT_LIMITS)
    except MirobotUsageError as exc:
        raise MirobotUsageError(
            f"{subject} {_fmt(pose)} is unreachable for the firmware ({what}): {exc}"
        ) from None


def point_to_point(
    envelope: Envelope, start: Joints | None, target: Pose, what: str
) -> CartesianEnd:
    """``M20 G0``: the joint move to the firmware IK of ``target``."""
    problem = envelope.box_problem(target, what)
    if problem is not None:
        raise MirobotUsageError(problem)
    q = firmware_ik(envelope, target, "target pose", what)
    problem = envelope.joint_problem(q, what, f"target pose {_fmt(target)} needs (firmware IK) ")
    if problem is not None:
        raise MirobotUsageError(problem)
    if start is not None:
        envelope.check_joint_path(start, q, what=what)
    return CartesianEnd(q, None, 1, q)


Segment = tuple[Callable[[int], FloatArray], float, str]
"""(samples for a number of intervals, intervals needed, kind of path)."""


def _line(a: Pose, b: Pose, step: float) -> Segment:
    return (lambda n: line_samples(a, b, n), line_samples_needed(a, b, step), "straight line")


def cartesian_path(
    envelope: Envelope,
    start: Joints,
    start_pose: Pose,
    target: Pose,
    motion: int,
    *,
    radius: float | None,
    gate_lift: float | None,
    what: str,
) -> CartesianEnd:
    """``M20 G1``/``G2``/``G3``/``G5`` from ``start`` (joints) at ``start_pose`` to ``target``."""
    step = envelope.path_step_mm
    segments: list[Segment] = []
    if motion == 1:
        segments.append(_line(start_pose, target, step))
    elif motion in (2, 3):
        if radius is None:
            raise MirobotUsageError(f"G{motion} needs R<radius> (the firmware rejects it)")
        plan = arc_plan(start_pose, target, radius, motion == 2, step)
        if isinstance(plan, str):
            raise MirobotUsageError(plan)
        arc = plan
        segments.append((lambda n: arc_samples(arc, start_pose, target, n), plan.intervals, "arc"))
    else:
        if gate_lift is None:
            raise MirobotUsageError("G5 needs the lift height $49, which is unknown")
        top = max(start_pose[2], target[2]) + gate_lift
        up = as_pose((*start_pose[:2], top, *start_pose[3:]))
        over = as_pose((*target[:2], top, *target[3:]))
        segments += [_line(start_pose, up, step), _line(up, over, step), _line(over, target, step)]
    total = sum(needed for _, needed, _ in segments)
    if total > MAX_PATH_SAMPLES:
        raise MirobotUsageError(
            f"the path needs {total:.0f} check samples, more than the {MAX_PATH_SAMPLES} the "
            "envelope checks for one line: split it into shorter moves"
        )
    ik = firmware_ik(envelope, start_pose, "the start pose", what)
    candidates = snap_candidates(ik, start)
    first = candidates[0]
    snap: Joints | None = None
    for target_q in candidates:
        if max(abs(a - b) for a, b in zip(target_q, start, strict=True)) <= SNAP_TOLERANCE:
            continue
        snap = snap or target_q  # the firmware's rapid joint move to its IK branch first
        problem = envelope.joint_problem(
            target_q, what, f"the rapid joint move to the firmware's IK branch {_fmt(target_q)}: "
        )
        if problem is not None:
            raise MirobotUsageError(problem)
        envelope.check_joint_path(start, target_q, what=f"{what}, wrist snap before the path")
    limits = envelope.joint_limits
    allowed = np.maximum(np.asarray(_excess(limits, first)), 0.0)
    prev = first
    count = 0
    wrist = [first[3], first[3], first[5], first[5]]  # J4 and J6 extremes along the path
    for sampler, needed, kind in segments:
        samples = sampler(int(needed))
        problem = envelope.box_problem(as_pose(samples[-1]), what) or envelope.path_box_problem(
            samples[:, :3], what, kind
        )
        if problem is not None:
            raise MirobotUsageError(problem)
        rows = _path_joints(envelope, samples, prev, kind, what)
        lo = np.asarray([v[0] for v in limits])
        hi = np.asarray([v[1] for v in limits])
        excess = np.maximum(lo[None, :] - rows, rows - hi[None, :])
        bad = (excess > allowed[None, :] + LIMIT_TOL).any(axis=1)
        bad[-1] = bool((excess[-1] > LIMIT_TOL).any())
        if bad.any():
            i = int(np.argmax(bad))
            where = "target pose" if i == len(rows) - 1 else f"the {kind} passes"
            q = as_pose(rows[i])
            pose = as_pose(samples[i])
            problem = envelope.joint_problem(q, what, f"{where} {_fmt(pose)} with ")
            if problem is not None:
                raise MirobotUsageError(problem)
        wrist = [
            min(wrist[0], float(rows[:, 3].min())),
            max(wrist[1], float(rows[:, 3].max())),
            min(wrist[2], float(rows[:, 5].min())),
            max(wrist[3], float(rows[:, 5].max())),
        ]
        prev = as_pose(rows[-1])
        count += len(rows)
    for other in candidates[1:]:  # the same path with J4/J6 whole turns apart
        shift4, shift6 = other[3] - first[3], other[5] - first[5]
        for j, low, high, shift in (
            (3, wrist[0], wrist[1], shift4),
            (5, wrist[2], wrist[3], shift6),
        ):
            bottom, top = limits[j]
            if low + shift < bottom - LIMIT_TOL or high + shift > top + LIMIT_TOL:
                raise MirobotUsageError(
                    f"after the rapid joint move to the firmware's IK branch {_fmt(other)}, "
                    f"J{j + 1} would leave the envelope's range {bottom:g}..{top:g} deg ({what})"
                )
    ambiguous = (
        len(
            {round(c[3] - first[3]) for c in candidates}
            | {round(c[5] - first[5]) for c in candidates}
        )
        > 1
    )
    return CartesianEnd(None if ambiguous else prev, snap, count, prev)


def _path_joints(
    envelope: Envelope, samples: FloatArray, start: Joints, kind: str, what: str
) -> FloatArray:
    """Firmware-branch IK of every sample (vectorised), J4/J6 kept continuous from ``start``."""
    rows = firmware_ik_rows(samples, envelope.dh, envelope.tool)
    for i in np.flatnonzero(np.isnan(rows[:, 0])).tolist():  # singular or back branch: one by one
        last = i == len(rows) - 1
        where = "target pose" if last else f"the {kind} passes"
        rows[i] = firmware_ik(envelope, as_pose(samples[i]), where, what)
    lo = np.asarray([v[0] for v in JOINT_LIMITS])
    hi = np.asarray([v[1] for v in JOINT_LIMITS])
    outside = ((rows < lo[None, :] - LIMIT_TOL) | (rows > hi[None, :] + LIMIT_TOL)).any(axis=1)
    if outside.any():  # the firmware's IK refuses angles outside its factory ranges
        i = int(np.argmax(outside))
        where = "target pose" if i == len(rows) - 1 else f"the {kind} passes"
        firmware_ik(envelope, as_pose(samples[i]), where, what)  # raises with the firmware's text
    ref4, ref6 = start[3], start[5]
    (lo4, hi4), (lo6, hi6) = JOINT_LIMITS[3], JOINT_LIMITS[5]
    j4 = rows[:, 3].tolist()
    j6 = rows[:, 5].tolist()
    for i in range(len(j4)):
        shifted = j4[i] + 360.0 * round((ref4 - j4[i]) / 360.0)
        if lo4 <= shifted <= hi4:
            j4[i] = shifted
        shifted = j6[i] + 360.0 * round((ref6 - j6[i]) / 360.0)
        if lo6 <= shifted <= hi6:
            j6[i] = shifted
        ref4, ref6 = j4[i], j6[i]
    rows[:, 3] = j4
    rows[:, 5] = j6
    return rows


def snap_candidates(ik: Joints, start: Joints) -> list[Joints]:
    """Where the firmware's rapid joint move before a path may go: its IK of the start pose,
    with J4/J6 taken nearest to the current joints (the emulator's model) or as computed (the
    firmware's own numbers). A wrist flip puts J4/J6 exactly half a turn away: both ways count."""
    nearest = unwrap(ik, start)
    options: list[list[float]] = [[v] for v in nearest]
    for j in (3, 5):
        lo, hi = JOINT_LIMITS[j]
        turns = (start[j] - ik[j]) / 360.0
        values = {nearest[j], ik[j]}
        if abs(turns - math.floor(turns) - 0.5) < 1e-3:  # a tie: both half-turn directions
            values |= {ik[j] + 360.0 * math.floor(turns), ik[j] + 360.0 * math.ceil(turns)}
        options[j] = [nearest[j], *sorted(v for v in values if v != nearest[j] and lo <= v <= hi)]
    out: list[Joints] = [nearest]
    for j4 in options[3]:
        for j6 in options[5]:
            q = (nearest[0], nearest[1], nearest[2], j4, nearest[4], j6)
            if q not in out:
                out.append(q)
    return out


def _excess(limits: tuple[tuple[float, float], ...], q: Sequence[float]) -> list[float]:
    """How far each joint is outside its range (negative: inside)."""
    return [max(lo - v, v - hi) for v, (lo, hi) in zip(q, limits, strict=True)]
