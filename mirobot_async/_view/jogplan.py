"""Hold to jog's motion, pure: the speed of a held jog and how far its next short move goes.

The arm's planner always plans to stand still at the end of what it was given. From a speed
``v`` it brakes in ``v / a`` seconds (``a``: the joint acceleration, :data:`JOINT_ACCEL`) and
covers ``v**2 / (2 a)`` meanwhile, so a queue of motion ``d`` ahead of an arm cruising at ``v``
runs out in ``d / v + v / (2 a)`` seconds. A held jog keeps the queue just above the braking
distance: :func:`next_step` is due only while the queue would run out within one braking time
and one status period, so once the release is known no move is sent and the arm stands still
within about ``v / a`` plus a status period (40 ms + about 10 ms on the virtual arm).

Speeds are chosen in joint space, where the acceleration holds: a joint jogs at
:data:`JOINT_RATE`; a Cartesian jog at the pose rate that moves the joints at most
:data:`CARTESIAN_JOINT_RATE` where the arm is (:func:`pose_sensitivity`, from the firmware's
inverse kinematics), capped at :data:`LINEAR_RATE_MAX` mm/s or :data:`TURN_RATE_MAX` deg/s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final, Literal

from mirobot_async import kinematics
from mirobot_async.errors import MirobotUsageError

__all__ = [
    "CARTESIAN_AXES",
    "CARTESIAN_JOINT_RATE",
    "JOINT_ACCEL",
    "JOINT_RATE",
    "LINEAR_RATE_MAX",
    "TURN_RATE_MAX",
    "CartesianSpeed",
    "JogAxis",
    "angle_delta",
    "brake_seconds",
    "cartesian_speed",
    "firmware_branch",
    "grid_pose",
    "joint_delta",
    "next_step",
    "on_grid",
    "pose_sensitivity",
    "reachable",
    "step_sizes",
]

CARTESIAN_AXES: Final = ("X", "Y", "Z", "RX", "RY", "RZ")

JOINT_RATE: Final = 2.0
"""Joint-space speed of a held jog, deg/s (120 deg/min): it brakes in 40 ms."""
CARTESIAN_JOINT_RATE: Final = 1.5
"""Joint-space speed of a held Cartesian jog, deg/s: it brakes in 30 ms, as its loop is slower
(the arm answers a Cartesian line only once it has solved it: 15 ms a round on the virtual arm,
8 ms for a joint line)."""
JOINT_ACCEL: Final = 50.0
"""The joints' acceleration, deg/s^2: the firmware's default ``$120..$125`` (an arm set to
accelerate more slowly brakes later)."""
LINEAR_RATE_MAX: Final = 5.0
"""Fastest tool speed of a held X, Y or Z jog, mm/s (slower where the joints would exceed
:data:`CARTESIAN_JOINT_RATE`)."""
TURN_RATE_MAX: Final = 2.0
"""Fastest turn of a held RX, RY or RZ jog, deg/s (likewise)."""
MIN_STEP_SECONDS: Final = 0.01
"""Seconds of motion a move of a held jog adds at least (fewer, longer lines on a fast link)."""
_PROBE: Final = 0.01
"""Pose change (mm or deg) over which :func:`pose_sensitivity` differentiates."""
BRANCH_TOLERANCE: Final = 1.0
"""Largest joint gap (deg) between the arm and the firmware's solution of its pose that lets a
Cartesian jog start: beyond it the firmware would first swing the arm over to its own
solution."""


@dataclass(frozen=True, slots=True)
class JogAxis:
    """What a hold button moves: a joint (``index`` 0..5 is J1..J6) or a Cartesian axis of the
    tool's pose (0..5 is X, Y, Z, RX, RY, RZ), toward ``sign`` (+1 or -1)."""

    kind: Literal["joint", "pose"]
    index: int
    sign: int

    @property
    def label(self) -> str:
        """``J1 +``, ``RX -``...: the button's text without `` (hold)``."""
        name = f"J{self.index + 1}" if self.kind == "joint" else CARTESIAN_AXES[self.index]
        return f"{name} {'+' if self.sign > 0 else '-'}"

    @property
    def unit(self) -> str:
        return "mm" if self.kind == "pose" and self.index < 3 else "deg"


_STEPS_SETTING: Final = {0: 104, 1: 105, 2: 106, 3: 100, 4: 101, 5: 102}
"""``$N`` of each joint's steps per degree (the firmware's axis letters a..g are J4, J5, J6,
the rail, J1, J2, J3: ``$100..$106``)."""


def step_sizes(settings: Mapping[int, float]) -> tuple[float, ...]:
    """Degrees per motor step of J1..J6 from the arm's ``$$`` (0 where unknown): the arm
    rounds every target to whole steps (J6: 0.09 deg on the 2021 firmware)."""
    sizes = []
    for joint in range(6):
        per_degree = settings.get(_STEPS_SETTING[joint], 0.0)
        sizes.append(1.0 / per_degree if math.isfinite(per_degree) and per_degree > 0 else 0.0)
    return tuple(sizes)


def on_grid(value: float, step: float) -> float:
    """``value`` rounded to whole motor steps of ``step`` degrees (unchanged when 0)."""
    return round(value / step) * step if step > 0 else value


