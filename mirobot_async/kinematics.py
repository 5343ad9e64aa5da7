"""Forward and inverse kinematics of the Mirobot 6-axis arm (PROTOCOL.md section 8).

Pure math (``math`` and numpy): no I/O, no asyncio. This is the only module of ``mirobot_async``
the emulator imports, so its choices (notably the firmware IK branch) define what the virtual arm
reports. Angles in degrees, lengths in mm; Craig's modified DH (``T = RotX(alpha) TransX(a)
RotZ(theta) TransZ(d)``, table of PROTOCOL 8.1); the flange point is the origin of frame 6, a
tool offset ``(tx, ty, tz)`` is in the flange frame. A pose is ``(x, y, z, rx, ry, rz)``, roll,
pitch, yaw about the *fixed* world axes, ``R = Rz(rz) Ry(ry) Rx(rx)`` (PROTOCOL 8.2).

Errors, all :class:`~mirobot_async.errors.MirobotUsageError` (hence ``ValueError``):
:class:`Unreachable` (no theta3: outside the workspace), :class:`OutOfLimits` (no solution
within the joint ranges), :class:`BehindShoulder` (the firmware would go to another pose).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Literal, TypeAlias

import numpy as np
import numpy.typing as npt

from mirobot_async.errors import (  # defined with the error tree
    BehindShoulder,
    MirobotUsageError,
    OutOfLimits,
    Unreachable,
)

__all__ = [
    "BEHIND_SHOULDER_TOL",
    "DH",
    "DH_2021",
    "DH_CLASSIC",
    "JOINT_LIMITS",
    "BehindShoulder",
    "Joints",
    "Limits",
    "OutOfLimits",
    "Pose",
    "Unreachable",
    "firmware_pose",
    "forward",
    "forward_many",
    "in_limits",
    "inverse",
    "inverse_all",
    "line_reachable",
    "matrix_to_rpy",
    "rpy_to_matrix",
    "sample_line",
]

Joints: TypeAlias = tuple[float, float, float, float, float, float]
"""Joint angles J1..J6 in degrees."""
Pose: TypeAlias = tuple[float, float, float, float, float, float]
"""Cartesian pose x, y, z (mm), rx, ry, rz (degrees, fixed-axis RPY)."""
Limits: TypeAlias = Sequence[tuple[float, float]]
"""Per-joint ``(low, high)`` ranges in degrees, J1..J6."""
FloatArray: TypeAlias = npt.NDArray[np.float64]

JOINT_LIMITS: tuple[tuple[float, float], ...] = (
    (-100.0, 160.0), (-30.0, 70.0), (-170.0, 60.0),
    (-350.0, 350.0), (-205.0, 36.0), (-360.0, 360.0),
)  # fmt: skip
"""Factory joint ranges J1..J6 in degrees (PROTOCOL section 7, settings ``$130..$146``)."""

_DEG = math.pi / 180.0
_RAD = 180.0 / math.pi

#: ASSUMED: |cos(q5)| below which the wrist counts as singular (q5 = +-90) and q4 is pinned.
#: The firmware's own threshold is unknown; 1e-9 only catches poses that are singular to rounding.
SINGULAR_EPS = 1e-9
#: Tolerance (degrees) when testing joint limits, so that a limit value itself survives rounding.
LIMIT_TOL = 1e-6
#: Relative slack on the law of cosines before a pose is declared unreachable (rounding only).
_REACH_EPS = 1e-12
#: Solutions closer than this (degrees, every joint) are duplicates (singular branches coincide).
_DUP_TOL = 1e-9
#: How far (mm) a wrist centre may lie behind the shoulder before the mirrored pose counts.
BEHIND_SHOULDER_TOL = 1e-6


@dataclass(frozen=True, slots=True)
class DH:
    """The six lengths (mm) of the Mirobot's modified DH table (PROTOCOL 8.1).

    ``l`` is the flange offset along z6; it is negative because z6 points back up the wrist.
    """

    d1: float
    a1: float
    a2: float
    a3: float
    d4: float
    l: float  # noqa: E741 - the firmware's own name for the length

    @classmethod
    def from_settings(cls, settings: Mapping[int, float]) -> DH:
        """Build from the 2021 settings ``{29: D1, 30: A1, 31: A2, 32: A3, 33: D4, 34: L}``."""
        try:
            values = [float(settings[n]) for n in (29, 30, 31, 32, 33, 34)]
        except KeyError as exc:
            raise MirobotUsageError(f"DH settings lack ${exc.args[0]} (need $29..$34)") from None
        return cls(*values)

    def to_settings(self) -> dict[int, float]:
        """The inverse of :meth:`from_settings`."""
        return {29: self.d1, 30: self.a1, 31: self.a2, 32: self.a3, 33: self.d4, 34: self.l}

    @property
    def forearm(self) -> float:
        """Length from the elbow axis to the wrist centre, ``sqrt(A3^2 + D4^2)``."""
        return math.hypot(self.a3, self.d4)


DH_2021 = DH(127.0, 29.69, 108.0, 20.0, 168.98, -24.28)
"""Geometry of firmware 20210516 (the 2021 profile)."""
DH_CLASSIC = DH(78.0, 32.0, 108.0, 20.0, 170.0, -25.0)
"""Geometry of firmware 20191228_2 (the classic profile)."""

_Rows: TypeAlias = tuple[
    tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]
]


# --------------------------------------------------------------------------------------------
# Orientation helpers


def _rpy_rows(rx: float, ry: float, rz: float) -> _Rows:
    """``Rz(rz) Ry(ry) Rx(rx)`` (degrees) as plain row tuples."""
    cx, sx = math.cos(rx * _DEG), math.sin(rx * _DEG)
    cy, sy = math.cos(ry * _DEG), math.sin(ry * _DEG)
    cz, sz = math.cos(rz * _DEG), math.sin(rz * _DEG)
    return (
        (cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx),
        (sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx),
        (-sy, cy * sx, cy * cx),
    )


def _rows_rpy(
    r00: float, r10: float, r20: float, r21: float, r22: float
) -> tuple[float, float, float]:
    """PROTOCOL 8.2 extraction of (rx, ry, rz) in degrees from the five entries it needs."""
    rx = math.atan2(r21, r22) * _RAD
    ry = math.atan2(-r20, math.sqrt(r21 * r21 + r22 * r22)) * _RAD
    rz = math.atan2(r10, r00) * _RAD
    return rx, ry, rz


def rpy_to_matrix(rx: float, ry: float, rz: float) -> FloatArray:
    """Rotation matrix of fixed-axis roll/pitch/yaw (degrees): ``Rz(rz) @ Ry(ry) @ Rx(rx)``."""
    return np.array(_rpy_rows(rx, ry, rz), dtype=np.float64)


def matrix_to_rpy(matrix: npt.ArrayLike) -> tuple[float, float, float]:
    """Fixed-axis (rx, ry, rz) in degrees of a 3x3 rotation matrix, as the firmware prints them.

    At ry = +-90 (gimbal lock) the split between rx and rz is whatever the formula gives.
    """
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape != (3, 3):
        raise MirobotUsageError(f"expected a 3x3 rotation matrix, got shape {m.shape}")
    return _rows_rpy(float(m[0, 0]), float(m[1, 0]), float(m[2, 0]), float(m[2, 1]), float(m[2, 2]))


def _wrap180(angle: float) -> float:
    """Normalise degrees to (-180, 180]."""
    a = math.fmod(angle, 360.0)
    if a <= -180.0:
        a += 360.0
    elif a > 180.0:
        a -= 360.0
    return a + 0.0  # turns -0.0 into 0.0


# --------------------------------------------------------------------------------------------
# Forward kinematics


def _check_vector(values: Iterable[float], what: str) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise MirobotUsageError(f"{what} must be numbers, got {values!r}") from None
    if not all(math.isfinite(v) for v in out):
        raise MirobotUsageError(f"{what} must be finite, got {out!r}")
    return out


def _fk_frame(q: Sequence[float], dh: DH) -> tuple[_Rows, tuple[float, float, float]]:
    """Rotation R06 and flange position of joints ``q`` (closed form of the MDH chain)."""
    q1, q2, q3, q4, q5, q6 = (v * _DEG for v in q)
    c1, s1 = math.cos(q1), math.sin(q1)
    c2, s2 = math.cos(q2), math.sin(q2)
    c23, s23 = math.cos(q2 + q3), math.sin(q2 + q3)
    c4, s4 = math.cos(q4), math.sin(q4)
    c5, s5 = math.cos(q5), math.sin(q5)
    c6, s6 = math.cos(q6), math.sin(q6)
    # R36 (derived from the table: alpha3 = -90, theta5 = q5 + 90, alpha5 = +90).
    m00 = s4 * s6 - c4 * s5 * c6
    m01 = c4 * s5 * s6 + s4 * c6
    m02 = c4 * c5
    m10 = c5 * c6
    m11 = -c5 * s6
    m12 = s5
    m20 = s4 * s5 * c6 + c4 * s6
    m21 = c4 * c6 - s4 * s5 * s6
    m22 = -s4 * c5
    # R03 = [[c1 s23, c1 c23, -s1], [s1 s23, s1 c23, c1], [c23, -s23, 0]]; R06 = R03 R36.
    u0 = s23 * m00 + c23 * m10  # planar combination shared by rows 0 and 1
    u1 = s23 * m01 + c23 * m11
    u2 = s23 * m02 + c23 * m12
    r00, r01, r02 = c1 * u0 - s1 * m20, c1 * u1 - s1 * m21, c1 * u2 - s1 * m22
    r10, r11, r12 = s1 * u0 + c1 * m20, s1 * u1 + c1 * m21, s1 * u2 + c1 * m22
    r20 = c23 * m00 - s23 * m10
    r21 = c23 * m01 - s23 * m11
    r22 = c23 * m02 - s23 * m12
    # Wrist centre in the arm plane, then the flange point w + L * z6.
    radial = dh.a1 + dh.a2 * s2 + dh.a3 * s23 + dh.d4 * c23
    height = dh.d1 + dh.a2 * c2 + dh.a3 * c23 - dh.d4 * s23
    x = c1 * radial + dh.l * r02
    y = s1 * radial + dh.l * r12
    z = height + dh.l * r22
    return ((r00, r01, r02), (r10, r11, r12), (r20, r21, r22)), (x, y, z)


def forward(
    joints: Sequence[float],
    dh: DH = DH_2021,
    tool: Sequence[float] = (0.0, 0.0, 0.0),
) -> Pose:
    """Pose ``(x, y, z, rx, ry, rz)`` of the tool point for joints J1..J6 (degrees).

    Plain ``math`` on floats (a few microseconds) because the emulator calls it for every status
    report. ``tool`` is an offset in the flange frame.
    """
    if len(joints) != 6:
        raise MirobotUsageError(f"forward() needs 6 joint angles, got {len(joints)}")
    rows, (x, y, z) = _fk_frame(joints, dh)
    tx, ty, tz = tool
    if tx or ty or tz:
        x += rows[0][0] * tx + rows[0][1] * ty + rows[0][2] * tz
        y += rows[1][0] * tx + rows[1][1] * ty + rows[1][2] * tz
        z += rows[2][0] * tx + rows[2][1] * ty + rows[2][2] * tz
    rx, ry, rz = _rows_rpy(rows[0][0], rows[1][0], rows[2][0], rows[2][1], rows[2][2])
    # "+ 0.0" turns -0.0 into 0.0, so that a printed status never shows "-0.000" for an exact 0.
    return (x + 0.0, y + 0.0, z + 0.0, rx + 0.0, ry + 0.0, rz + 0.0)


def forward_many(
    joints: npt.ArrayLike,
    dh: DH = DH_2021,
    tool: Sequence[float] = (0.0, 0.0, 0.0),
) -> FloatArray:
    """Vectorised :func:`forward`: an ``(N, 6)`` array of joints to an ``(N, 6)`` array of poses."""
    q = np.asarray(joints, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 6:
        raise MirobotUsageError(f"forward_many() needs an (N, 6) array, got shape {q.shape}")
    r = np.radians(q)
    c1, s1 = np.cos(r[:, 0]), np.sin(r[:, 0])
    c2, s2 = np.cos(r[:, 1]), np.sin(r[:, 1])
    q23 = r[:, 1] + r[:, 2]
    c23, s23 = np.cos(q23), np.sin(q23)
    c4, s4 = np.cos(r[:, 3]), np.sin(r[:, 3])
    c5, s5 = np.cos(r[:, 4]), np.sin(r[:, 4])
    c6, s6 = np.cos(r[:, 5]), np.sin(r[:, 5])
    m00 = s4 * s6 - c4 * s5 * c6
    m01 = c4 * s5 * s6 + s4 * c6
    m02 = c4 * c5
    m10 = c5 * c6
    m11 = -c5 * s6
    m12 = s5
    m20 = s4 * s5 * c6 + c4 * s6
    m21 = c4 * c6 - s4 * s5 * s6
    m22 = -s4 * c5
    u0 = s23 * m00 + c23 * m10
    u1 = s23 * m01 + c23 * m11
    u2 = s23 * m02 + c23 * m12
    r00, r01, r02 = c1 * u0 - s1 * m20, c1 * u1 - s1 * m21, c1 * u2 - s1 * m22
    r10, r11, r12 = s1 * u0 + c1 * m20, s1 * u1 + c1 * m21, s1 * u2 + c1 * m22
    r20 = c23 * m00 - s23 * m10
    r21 = c23 * m01 - s23 * m11
    r22 = c23 * m02 - s23 * m12
    radial = dh.a1 + dh.a2 * s2 + dh.a3 * s23 + dh.d4 * c23
    tx, ty, tz = (float(v) for v in tool)
    out = np.empty_like(q)
    out[:, 0] = c1 * radial + dh.l * r02 + r00 * tx + r01 * ty + r02 * tz
    out[:, 1] = s1 * radial + dh.l * r12 + r10 * tx + r11 * ty + r12 * tz
    out[:, 2] = (dh.d1 + dh.a2 * c2 + dh.a3 * c23 - dh.d4 * s23) + dh.l * r22
    out[:, 2] += r20 * tx + r21 * ty + r22 * tz
    out[:, 3] = np.degrees(np.arctan2(r21, r22))
    out[:, 4] = np.degrees(np.arctan2(-r20, np.sqrt(r21 * r21 + r22 * r22)))
    out[:, 5] = np.degrees(np.arctan2(r10, r00))
    out += 0.0  # -0.0 -> 0.0, as in forward()
    return out


# --------------------------------------------------------------------------------------------
# Inverse kinematics


def _fmt(values: Sequence[float]) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in values) + ")"


def _solve(
    pose: Sequence[float],
    dh: DH,
    tool: Sequence[float],
    *,
    q1_singular: float = 0.0,
    q4_singular: float = 0.0,
) -> list[tuple[Joints, bool, bool, bool]]:
    """Every analytic solution as ``(joints, shoulder_front, elbow_up, wrist_unflipped)``.

    The firmware branch is the first entry. Angles are normalised to (-180, 180]. When the wrist
    centre lies on the J1 axis q1 is ``q1_singular``; at the wrist singularity (q5 = +-90) q4 is
    ``q4_singular`` and q6 absorbs the rest. Raises :class:`Unreachable`.
    """
    if len(pose) != 6:
        raise MirobotUsageError(f"a pose needs 6 numbers (x, y, z, rx, ry, rz), got {len(pose)}")
    x, y, z, rx, ry, rz = _check_vector(pose, "pose")
    tx, ty, tz = _check_vector(tool, "tool offset")
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = _rpy_rows(rx, ry, rz)
    # Flange point, then wrist centre w = p - L * z6.
    px = x - (r00 * tx + r01 * ty + r02 * tz)
    py = y - (r10 * tx + r11 * ty + r12 * tz)
    pz = z - (r20 * tx + r21 * ty + r22 * tz)
    wx, wy, wz = px - dh.l * r02, py - dh.l * r12, pz - dh.l * r22

    a2, k = dh.a2, dh.forearm
    if a2 <= 0.0 or k <= 0.0:
        raise MirobotUsageError(f"degenerate DH geometry {dh!r}: A2 and the forearm must be > 0")
    beta = math.atan2(dh.d4, dh.a3)  # angle of the forearm vector (A3, D4) from the arm's x axis
    rho = math.hypot(wx, wy)
    q1_front = math.atan2(wy, wx) if rho > 1e-12 else q1_singular * _DEG
    h = wz - dh.d1

    out: list[tuple[Joints, bool, bool, bool]] = []
    for front in (True, False):
        q1 = q1_front if front else q1_front + math.pi
        r = (rho if front else -rho) - dh.a1
        cos_phi = (r * r + h * h - a2 * a2 - k * k) / (2.0 * a2 * k)
        if abs(cos_phi) > 1.0 + _REACH_EPS:
            continue
        phi0 = math.acos(max(-1.0, min(1.0, cos_phi)))  # phi = q3 + beta, the elbow's bend
        c1, s1 = math.cos(q1), math.sin(q1)
        for elbow_up in (True, False):
            phi = phi0 if elbow_up else -phi0
            q3 = phi - beta
            q2 = math.atan2(r, h) - math.atan2(k * math.sin(phi), a2 + k * math.cos(phi))
            c23, s23 = math.cos(q2 + q3), math.sin(q2 + q3)
            # R36 = R03^T R06, R03 = [[c1 s23, c1 c23, -s1], [s1 s23, s1 c23, c1], [c23, -s23, 0]];
            # only the entries the wrist angles need are formed.
            v0, v1, v2 = c1 * r00 + s1 * r10, c1 * r01 + s1 * r11, c1 * r02 + s1 * r12
            m02 = s23 * v2 + c23 * r22
            m10 = c23 * v0 - s23 * r20
            m11 = c23 * v1 - s23 * r21
            m12 = c23 * v2 - s23 * r22
            m20 = -s1 * r00 + c1 * r10
            m21 = -s1 * r01 + c1 * r11
            m22 = -s1 * r02 + c1 * r12
            c5_abs = math.hypot(m02, m22)
            for unflipped in (True, False):
                if c5_abs < SINGULAR_EPS:
                    # q5 = +-90: only q4 + s5*q6 is defined; pin q4 (the firmware pins it to 0).
                    if not unflipped:
                        continue
                    s5 = 1.0 if m12 >= 0.0 else -1.0
                    q5 = math.copysign(math.pi / 2, s5)
                    q4 = q4_singular * _DEG
                    q6 = math.atan2(m20, m21) - s5 * q4
                else:
                    sign = 1.0 if unflipped else -1.0
                    q5 = math.atan2(m12, sign * c5_abs)
                    q4 = math.atan2(-sign * m22, sign * m02)
                    q6 = math.atan2(-sign * m11, sign * m10)
                joints = (
                    _wrap180(q1 * _RAD),
                    _wrap180(q2 * _RAD),
                    _wrap180(q3 * _RAD),
                    _wrap180(q4 * _RAD),
                    _wrap180(q5 * _RAD),
                    _wrap180(q6 * _RAD),
                )
                out.append((joints, front, elbow_up, unflipped))
    # Stretched arm (cos_phi = +-1): elbow up and down coincide; keep one of each.
    unique: list[tuple[Joints, bool, bool, bool]] = []
    for sol in out:
        if not any(_same_angles(sol[0], u[0]) for u in unique):
            unique.append(sol)
    if not unique:
        raise Unreachable(
            f"pose {_fmt((x, y, z, rx, ry, rz))} is unreachable: no valid value for theta3 "
            f"(wrist centre {_fmt((wx, wy, wz))} is out of the arm's reach)"
        )
    return unique


def _same_angles(a: Sequence[float], b: Sequence[float]) -> bool:
    for u, v in zip(a, b, strict=True):
        d = abs(u - v) % 360.0
        if min(d, 360.0 - d) > _DUP_TOL:
            return False
    return True


def in_limits(joints: Sequence[float], limits: Limits = JOINT_LIMITS) -> bool:
    """True when every joint lies within its ``(low, high)`` range (with a tiny tolerance)."""
    return all(
        lo - LIMIT_TOL <= q <= hi + LIMIT_TOL for q, (lo, hi) in zip(joints, limits, strict=True)
    )


def inverse_all(
    pose: Sequence[float],
    dh: DH = DH_2021,
    tool: Sequence[float] = (0.0, 0.0, 0.0),
) -> list[Joints]:
    """All analytic IK solutions of ``pose`` (up to 8), angles in (-180, 180], not range-filtered.

    Order: shoulder front before back, elbow up before down, wrist unflipped before flipped; so
    the first entry is the firmware's choice. At the wrist singularity there is one solution per
    arm configuration, with q4 = 0. Raises :class:`Unreachable` outside the workspace.
    """
    return [sol[0] for sol in _solve(pose, dh, tool)]


def _nearest_wrap(value: float, target: float, lo: float, hi: float) -> float | None:
    """``value + 360 k`` nearest to ``target`` within ``[lo, hi]``; None when no k fits."""
    base = value + 360.0 * round((target - value) / 360.0)
    candidates = [base + 360.0 * k for k in (-2, -1, 0, 1, 2)]
    fitting = [c for c in candidates if lo - LIMIT_TOL <= c <= hi + LIMIT_TOL]
    if not fitting:
        return None
    return min(fitting, key=lambda c: abs(c - target))


def inverse(
    pose: Sequence[float],
    dh: DH = DH_2021,
    branch: Literal["firmware", "nearest"] = "firmware",
    current: Sequence[float] | None = None,
    tool: Sequence[float] = (0.0, 0.0, 0.0),
    limits: Limits | None = None,
) -> Joints:
    """One IK solution of ``pose``.

    ``branch="firmware"`` reproduces the arm (PROTOCOL 8.3): shoulder front, elbow up,
    q5 in [-90, 90], q4 = 0 at the wrist singularity; with ``limits`` that solution must be in
    range (no other branch is tried, as on the arm), else :class:`OutOfLimits`.

    ``branch="nearest"`` returns the solution closest (Euclidean, degrees) to ``current``
    (default: all zero), each joint shifted by multiples of 360 to lie nearest to ``current``;
    with ``limits`` only in-range candidates count. At singularities the free joint (q1 or q4)
    keeps its current value.

    Raises :class:`Unreachable` when no solution exists, :class:`OutOfLimits` when none is in range.
    """
    if branch == "firmware":
        solution = _solve(pose, dh, tool)[0][0]  # Unreachable first: mirroring keeps the reach
        actual = firmware_pose(pose, dh, tool)
        if actual is not None:
            raise BehindShoulder(
                f"pose {_fmt(pose)}: its wrist centre lies behind the shoulder (within "
                f"A1 = {dh.a1:g} mm of the base axis); the firmware solves it as the mirrored "
                f"pose {_fmt(actual)} and the arm would go there instead",
                actual,
            )
        if limits is not None and not in_limits(solution, limits):
            bad = _first_violation(solution, limits)
            raise OutOfLimits(
                f"pose {_fmt(pose)}: there is one angle out of limit (J{bad + 1} = "
                f"{solution[bad]:.3f} outside {_fmt(limits[bad])}; joints {_fmt(solution)})"
            )
        return solution
    if branch != "nearest":
        raise MirobotUsageError(f"unknown IK branch {branch!r} (use 'firmware' or 'nearest')")

    ref = (0.0,) * 6 if current is None else _check_vector(current, "current joints")
    if len(ref) != 6:
        raise MirobotUsageError(f"current joints need 6 angles, got {len(ref)}")
    rng: Limits = limits if limits is not None else ((-math.inf, math.inf),) * 6
    best: Joints | None = None
    best_dist = math.inf
    for sol, *_ in _solve(pose, dh, tool, q1_singular=ref[0], q4_singular=ref[3]):
        shifted: list[float] = []
        for value, target, (lo, hi) in zip(sol, ref, rng, strict=True):
            wrapped = _nearest_wrap(value, target, lo, hi)
            if wrapped is None:
                break
            shifted.append(wrapped)
        else:
            dist = math.fsum((a - b) ** 2 for a, b in zip(shifted, ref, strict=True))
            if dist < best_dist:
                best_dist = dist
                best = (shifted[0], shifted[1], shifted[2], shifted[3], shifted[4], shifted[5])
    if best is None:
        raise OutOfLimits(f"pose {_fmt(pose)}: every IK solution has one angle out of limit")
    return best


def firmware_pose(
    pose: Sequence[float], dh: DH = DH_2021, tool: Sequence[float] = (0.0, 0.0, 0.0)
) -> Pose | None:
    """The pose the arm goes to when asked for ``pose`` if that is another one (the wrist centre
    mirrored in front of the shoulder, same azimuth and orientation: :class:`BehindShoulder`),
    else None (the usual case)."""
    if len(pose) != 6:
        raise MirobotUsageError(f"a pose needs 6 numbers (x, y, z, rx, ry, rz), got {len(pose)}")
    x, y, z, rx, ry, rz = _check_vector(pose, "pose")
    tx, ty, tz = _check_vector(tool, "tool offset")
    (r00, r01, r02), (r10, r11, r12), _ = _rpy_rows(rx, ry, rz)
    wx = x - (r00 * tx + r01 * ty + r02 * tz) - dh.l * r02
    wy = y - (r10 * tx + r11 * ty + r12 * tz) - dh.l * r12
    rho = math.hypot(wx, wy)
    if rho >= dh.a1 - BEHIND_SHOULDER_TOL:
        return None
    ux, uy = (wx / rho, wy / rho) if rho > 1e-12 else (1.0, 0.0)  # on the axis: J1 = 0
    shift = 2.0 * (dh.a1 - rho)  # from rho to the mirrored distance 2 * A1 - rho
    return (x + ux * shift, y + uy * shift, z, rx, ry, rz)


def _first_violation(joints: Sequence[float], limits: Limits) -> int:
    for i, (q, (lo, hi)) in enumerate(zip(joints, limits, strict=True)):
        if not lo - LIMIT_TOL <= q <= hi + LIMIT_TOL:
            return i
    return 0


# --------------------------------------------------------------------------------------------
# Straight lines


def sample_line(
    start_pose: Sequence[float],
    end_pose: Sequence[float],
    step_mm: float = 2.0,
    *,
    step_deg: float = 2.0,
) -> FloatArray:
    """Poses along the straight line from ``start_pose`` to ``end_pose``, both included.

    Samples are evenly spaced in the line parameter, at most ``step_mm`` apart in position and
    ``step_deg`` in each orientation component (so a pure re-orientation is sampled too).
    ASSUMED (PROTOCOL 9 and the G91 semantics of 8.2): orientation is interpolated linearly and
    component-wise on (rx, ry, rz), without wrapping at +-180, as the firmware's own numbers are.
    """
    if not (step_mm > 0 and step_deg > 0):
        raise MirobotUsageError(f"sample steps must be > 0, got {step_mm} mm / {step_deg} deg")
    a = np.asarray(_check_vector(start_pose, "start pose"), dtype=np.float64)
    b = np.asarray(_check_vector(end_pose, "end pose"), dtype=np.float64)
    if a.shape != (6,) or b.shape != (6,):
        raise MirobotUsageError("sample_line() needs two 6-number poses")
    delta = b - a
    dist = float(np.linalg.norm(delta[:3]))
    turn = float(np.max(np.abs(delta[3:])))
    n = max(1, math.ceil(dist / step_mm - 1e-9), math.ceil(turn / step_deg - 1e-9))
    t = np.linspace(0.0, 1.0, n + 1)
    out: FloatArray = a[None, :] + t[:, None] * delta[None, :]
    out[-1] = b  # exact end point
    return out


def line_reachable(
    start_pose: Sequence[float],
    end_pose: Sequence[float],
    dh: DH = DH_2021,
    step_mm: float = 2.0,
    limits: Limits | None = JOINT_LIMITS,
    tool: Sequence[float] = (0.0, 0.0, 0.0),
) -> bool:
    """True when every sample of the line has a firmware-branch IK solution within ``limits``."""
    for pose in sample_line(start_pose, end_pose, step_mm):
        try:
            inverse(tuple(float(v) for v in pose), dh, "firmware", tool=tool, limits=limits)
        except MirobotUsageError:
            return False
    return True
