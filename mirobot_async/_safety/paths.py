"""Sampling of the paths the firmware moves along, with bounded work.

Straight lines and ``G2``/``G3`` arcs in Cartesian space are sampled for the envelope's checks;
the number of samples is computed first (:func:`line_samples_needed`, :func:`arc_plan`) so that
an absurd line (``A300000``, ``A99999999999``) is refused before anything is allocated, and no
check of one line can take more than a few milliseconds (:data:`MAX_PATH_SAMPLES` inverse
kinematics, :data:`MAX_JOINT_PATH_SAMPLES` vectorised forward kinematics). Pure module.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final, TypeAlias

import numpy as np
import numpy.typing as npt

from mirobot_async.kinematics import BEHIND_SHOULDER_TOL, DH, JOINT_LIMITS, Joints, Pose

__all__ = [
    "MAX_JOINT_PATH_SAMPLES",
    "MAX_PATH_SAMPLES",
    "PATH_STEP_DEG",
    "ArcPlan",
    "arc_plan",
    "arc_samples",
    "firmware_ik_rows",
    "line_samples",
    "line_samples_needed",
    "unwrap",
]

FloatArray: TypeAlias = npt.NDArray[np.float64]

MAX_PATH_SAMPLES: Final = 1000
"""Most samples (inverse kinematics, vectorised) checked for one Cartesian path, about 4 ms;
longer paths are refused with a request to split them (1000 samples at 2 mm is 2 m, more than
any reachable path: the arm's reach is about 300 mm)."""
MAX_JOINT_PATH_SAMPLES: Final = 4000
"""Most samples of one joint-space path (vectorised forward kinematics, about 3 ms)."""
_REACH_EPS: Final = 1e-12
_SINGULAR_EPS: Final = 1e-9
"""The tolerances of :mod:`mirobot_async.kinematics` (reach and wrist singularity)."""
PATH_STEP_DEG: Final = 2.0
"""Largest change of each orientation angle between two samples of a Cartesian path."""


def line_samples_needed(
    start: Sequence[float], end: Sequence[float], step_mm: float, step_deg: float = PATH_STEP_DEG
) -> float:
    """Intervals needed on the straight line ``start`` -> ``end`` (poses); may be huge or inf."""
    dist = math.dist(start[:3], end[:3])
    turn = max(abs(b - a) for a, b in zip(start[3:6], end[3:6], strict=True))
    return max(1.0, math.ceil(dist / step_mm - 1e-9), math.ceil(turn / step_deg - 1e-9))


def line_samples(start: Sequence[float], end: Sequence[float], intervals: int) -> FloatArray:
    """``intervals + 1`` evenly spaced samples of the straight line, both ends exact.

    ASSUMED (PROTOCOL 9): position and the orientation angles are interpolated linearly and
    component-wise, without wrapping at +-180, as the firmware's own numbers are.
    """
    a = np.asarray(start, dtype=np.float64)
    b = np.asarray(end, dtype=np.float64)
    t = np.linspace(0.0, 1.0, intervals + 1)
    out: FloatArray = a[None, :] + t[:, None] * (b - a)[None, :]
    out[-1] = b
    return out


@dataclass(frozen=True, slots=True)
class ArcPlan:
    """A ``G2``/``G3`` arc of radius R (the minor arc) in the XY plane, ready to sample."""

    centre: tuple[float, float]
    radius: float
    start_angle: float
    travel: float
    """Signed angle swept (radians): negative clockwise."""
    intervals: float
    """Intervals needed at the step asked (may be huge)."""


def arc_plan(
    start: Sequence[float],
    end: Sequence[float],
    radius: float,
    clockwise: bool,
    step_mm: float,
    step_deg: float = PATH_STEP_DEG,
) -> ArcPlan | str:
    """The arc from ``start`` to ``end`` (poses) as GRBL's radius format computes it, or the
    problem that makes the firmware refuse it (``Arc radius error``, a zero chord)."""
    name = "G2" if clockwise else "G3"
    if not radius > 0:
        return f"{name} R{radius:g}: the radius must be > 0"
    dx, dy = end[0] - start[0], end[1] - start[1]
    chord = math.hypot(dx, dy)
    if chord == 0:
        return f"{name} with a zero chord: a full circle is impossible with R"
    disc = 4.0 * radius * radius - chord * chord
    if disc < -1e-9:
        return (
            f"{name}: the chord {chord:.3f} mm is longer than 2R = {2 * radius:.3f} mm "
            "(the firmware says 'Arc radius error')"
        )
    h = -math.sqrt(max(0.0, disc)) / chord
    if not clockwise:
        h = -h
    ci, cj = 0.5 * (dx - dy * h), 0.5 * (dy + dx * h)
    cx, cy = start[0] + ci, start[1] + cj
    rx, ry = -ci, -cj  # start relative to the centre
    ex, ey = end[0] - cx, end[1] - cy
    travel = math.atan2(rx * ey - ry * ex, rx * ex + ry * ey)
    if clockwise and travel >= -1e-9:
        travel -= 2 * math.pi
    elif not clockwise and travel <= 1e-9:
        travel += 2 * math.pi
    r = math.hypot(rx, ry)
    length = math.hypot(abs(travel) * r, end[2] - start[2])
    turn = max(abs(b - a) for a, b in zip(start[3:6], end[3:6], strict=True))
    intervals = max(1.0, math.ceil(length / step_mm - 1e-9), math.ceil(turn / step_deg - 1e-9))
    return ArcPlan((cx, cy), r, math.atan2(ry, rx), travel, intervals)


def arc_samples(
    plan: ArcPlan, start: Sequence[float], end: Sequence[float], intervals: int
) -> FloatArray:
    """Samples of the arc (both ends exact), plus its x/y extreme points (for the box test).

    ASSUMED (GRBL): z and the orientation are interpolated linearly along the arc.
    """
    ts = set(np.linspace(0.0, 1.0, intervals + 1).tolist())
    a0, travel = plan.start_angle, plan.travel
    lo, hi = sorted((a0, a0 + travel))
    for k in range(math.ceil(lo / (math.pi / 2)), math.floor(hi / (math.pi / 2)) + 1):
        ts.add((k * math.pi / 2 - a0) / travel)
    t = np.asarray(sorted(v for v in ts if 0.0 <= v <= 1.0))
    a = np.asarray(start, dtype=np.float64)
    b = np.asarray(end, dtype=np.float64)
    out: FloatArray = a[None, :] + t[:, None] * (b - a)[None, :]
    angle = a0 + t * travel
    out[:, 0] = plan.centre[0] + plan.radius * np.cos(angle)
    out[:, 1] = plan.centre[1] + plan.radius * np.sin(angle)
    out[0], out[-1] = a, b
    return out


def unwrap(q: Sequence[float], ref: Sequence[float]) -> Joints:
    """Shift J4 and J6 by whole turns to lie nearest to ``ref`` (within the factory ranges), as
    the firmware keeps them continuous along a path."""
    out = [float(v) for v in q[:6]]
    for j in (3, 5):
        lo, hi = JOINT_LIMITS[j]
        shifted = out[j] + 360.0 * round((ref[j] - out[j]) / 360.0)
        if lo <= shifted <= hi:
            out[j] = shifted
    return (out[0], out[1], out[2], out[3], out[4], out[5])


def as_pose(values: Sequence[float]) -> Pose:
    """Six floats as a :data:`~mirobot_async.kinematics.Pose`."""
    return (
        float(values[0]),
        float(values[1]),
        float(values[2]),
        float(values[3]),
        float(values[4]),
        float(values[5]),
    )


def firmware_ik_rows(poses: FloatArray, dh: DH, tool: Sequence[float]) -> FloatArray:
    """The firmware-branch IK (shoulder front, elbow up, wrist unflipped) of many poses at once.

    The same closed form as :func:`mirobot_async.kinematics.inverse` (``branch="firmware"``),
    vectorised; rows where that branch does not apply (front unreachable, a singular wrist or
    shoulder) are NaN: the caller solves those one by one with ``inverse``.
    """
    deg = math.pi / 180.0
    x, y, z = poses[:, 0], poses[:, 1], poses[:, 2]
    cx, sx = np.cos(poses[:, 3] * deg), np.sin(poses[:, 3] * deg)
    cy, sy = np.cos(poses[:, 4] * deg), np.sin(poses[:, 4] * deg)
    cz, sz = np.cos(poses[:, 5] * deg), np.sin(poses[:, 5] * deg)
    r00, r01, r02 = cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx
    r10, r11, r12 = sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx
    r20, r21, r22 = -sy, cy * sx, cy * cx
    tx, ty, tz = (float(v) for v in tool)
    wx = x - (r00 * tx + r01 * ty + r02 * tz) - dh.l * r02
    wy = y - (r10 * tx + r11 * ty + r12 * tz) - dh.l * r12
    wz = z - (r20 * tx + r21 * ty + r22 * tz) - dh.l * r22
    a2, k = dh.a2, dh.forearm
    beta = math.atan2(dh.d4, dh.a3)
    rho = np.hypot(wx, wy)
    q1 = np.arctan2(wy, wx)
    h = wz - dh.d1
    r = rho - dh.a1
    cos_phi = (r * r + h * h - a2 * a2 - k * k) / (2.0 * a2 * k)
    # a wrist centre behind the shoulder: the firmware goes elsewhere (kinematics.BehindShoulder)
    good = (np.abs(cos_phi) <= 1.0 + _REACH_EPS) & (r >= -BEHIND_SHOULDER_TOL)
    phi = np.arccos(np.clip(cos_phi, -1.0, 1.0))
    q3 = phi - beta
    q2 = np.arctan2(r, h) - np.arctan2(k * np.sin(phi), a2 + k * np.cos(phi))
    c1, s1 = np.cos(q1), np.sin(q1)
    c23, s23 = np.cos(q2 + q3), np.sin(q2 + q3)
    v0, v1, v2 = c1 * r00 + s1 * r10, c1 * r01 + s1 * r11, c1 * r02 + s1 * r12
    m02 = s23 * v2 + c23 * r22
    m10 = c23 * v0 - s23 * r20
    m11 = c23 * v1 - s23 * r21
    m12 = c23 * v2 - s23 * r22
    m22 = -s1 * r02 + c1 * r12
    c5 = np.hypot(m02, m22)
    good &= c5 >= _SINGULAR_EPS
    q5 = np.arctan2(m12, c5)
    q4 = np.arctan2(-m22, m02)
    q6 = np.arctan2(-m11, m10)
    out: FloatArray = np.stack([q1, q2, q3, q4, q5, q6], axis=1) / deg
    out = np.fmod(out, 360.0)
    out = np.where(out <= -180.0, out + 360.0, np.where(out > 180.0, out - 360.0, out)) + 0.0
    out[~good] = np.nan
    return out
