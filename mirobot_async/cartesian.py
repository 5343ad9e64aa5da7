"""Cartesian (``M20``) moves as the firmware executes them, checked against an envelope.

A point-to-point ``G0`` is a joint-space move to the firmware-branch IK of the target. A path
(``G1`` line, ``G2``/``G3`` arc, ``G5`` gate: up, across, down) starts, when the joints are not
on the firmware's IK branch of the current pose, with a rapid joint move to that branch (the
"wrist snap"), then follows the path with J4/J6 kept continuous. Every part is checked: the
snap's joint path, every path sample's IK (reachable, within the envelope's joint limits) and
tool point (in the box). The work is bounded (:data:`~mirobot_async.paths.MAX_PATH_SAMPLES`).
Raises :class:`~mirobot_async.errors.MirobotUsageError` with the reason. Pure module.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import JOINT_LIMITS, LIMIT_TOL, Joints, Pose, inverse
from mirobot_async.paths import (
    MAX_PATH_SAMPLES,
    FloatArray,
    arc_plan,
    arc_samples,
    as_pose,
    line_samples,
    line_samples_needed,
    unwrap,
)

if TYPE_CHECKING:
    from mirobot_async.envelope import Envelope

__all__ = ["SNAP_TOLERANCE", "CartesianEnd", "cartesian_path", "point_to_point"]

SNAP_TOLERANCE = 1e-4
"""Largest joint gap (deg) between the arm and the IK of its pose that needs no snap move."""


@dataclass(frozen=True, slots=True)
class CartesianEnd:
    """Where a Cartesian move ends and what was checked on the way."""

    joints: Joints
    snap: Joints | None
    """Target of the rapid joint move before the path, when there is one."""
    samples: int


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
    return CartesianEnd(q, None, 1)


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
    first = unwrap(firmware_ik(envelope, start_pose, "the start pose", what), start)
    snap: Joints | None = None
    if max(abs(a - b) for a, b in zip(first, start, strict=True)) > SNAP_TOLERANCE:
        snap = first  # the firmware's rapid joint move to its IK branch first
        problem = envelope.joint_problem(
            first, what, f"the rapid joint move to the firmware's IK branch {_fmt(first)}: "
        )
        if problem is not None:
            raise MirobotUsageError(problem)
        envelope.check_joint_path(start, first, what=f"{what}, wrist snap before the path")
    prev = first
    count = 0
    allowed = np.maximum(_excess(envelope, first), 0.0)
    for sampler, needed, kind in segments:
        samples = sampler(int(needed))
        problem = envelope.box_problem(as_pose(samples[-1]), what) or envelope.path_box_problem(
            samples[:, :3], what, kind
        )
        if problem is not None:
            raise MirobotUsageError(problem)
        for i, row in enumerate(samples):
            pose = as_pose(row)
            last = i == len(samples) - 1
            where = "target pose" if last else f"the {kind} passes"
            q = unwrap(firmware_ik(envelope, pose, where, what), prev)
            excess = _excess(envelope, q)
            if last or (excess > allowed + LIMIT_TOL).any():
                problem = envelope.joint_problem(q, what, f"{where} {_fmt(pose)} with ")
                if problem is not None:
                    raise MirobotUsageError(problem)
            prev = q
            count += 1
    return CartesianEnd(prev, snap, count)


def _excess(envelope: Envelope, q: Joints) -> FloatArray:
    limits = np.asarray(envelope.joint_limits)
    qa = np.asarray(q)
    out: FloatArray = np.maximum(limits[:, 0] - qa, qa - limits[:, 1])
    return out
