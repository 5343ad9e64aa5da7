"""The workspace safety envelope: refuse a move before it is sent if it would leave allowed space.

An :class:`Envelope` has three optional parts:

- **joint limits**: the firmware's ranges (:data:`~mirobot_async.kinematics.JOINT_LIMITS`) by
  default; an envelope may only *narrow* them;
- **a Cartesian box** for the tool point (the x, y, z of forward kinematics including the tool
  offset, in the arm's base frame, the frame of the status report's pose). Each side of each axis
  is optional: ``z=(20, None)`` is "at least 20 mm above the table", ``x=None`` no bound on x;
- **a rail range** (the D axis, mm).

Semantics of the checks (each raises :class:`~mirobot_async.errors.MirobotUsageError` naming the
violated bound, and returns ``None`` when the move is allowed):

- **Joint moves** (``M21``, and the joint-space motion of a Cartesian ``G0``) are checked by their
  target: joint limits, rail range, and the tool point at the target inside the box. When the start
  joints are known the straight joint-space path is sampled too (linear joint interpolation, as the
  firmware moves), so that the tool point may not leave the box on the way.
- **Cartesian linear moves** (2021 ``M20 G1`` with ``$35=1``; the classic firmware's ``M20 G1``
  is a joint move, checked as one) and **arcs** (``G2``/``G3``) are checked by samples of
  the path, at most ``path_step_mm`` apart: every sample in the box, and every sample's
  firmware-branch IK (PROTOCOL 8.3) reachable and within the joint limits. The box test of lines and
  arcs is exact (a box is convex; an arc's extreme points are added to its samples).
- **Sampling limit**: joint-space paths and the IK of path samples are only checked at the
  samples; a violation shallower than about ``path_step_mm / 2`` between two samples can pass.
- **Recovery**: a move whose start is already outside the envelope (after homing, after an
  opt-out, or when the envelope was made while the arm was elsewhere) is allowed if its target is
  inside and, along the way, it never goes farther outside any bound than where it started.
- **Relative moves** (``G91``) are checked against the last known position, which the caller
  passes (``current_joints`` / ``current_pose``); without it they are refused.
- **Raw lines** (``Mirobot.send``, ``stream``) are checked **default-deny** by the client's
  guard with :func:`mirobot_async._safety.prediction.predict`: a line is let
  through only when its exact effect is predicted from the modal state (:class:`MotionModes`:
  M20/M21, G90/G91, G0..G5, G20/G21, any of them possibly unknown), the position, the 2021 base
  offset ``$41..$43`` and what the firmware stores (work offsets, startup lines, soft limits,
  ``$35``: :mod:`mirobot_async._safety.firmware_memory`); everything it cannot model is refused
  (see :mod:`mirobot_async._safety.prediction`). The opt-out is ``Mirobot.send(line,
  check_envelope=False)``, which logs a WARNING.
- **Bounded work**: at most :data:`~mirobot_async._safety.paths.MAX_PATH_SAMPLES` samples per
Cartesian
  path (longer paths are refused: split them) and
  :data:`~mirobot_async._safety.paths.MAX_JOINT_PATH_SAMPLES` per joint-space path (sampled coarser
  beyond); absurd values are refused before any sampling.
- ASSUMED: homing (any ``$H...`` line) passes: its path to the switches cannot be bounded; it
  resets the modes and leaves the position unknown until the next status.

The envelope's ``dh`` and ``tool`` must match the robot's settings (``$29..$34``, ``$46..$48``):
the box is checked on the envelope's own kinematic model. Pure module: no I/O, no asyncio.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Final, TypeAlias

import numpy as np
import numpy.typing as npt

from mirobot_async._core.acceptance import update_modes
from mirobot_async._core.modal import LineCheck, MotionModes
from mirobot_async._core.values import fmt_number
from mirobot_async._safety.paths import (
    MAX_JOINT_PATH_SAMPLES,
    MAX_PATH_SAMPLES,
    arc_plan,
    arc_samples,
    firmware_ik_rows,
    line_samples,
    line_samples_needed,
)
from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import (
    DH,
    DH_2021,
    JOINT_LIMITS,
    LIMIT_TOL,
    Joints,
    Pose,
    forward,
    forward_many,
    inverse,
)

__all__ = [
    "Bound",
    "Envelope",
    "LineCheck",
    "MotionModes",
    "update_modes",
]

Bound: TypeAlias = tuple[float | None, float | None]
"""``(low, high)``; ``None`` on a side means no bound on that side."""
FloatArray: TypeAlias = npt.NDArray[np.float64]

BOX_TOL: Final = 1e-6
"""Tolerance (mm) of the box test, so that a bound value itself survives rounding."""
_AXES: Final = ("x", "y", "z")
_ZERO_JOINTS: Final[Joints] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def _num(value: float) -> str:
    """A bound for a message: short, exact, no exponent (``20``, ``-30``, ``198.67``)."""
    return fmt_number(value, 6)


def _real(value: object, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise MirobotUsageError(f"{what}={value!r} must be a number")
    out = float(value)
    if not math.isfinite(out):
        raise MirobotUsageError(f"{what}={out!r} must be a finite number")
    return out


def _vector(values: object, n: int, what: str) -> tuple[float, ...]:
    if not isinstance(values, Sequence | np.ndarray) or isinstance(values, str | bytes):
        raise MirobotUsageError(f"{what} must be {n} numbers, got {values!r}")
    if len(values) != n:
        raise MirobotUsageError(f"{what} must be {n} numbers, got {len(values)}")
    return tuple(_real(v, f"{what}[{i}]") for i, v in enumerate(values))


def _joints6(values: object, what: str) -> Joints:
    q = _vector(values, 6, what)
    return (q[0], q[1], q[2], q[3], q[4], q[5])


def _pose6(values: object, what: str) -> Pose:
    p = _vector(values, 6, what)
    return (p[0], p[1], p[2], p[3], p[4], p[5])


def _fmt(values: Sequence[float]) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in values) + ")"


def _bound(value: object, what: str) -> Bound | None:
    """Validate an optional ``(low, high)`` pair with optional sides."""
    if value is None:
        return None
    if not isinstance(value, Sequence) or isinstance(value, str | bytes) or len(value) != 2:
        raise MirobotUsageError(f"{what}={value!r} must be a (low, high) pair or None")
    lo = None if value[0] is None else _real(value[0], f"{what} low")
    hi = None if value[1] is None else _real(value[1], f"{what} high")
    if lo is not None and hi is not None and lo > hi:
        raise MirobotUsageError(f"{what}=({_num(lo)}, {_num(hi)}): low is above high")
    return (lo, hi)


# --------------------------------------------------------------------------------------------
# The envelope


@dataclass(frozen=True, slots=True)
class Envelope:
    """Allowed space: optional box for the tool point, joint limits (narrowing only), rail range.

    ``x``/``y``/``z``/``rail`` are ``(low, high)`` with ``None`` for an open side, or ``None``.
    ``joints`` maps joint numbers 1..6 to ``(low, high)`` (``None`` side = the firmware's value).
    Raises MirobotUsageError for a reversed, non-finite or widened range or an unknown joint.
    """

    x: Bound | None = None
    y: Bound | None = None
    z: Bound | None = None
    joints: Mapping[int, Bound] | None = field(default=None, compare=False, hash=False)
    rail: Bound | None = None
    dh: DH = DH_2021
    tool: tuple[float, float, float] = (0.0, 0.0, 0.0)
    path_step_mm: float = 2.0
    joint_limits: tuple[tuple[float, float], ...] = field(init=False)
    """The effective J1..J6 ranges in degrees (firmware ranges narrowed by ``joints``)."""
    _lo: tuple[float, float, float] = field(init=False, repr=False, compare=False)
    _hi: tuple[float, float, float] = field(init=False, repr=False, compare=False)
    _reach: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        boxes = [_bound(getattr(self, a), a) for a in _AXES]
        for name, box in zip(_AXES, boxes, strict=True):
            set_(self, name, box)
        set_(self, "rail", _bound(self.rail, "rail"))
        lo = tuple(-math.inf if b is None or b[0] is None else b[0] for b in boxes)
        hi = tuple(math.inf if b is None or b[1] is None else b[1] for b in boxes)
        set_(self, "_lo", lo)
        set_(self, "_hi", hi)
        if not isinstance(self.dh, DH):
            raise MirobotUsageError(f"dh={self.dh!r} must be a kinematics.DH")
        tool = _vector(self.tool, 3, "tool")
        set_(self, "tool", (tool[0], tool[1], tool[2]))
        step = _real(self.path_step_mm, "path_step_mm")
        if step <= 0:
            raise MirobotUsageError(f"path_step_mm={_num(step)} must be > 0")
        set_(self, "path_step_mm", step)
        set_(self, "joint_limits", self._narrow(self.joints))
        if self.joints is not None:
            set_(self, "joints", MappingProxyType(dict(self.joints)))
        dh = self.dh
        # Upper bound of the tool point's distance from any joint axis (for joint-path sampling).
        reach = abs(dh.a1) + abs(dh.a2) + dh.forearm + abs(dh.l) + math.hypot(*self.tool)
        set_(self, "_reach", reach)

    @staticmethod
    def _narrow(joints: object) -> tuple[tuple[float, float], ...]:
        limits = [tuple(r) for r in JOINT_LIMITS]
        if joints is None:
            return tuple((lo, hi) for lo, hi in limits)
        if not isinstance(joints, Mapping):
            raise MirobotUsageError(f"joints={joints!r} must be a mapping {{1: (low, high), ...}}")
        for key, value in joints.items():
            if isinstance(key, bool) or not isinstance(key, int) or not 1 <= key <= 6:
                raise MirobotUsageError(f"joints has key {key!r}: joint numbers are 1..6")
            pair = _bound(value, f"joints[{key}]")
            if pair is None:
                continue
            fw_lo, fw_hi = JOINT_LIMITS[key - 1]
            shown = ", ".join("None" if v is None else _num(v) for v in pair)
            for value in pair:
                if value is not None and not fw_lo <= value <= fw_hi:
                    raise MirobotUsageError(
                        f"joints[{key}]=({shown}) is wider than the firmware's J{key} range "
                        f"{_num(fw_lo)}..{_num(fw_hi)} deg: an envelope may only narrow the "
                        "joint limits"
                    )
            lo = fw_lo if pair[0] is None else pair[0]
            hi = fw_hi if pair[1] is None else pair[1]
            limits[key - 1] = (lo, hi)
        return tuple((lo, hi) for lo, hi in limits)

    # ----------------------------------------------------------------------------------------
    # Elementary tests

    @property
    def has_box(self) -> bool:
        """True when at least one side of the Cartesian box is bounded."""
        return any(math.isfinite(v) for v in (*self._lo, *self._hi))

    def joint_problem(self, q: Sequence[float], what: str, prefix: str = "") -> str | None:
        for i, (value, (lo, hi)) in enumerate(zip(q, self.joint_limits, strict=True)):
            if not lo - LIMIT_TOL <= value <= hi + LIMIT_TOL:
                return (
                    f"{prefix}j{i + 1}={value:.3f} is outside the envelope's J{i + 1} range "
                    f"{_num(lo)}..{_num(hi)} deg ({what})"
                )
        return None

    def rail_problem(self, rail: float | None, what: str) -> str | None:
        if rail is None or self.rail is None:
            return None
        lo, hi = self.rail
        if lo is not None and rail < lo - BOX_TOL:
            return (
                f"rail d={rail:.3f} mm is below the envelope's minimum rail={_num(lo)} mm ({what})"
            )
        if hi is not None and rail > hi + BOX_TOL:
            return (
                f"rail d={rail:.3f} mm is above the envelope's maximum rail={_num(hi)} mm ({what})"
            )
        return None

    def _excess(self, points: FloatArray) -> FloatArray:
        """``(N, 6)`` amounts by which points exceed each side: x low, x high, y low, ..."""
        lo = np.asarray(self._lo)
        hi = np.asarray(self._hi)
        out = np.empty((points.shape[0], 6), dtype=np.float64)
        out[:, 0::2] = lo[None, :] - points[:, :3]
        out[:, 1::2] = points[:, :3] - hi[None, :]
        return out

    def _box_message(self, side: int, point: Sequence[float], subject: str, what: str) -> str:
        axis = _AXES[side // 2]
        value = point[side // 2]
        if side % 2 == 0:
            where, bound = "below the envelope's minimum", self._lo[side // 2]
        else:
            where, bound = "above the envelope's maximum", self._hi[side // 2]
        return f"{subject} {axis}={value:.3f} mm is {where} {axis}={_num(bound)} mm ({what})"

    def box_problem(self, point: Sequence[float], what: str, subject: str = "target") -> str | None:
        if not self.has_box:
            return None
        excess = self._excess(np.asarray([point[:3]], dtype=np.float64))[0]
        side = int(np.argmax(excess))
        if excess[side] > BOX_TOL:
            return self._box_message(side, point, subject, what)
        return None

    def path_box_problem(self, points: FloatArray, what: str, kind: str) -> str | None:
        """Samples (row 0 = start) inside the box, or no farther out than the start on any side."""
        if not self.has_box or len(points) == 0:
            return None
        excess = self._excess(points)
        allowed = np.maximum(excess[0], 0.0) + BOX_TOL
        bad = excess[1:] > allowed[None, :]
        if not bad.any():
            return None
        row, side = (int(v) for v in np.argwhere(bad)[0])
        point = points[row + 1]
        pct = 100.0 * (row + 1) / max(1, len(points) - 1)
        subject = f"the {kind} reaches (at {pct:.0f}% of the way, tool point {_fmt(point[:3])})"
        return self._box_message(side, point, subject, what)

    # ----------------------------------------------------------------------------------------
    # Predicates

    def contains_point(self, point: Sequence[float]) -> bool:
        """True when the point ``(x, y, z)`` (or the position of a 6-number pose) is in the box."""
        values = np.asarray(point, dtype=np.float64)
        if values.ndim != 1 or len(values) not in (3, 6) or not np.isfinite(values).all():
            raise MirobotUsageError(f"a point must be 3 (or 6) finite numbers, got {point!r}")
        return self.box_problem(values.tolist(), "") is None

    def contains_joints(self, joints: Sequence[float], rail: float | None = None) -> bool:
        """True when the joints are within the limits, the rail in range and the tool in the box."""
        q = _joints6(joints, "joints")
        r = None if rail is None else _real(rail, "rail")
        if self.joint_problem(q, "") or self.rail_problem(r, ""):
            return False
        return not self.has_box or self.box_problem(self.tool_point(q), "") is None

    def tool_point(self, joints: Sequence[float]) -> tuple[float, float, float]:
        """The tool point ``(x, y, z)`` of ``joints`` on the envelope's model."""
        x, y, z, *_ = forward(joints, self.dh, self.tool)
        return (x, y, z)

    # ----------------------------------------------------------------------------------------
    # Checks

    def check_joints(
        self,
        target: Sequence[float],
        rail: float | None = None,
        *,
        start: Sequence[float] | None = None,
        what: str = "move",
    ) -> None:
        """Check a joint-space move to ``target`` (J1..J6, degrees) and ``rail`` (mm).

        Joint limits, rail range and the tool point at the target in the box; with ``start`` (the
        current joints) also the tool point along the joint-space path (:meth:`check_joint_path`).
        """
        q = _joints6(target, "target joints")
        r = None if rail is None else _real(rail, "rail")
        problem = self.joint_problem(q, what) or self.rail_problem(r, what)
        if problem is None and self.has_box:
            problem = self.box_problem(self.tool_point(q), what)
        if problem is not None:
            raise MirobotUsageError(problem)
        if start is not None:
            self.check_joint_path(start, q, what=what)

    def joint_path_steps(self, start: Sequence[float], target: Sequence[float]) -> int:
        """Samples needed so the tool point moves at most ``path_step_mm`` between two of them
        (at most :data:`~mirobot_async._safety.paths.MAX_JOINT_PATH_SAMPLES`: bounded work)."""
        turn = sum(abs(b - a) for a, b in zip(start, target, strict=True)) * math.pi / 180.0
        needed = max(1.0, math.ceil(turn * self._reach / self.path_step_mm - 1e-9))
        return int(min(needed, MAX_JOINT_PATH_SAMPLES))

    def check_joint_path(
        self,
        start: Sequence[float],
        target: Sequence[float],
        steps: int | None = None,
        *,
        what: str = "move",
    ) -> None:
        """Check the tool point along the linear joint interpolation ``start`` -> ``target``.

        ``steps`` intervals (default :meth:`joint_path_steps`). Only the box is tested here:
        joint limits of a joint-space line are decided by its end points (:meth:`check_joints`).
        """
        a = np.asarray(_joints6(start, "start joints"))
        b = np.asarray(_joints6(target, "target joints"))
        if not self.has_box:
            return
        n = self.joint_path_steps(a.tolist(), b.tolist()) if steps is None else int(steps)
        n = min(n, MAX_JOINT_PATH_SAMPLES)
        if n < 1:
            raise MirobotUsageError(f"steps={steps!r} must be >= 1")
        t = np.linspace(0.0, 1.0, n + 1)
        samples = a[None, :] + t[:, None] * (b - a)[None, :]
        points = forward_many(samples, self.dh, self.tool)[:, :3]
        problem = self.path_box_problem(points, what, "joint-space path")
        if problem is not None:
            raise MirobotUsageError(problem)

    def _ik(self, pose: Pose, what: str, subject: str) -> Joints:
        try:
            return inverse(pose, self.dh, "firmware", tool=self.tool)
        except MirobotUsageError as exc:
            raise MirobotUsageError(
                f"{subject} {_fmt(pose)} is unreachable ({what}): {exc}"
            ) from None

    def check_pose(
        self,
        pose: Sequence[float],
        *,
        start: Sequence[float] | None = None,
        what: str = "move_pose",
    ) -> None:
        """Check a point-to-point Cartesian move (``M20 G0``) to ``pose`` (x, y, z, rx, ry, rz).

        The position in the box, the firmware-branch IK reachable and within the joint limits; with
        ``start`` (current joints) also the joint-space path to the IK solution.
        """
        self._check_pose(_pose6(pose, "pose"), start, what)

    def _check_pose(self, pose: Pose, start: Sequence[float] | None, what: str) -> Joints:
        problem = self.box_problem(pose, what)
        if problem is not None:
            raise MirobotUsageError(problem)
        q = self._ik(pose, what, "target pose")
        problem = self.joint_problem(q, what, f"target pose {_fmt(pose)} needs (firmware IK) ")
        if problem is not None:
            raise MirobotUsageError(problem)
        if start is not None:
            self.check_joint_path(start, q, what=what)
        return q

    def check_linear_path(
        self, start_pose: Sequence[float], end_pose: Sequence[float], *, what: str = "move_linear"
    ) -> None:
        """Check a straight Cartesian move (``M20 G1``): samples at ``path_step_mm`` in the box,
        each sample's firmware-branch IK reachable and within the joint limits (bounded work)."""
        a = _pose6(start_pose, "start pose")
        b = _pose6(end_pose, "end pose")
        needed = line_samples_needed(a, b, self.path_step_mm)
        self._check_pose_samples(line_samples(a, b, self._bounded(needed, what)), what, "line")

    def _bounded(self, needed: float, what: str) -> int:
        if needed > MAX_PATH_SAMPLES:
            raise MirobotUsageError(
                f"the path needs {needed:.0f} check samples, more than the {MAX_PATH_SAMPLES} the "
                f"envelope checks for one move: split it into shorter moves ({what})"
            )
        return int(needed)

    def _check_pose_samples(self, samples: FloatArray, what: str, kind: str) -> Joints:
        """Box and IK of pose samples (row 0 = start); returns the IK of the last sample."""
        end = (*samples[-1].tolist(),)
        end_pose: Pose = (end[0], end[1], end[2], end[3], end[4], end[5])
        problem = self.box_problem(end_pose, what) or self.path_box_problem(
            samples[:, :3], what, kind
        )
        if problem is not None:
            raise MirobotUsageError(problem)
        rows = firmware_ik_rows(samples, self.dh, self.tool)
        reachable = np.ones(len(rows), dtype=bool)
        for i in np.flatnonzero(np.isnan(rows[:, 0])).tolist():  # singular or back branch
            v = samples[i].tolist()
            pose: Pose = (v[0], v[1], v[2], v[3], v[4], v[5])
            try:
                rows[i] = inverse(pose, self.dh, "firmware", tool=self.tool)
            except MirobotUsageError:
                if i == 0:
                    reachable[0] = False  # an unreachable start: the arm is not there
                    continue
                where = "target pose" if i == len(samples) - 1 else f"the {kind} passes"
                raise MirobotUsageError(
                    f"{where} {_fmt(pose)}, which is unreachable ({what})"
                ) from None
        limits = np.asarray(self.joint_limits)
        excess = np.maximum(limits[None, :, 0] - rows, rows - limits[None, :, 1])
        allowed = np.maximum(excess[0], 0.0) if reachable[0] else np.zeros(6)
        bad = (excess > allowed[None, :] + LIMIT_TOL).any(axis=1)
        bad[0] = False
        bad[-1] = bool((excess[-1] > LIMIT_TOL).any())
        if bad.any():
            i = int(np.argmax(bad))
            v = samples[i].tolist()
            where = "target pose" if i == len(samples) - 1 else f"the {kind} passes"
            prefix = f"{where} {_fmt(v)} with (firmware IK) "
            problem = self.joint_problem(rows[i].tolist(), what, prefix)
            if problem is not None:
                raise MirobotUsageError(problem)
        q = rows[-1].tolist()
        return (q[0], q[1], q[2], q[3], q[4], q[5])

    def check_arc(
        self,
        start_pose: Sequence[float],
        end_pose: Sequence[float],
        radius: float,
        *,
        clockwise: bool,
        what: str = "arc",
    ) -> None:
        """Check a ``G2`` (clockwise) / ``G3`` arc in the XY plane, radius ``R`` (the minor arc).

        ASSUMED (GRBL): z and the orientation are interpolated linearly along the arc.
        """
        a = _pose6(start_pose, "start pose")
        b = _pose6(end_pose, "end pose")
        plan = arc_plan(a, b, _real(radius, "radius"), clockwise, self.path_step_mm)
        if isinstance(plan, str):
            raise MirobotUsageError(f"{plan} ({what})")
        samples = arc_samples(plan, a, b, self._bounded(plan.intervals, what))
        self._check_pose_samples(samples, what, "arc")