def grid_pose(
    pose: tuple[float, ...], near: tuple[float, ...], steps: tuple[float, ...], dh: kinematics.DH
) -> tuple[float, ...] | None:
    """Where the arm ends when sent to ``pose`` from ``near`` (joints): the firmware's inverse
    kinematics (J4, J6 kept continuous), rounded to whole motor steps, and back; ``None`` when
    out of reach."""
    try:
        joints = kinematics.inverse(pose, dh, "firmware", limits=kinematics.JOINT_LIMITS)
    except MirobotUsageError:
        return None
    rounded = [
        on_grid(near[i] + joint_delta(joints, near, i), steps[i] if steps else 0.0)
        for i in range(6)
    ]
    return kinematics.forward(rounded, dh)


def brake_seconds(joint_rate: float, accel: float = JOINT_ACCEL) -> float:
    """Seconds the arm takes to stand still from ``joint_rate`` (deg/s, joint space)."""
    return joint_rate / accel


def next_step(ahead: float, room: float, rate: float, brake: float, period: float) -> float:
    """How far the next move of a held jog goes, in the jog's units; 0 when none is due now.

    ``ahead``: the motion queued ahead of the arm along the jog (the target less the position
    of a fresh status); ``room``: how far the edge (the joint's range) lies beyond the target;
    ``rate``: the jog's speed (units/s); ``brake``: :func:`brake_seconds` at that speed;
    ``period``: seconds between the jog's statuses. A move is due while the queue would run
    out within ``brake + period``; it adds a period of motion (at least
    :data:`MIN_STEP_SECONDS`). So the queue stays just above the braking distance (a late
    status lets the arm slow down a little, never run on), and once no move is sent the arm
    stands still within about ``brake + period``.
    """
    if rate <= 0.0 or room <= 0.0:
        return 0.0
    runs_out = max(ahead, 0.0) / rate + brake / 2.0
    if runs_out >= brake + period:
        return 0.0
    return min(rate * max(period, MIN_STEP_SECONDS), room)


@dataclass(frozen=True, slots=True)
class CartesianSpeed:
    """The speed of a held Cartesian jog where the arm is."""

    rate: float
    """Pose units (mm or deg) per second."""
    feed: float
    """The move's ``F``: mm/min for X, Y, Z; for RX, RY, RZ (no translation) the firmware reads
    it as deg/min along the joints' path (as the virtual arm does; if it read it as the turn's
    rate, the joints would still move no faster than :data:`CARTESIAN_JOINT_RATE`, and the turn
    faster)."""
    joint_rate: float
    """The joints' speed, deg/s (its braking: :func:`brake_seconds`)."""


def cartesian_speed(axis: int, sensitivity: float) -> CartesianSpeed:
    """The speed of a held jog of pose ``axis`` (0..5) where moving it one unit moves the
    joints ``sensitivity`` degrees (:func:`pose_sensitivity`)."""
    if axis < 3:
        rate = min(LINEAR_RATE_MAX, CARTESIAN_JOINT_RATE / sensitivity)
        return CartesianSpeed(rate, rate * 60.0, rate * sensitivity)
    feed_rate = min(TURN_RATE_MAX, CARTESIAN_JOINT_RATE / max(1.0, sensitivity))
    return CartesianSpeed(feed_rate / sensitivity, feed_rate * 60.0, feed_rate)


def pose_sensitivity(
    joints: tuple[float, ...], axis: int, sign: int, dh: kinematics.DH
) -> float | None:
    """Degrees the joints move (Euclidean, joint space) per mm or degree of pose ``axis``
    toward ``sign``, where ``joints`` put the arm; ``None`` when the firmware's inverse
    kinematics has no solution there within the joint ranges (the edge of the reach)."""
    q = tuple(joints[:6])
    pose = list(kinematics.forward(q, dh))
    pose[axis] += sign * _PROBE
    try:
        moved = kinematics.inverse(pose, dh, "firmware", limits=kinematics.JOINT_LIMITS)
    except MirobotUsageError:
        return None
    gap = math.sqrt(sum(joint_delta(moved, q, i) ** 2 for i in range(6)))
    return max(gap / _PROBE, 1e-6)


def firmware_branch(joints: tuple[float, ...], dh: kinematics.DH) -> bool:
    """Whether the arm stands where the firmware's own inverse kinematics of its pose puts it
    (within :data:`BRANCH_TOLERANCE`): else a Cartesian move would first swing it there."""
    q = tuple(joints[:6])
    try:
        solution = kinematics.inverse(kinematics.forward(q, dh), dh, "firmware")
    except MirobotUsageError:
        return False
    return all(abs(joint_delta(solution, q, i)) <= BRANCH_TOLERANCE for i in range(6))


def reachable(pose: tuple[float, ...], dh: kinematics.DH) -> bool:
    """Whether the firmware's inverse kinematics solves ``pose`` within the joint ranges."""
    try:
        kinematics.inverse(pose, dh, "firmware", limits=kinematics.JOINT_LIMITS)
    except MirobotUsageError:
        return False
    return True


def joint_delta(a: tuple[float, ...], b: tuple[float, ...], i: int) -> float:
    """Joint ``i`` of ``a`` less that of ``b``; J4 and J6 (which turn past a full turn, and
    which the firmware keeps continuous on a Cartesian path) modulo 360."""
    return angle_delta(a[i], b[i]) if i in (3, 5) else a[i] - b[i]


def angle_delta(a: float, b: float) -> float:
    """``a - b`` in degrees, wrapped into (-180, 180]."""
    d = (a - b) % 360.0
    return d - 360.0 if d > 180.0 else d
