"""Unit tests of mirobot_async._safety.envelope: construction, target and path checks, raw lines.

The references are independent of the module under test: forward kinematics is a plain product of
modified-DH matrices written here, boxes are compared by hand, and paths are sampled here at a much
finer step than the envelope's own ``path_step_mm``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import numpy.typing as npt
import pytest
from envelope_lines import check_envelope_line
from hypothesis import assume, event, given, settings
from hypothesis import strategies as st

from mirobot_async._core.modal import HOMED
from mirobot_async._safety.envelope import Envelope, LineCheck, MotionModes, update_modes
from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import (
    DH,
    DH_2021,
    DH_CLASSIC,
    JOINT_LIMITS,
    BehindShoulder,
    Unreachable,
    inverse,
)

Array = npt.NDArray[np.float64]
HOME = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
HOME_POSE = (198.67, 0.0, 230.72, 0.0, 0.0, 0.0)
SETTINGS = settings(max_examples=60, deadline=None)

# --------------------------------------------------------------------------------------------
# Independent reference: forward kinematics as a product of Craig's modified DH matrices


def _mdh(alpha: float, a: float, theta: Array, d: float) -> Array:
    """``RotX(alpha) TransX(a) RotZ(theta) TransZ(d)`` for a vector of thetas (radians)."""
    n = theta.shape[0]
    ca, sa = math.cos(alpha), math.sin(alpha)
    ct, st_ = np.cos(theta), np.sin(theta)
    t = np.zeros((n, 4, 4))
    t[:, 0, 0], t[:, 0, 1], t[:, 0, 3] = ct, -st_, a
    t[:, 1, 0], t[:, 1, 1], t[:, 1, 2], t[:, 1, 3] = st_ * ca, ct * ca, -sa, -sa * d
    t[:, 2, 0], t[:, 2, 1], t[:, 2, 2], t[:, 2, 3] = st_ * sa, ct * sa, ca, ca * d
    t[:, 3, 3] = 1.0
    return t


def tool_points(
    joints: npt.ArrayLike, dh: DH = DH_2021, tool: Sequence[float] = (0, 0, 0)
) -> Array:
    """``(N, 3)`` tool points of ``(N, 6)`` joint vectors (degrees), PROTOCOL 8.1 table."""
    q = np.radians(np.atleast_2d(np.asarray(joints, dtype=np.float64)))
    h = math.pi / 2
    rows = [
        (0.0, 0.0, q[:, 0], dh.d1),
        (-h, dh.a1, q[:, 1] - h, 0.0),
        (0.0, dh.a2, q[:, 2], 0.0),
        (-h, dh.a3, q[:, 3], dh.d4),
        (h, 0.0, q[:, 4] + h, 0.0),
        (h, 0.0, q[:, 5], dh.l),
    ]
    t = np.broadcast_to(np.eye(4), (q.shape[0], 4, 4)).copy()
    for alpha, a, theta, d in rows:
        t = t @ _mdh(alpha, a, theta, d)
    return t[:, :3, 3] + t[:, :3, :3] @ np.asarray(tool, dtype=np.float64)


def box_excess(points: Array, box: Sequence[tuple[float | None, float | None] | None]) -> Array:
    """``(N, 6)``: how far each point is beyond x-min, x-max, y-min, y-max, z-min, z-max."""
    out = np.full((points.shape[0], 6), -np.inf)
    for axis, bound in enumerate(box):
        if bound is None:
            continue
        lo, hi = bound
        if lo is not None:
            out[:, 2 * axis] = lo - points[:, axis]
        if hi is not None:
            out[:, 2 * axis + 1] = points[:, axis] - hi
    return out


def bound_name(side: int, box: Sequence[tuple[float | None, float | None] | None]) -> str:
    """How the message names a side: ``minimum z=20`` / ``maximum x=250``."""
    axis = "xyz"[side // 2]
    bound = box[side // 2]
    assert bound is not None
    value = bound[side % 2]
    assert value is not None
    word = "minimum" if side % 2 == 0 else "maximum"
    text = f"{value:.6f}".rstrip("0").rstrip(".")
    return f"{word} {axis}={'0' if text == '-0' else text}"


def test_the_reference_fk_matches_protocol_vectors() -> None:
    """The test's own FK reproduces PROTOCOL 8.4 (so it can judge the module)."""
    got = tool_points([HOME, (90.005, 30.001, -20, 10, 19.982, 45.005)])
    assert np.allclose(got[0], (198.67, 0.0, 230.72), atol=1e-3)
    assert np.allclose(got[1], (-3.985, 241.503, 190.191), atol=2e-3)


# --------------------------------------------------------------------------------------------
# Construction


def test_defaults_are_the_firmware_ranges() -> None:
    env = Envelope()
    assert env.joint_limits == JOINT_LIMITS
    assert not env.has_box
    assert env.contains_joints((150, 60, -160, 300, -200, 350))
    assert not env.contains_joints((161, 0, 0, 0, 0, 0))


def test_joint_limits_may_be_narrowed_with_open_sides() -> None:
    env = Envelope(joints={2: (-10, 45), 5: (None, 0), 1: (0, None)})
    assert env.joint_limits[0] == (0.0, 160.0)
    assert env.joint_limits[1] == (-10.0, 45.0)
    assert env.joint_limits[4] == (-205.0, 0.0)
    assert env.joint_limits[2:4] == JOINT_LIMITS[2:4]
    assert env == Envelope(joints={1: (0.0, 160.0), 2: (-10.0, 45.0), 5: (-205, 0)})
    assert hash(env) == hash(Envelope(joints={1: (0, 160), 2: (-10, 45), 5: (-205, 0)}))


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"joints": {2: (-40, 60)}}, "wider than the firmware's J2 range -30..70"),
        ({"joints": {1: (0, 161)}}, "may only narrow"),
        ({"joints": {3: (10, -10)}}, "low is above high"),
        ({"joints": {2: (80, None)}}, "wider than the firmware's J2 range"),
        ({"joints": {4: (math.nan, 0)}}, "finite"),
        ({"joints": {4: (-math.inf, 0)}}, "finite"),
        ({"joints": {7: (0, 1)}}, "joint numbers are 1..6"),
        ({"joints": {0: (0, 1)}}, "joint numbers are 1..6"),
        ({"joints": {True: (0, 1)}}, "joint numbers are 1..6"),
        ({"joints": {"J1": (0, 1)}}, "joint numbers are 1..6"),
        ({"joints": {1: (0, 1, 2)}}, "(low, high) pair"),
        ({"joints": [(0, 1)]}, "mapping"),
        ({"z": (30, 20)}, "low is above high"),
        ({"x": (math.nan, None)}, "finite"),
        ({"y": "wide"}, "(low, high) pair"),
        ({"rail": (10, 0)}, "low is above high"),
        ({"path_step_mm": 0}, "must be > 0"),
        ({"path_step_mm": math.inf}, "finite"),
        ({"tool": (0, 0)}, "3 numbers"),
    ],
)
def test_bad_construction_is_refused(kwargs: dict[str, object], words: str) -> None:
    with pytest.raises(MirobotUsageError, match=None) as info:
        Envelope(**kwargs)  # type: ignore[arg-type]
    assert words in str(info.value)


def test_open_box_sides() -> None:
    env = Envelope(z=(20, None), x=(None, 250))
    assert env.has_box
    assert env.contains_point((-1000, 5000, 20))
    assert env.contains_point((250, 0, 1e6, 0, 0, 0))
    assert not env.contains_point((0, 0, 19.9))
    assert not env.contains_point((250.1, 0, 100))
    with pytest.raises(MirobotUsageError):
        env.contains_point((0, 0))


def test_messages_name_the_bound() -> None:
    env = Envelope(z=(20, None), joints={2: (-30, 60)}, rail=(0, 400))
    with pytest.raises(MirobotUsageError) as info:
        env.check_pose((198.67, 0, 5, 0, 0, 0), what="move_pose")
    assert str(info.value) == (
        "target z=5.000 mm is below the envelope's minimum z=20 mm (move_pose)"
    )
    with pytest.raises(MirobotUsageError) as info:
        env.check_joints((0, 65, 0, 0, 0, 0), what="move_joints")
    assert str(info.value) == (
        "j2=65.000 is outside the envelope's J2 range -30..60 deg (move_joints)"
    )
    with pytest.raises(MirobotUsageError, match=r"rail d=500\.000 mm is above .* rail=400 mm"):
        env.check_joints(HOME, 500.0)
    with pytest.raises(MirobotUsageError, match="unreachable"):
        env.check_pose((600, 0, 200, 0, 0, 0))
    with pytest.raises(MirobotUsageError, match=r"needs \(firmware IK\) j2=.* J2 range -30\.\.60"):
        env.check_pose((261.2, 0, 43.02, 0, 0, 0))  # IK: j2=65, j3=-20
    env.check_joints(HOME, 100.0)
    env.check_pose(HOME_POSE)


# --------------------------------------------------------------------------------------------
# Hypothesis strategies

side = st.one_of(st.none(), st.floats(-300, 350, allow_nan=False))


@st.composite
def boxes(draw: st.DrawFn) -> tuple[tuple[float | None, float | None] | None, ...]:
    out: list[tuple[float | None, float | None] | None] = []
    for _ in range(3):
        if draw(st.booleans()):
            out.append(None)
            continue
        lo, hi = draw(side), draw(side)
        if lo is not None and hi is not None and lo > hi:
            lo, hi = hi, lo
        out.append((lo, hi))
    return tuple(out)


@st.composite
def narrowed(draw: st.DrawFn) -> dict[int, tuple[float, float]]:
    out: dict[int, tuple[float, float]] = {}
    for joint in draw(st.sets(st.integers(1, 6), max_size=3)):
        lo, hi = JOINT_LIMITS[joint - 1]
        a = draw(st.floats(lo, hi))
        b = draw(st.floats(lo, hi))
        out[joint] = (min(a, b), max(a, b))
    return out


@st.composite
def narrowed_around(draw: st.DrawFn, q: Sequence[float]) -> dict[int, tuple[float, float]]:
    """Narrowed joint limits that contain ``q`` (each chosen side 0.5..60 deg away)."""
    out: dict[int, tuple[float, float]] = {}
    for joint in draw(st.sets(st.integers(1, 6), max_size=3)):
        lo, hi = JOINT_LIMITS[joint - 1]
        value = q[joint - 1]
        out[joint] = (
            max(lo, value - draw(st.floats(0.5, 60))),
            min(hi, value + draw(st.floats(0.5, 60))),
        )
    return out


def joints_in(limits: Sequence[tuple[float, float]], slack: float = 0.0) -> st.SearchStrategy:
    return st.tuples(*(st.floats(lo - slack, hi + slack) for lo, hi in limits))


def _near(value: float, bounds: Sequence[float | None], tol: float) -> bool:
    return any(b is not None and abs(value - b) < tol for b in bounds)


# --------------------------------------------------------------------------------------------
# Targets


@SETTINGS
@given(box=boxes(), joints=narrowed(), target=joints_in(JOINT_LIMITS, slack=20.0))
def test_joint_targets_against_the_reference(
    box: tuple[tuple[float | None, float | None] | None, ...],
    joints: dict[int, tuple[float, float]],
    target: tuple[float, ...],
) -> None:
    env = Envelope(x=box[0], y=box[1], z=box[2], joints=joints)
    limits = [joints.get(i + 1, JOINT_LIMITS[i]) for i in range(6)]
    assume(not any(_near(q, lim, 1e-4) for q, lim in zip(target, limits, strict=True)))
    point = tool_points([target])[0]
    for axis in range(3):
        b = box[axis]
        assume(b is None or not _near(float(point[axis]), b, 1e-4))
    bad_joints = [
        i for i, (q, (lo, hi)) in enumerate(zip(target, limits, strict=True)) if not lo <= q <= hi
    ]
    excess = box_excess(point[None, :], box)[0]
    bad_sides = [s for s in range(6) if excess[s] > 0]
    if not bad_joints and not bad_sides:
        event("inside")
        env.check_joints(target)
        assert env.contains_joints(target)
        return
    assert not env.contains_joints(target)
    event("outside")
    with pytest.raises(MirobotUsageError) as info:
        env.check_joints(target, what="t")
    names = [f"J{i + 1} range" for i in bad_joints] + [bound_name(s, box) for s in bad_sides]
    assert any(name in str(info.value) for name in names), (str(info.value), names)


@SETTINGS
@given(box=boxes(), joints=narrowed(), start=joints_in(JOINT_LIMITS))
def test_pose_targets_against_the_reference(
    box: tuple[tuple[float | None, float | None] | None, ...],
    joints: dict[int, tuple[float, float]],
    start: tuple[float, ...],
) -> None:
    """A reachable pose (FK of random joints): refused iff its position leaves the box or its
    firmware-branch IK leaves the joint limits."""
    env = Envelope(x=box[0], y=box[1], z=box[2], joints=joints)
    limits = [joints.get(i + 1, JOINT_LIMITS[i]) for i in range(6)]
    point = tool_points([start])[0]
    pose = (*point.tolist(), 10.0, -20.0, 30.0)
    try:
        q = inverse(pose, DH_2021, "firmware")
    except (Unreachable, BehindShoulder):  # the firmware would not go there: refused too
        with pytest.raises(MirobotUsageError, match=r"unreachable|below|above"):
            env.check_pose(pose)
        return
    assume(not any(_near(a, lim, 1e-4) for a, lim in zip(q, limits, strict=True)))
    assume(all(b is None or not _near(float(point[i]), b, 1e-4) for i, b in enumerate(box)))
    bad_sides = [s for s in range(6) if box_excess(point[None, :], box)[0][s] > 0]
    bad_joints = [
        i for i, (a, (lo, hi)) in enumerate(zip(q, limits, strict=True)) if not lo <= a <= hi
    ]
    if not bad_sides and not bad_joints:
        event("inside")
        env.check_pose(pose)
        assert env.contains_point(pose)
        return
    event("outside")
    with pytest.raises(MirobotUsageError) as info:
        env.check_pose(pose)
    names = [bound_name(s, box) for s in bad_sides] + [f"J{i + 1} range" for i in bad_joints]
    assert any(name in str(info.value) for name in names), (str(info.value), names)


# --------------------------------------------------------------------------------------------
# Joint-space paths


@st.composite
def box_around(
    draw: st.DrawFn, point: Array, near: float = 0.5, far: float = 150.0
) -> tuple[tuple[float | None, float | None], ...]:
    """A box that contains ``point``, each side open or ``near..far`` mm away."""
    out = []
    for axis in range(3):
        lo = draw(st.one_of(st.none(), st.floats(near, far)))
        hi = draw(st.one_of(st.none(), st.floats(near, far)))
        c = float(point[axis])
        out.append((None if lo is None else c - lo, None if hi is None else c + hi))
    return tuple(out)


@SETTINGS
@given(data=st.data(), start=joints_in(JOINT_LIMITS))
def test_joint_paths_against_a_fine_reference(
    data: st.DataObject, start: tuple[float, ...]
) -> None:
    """Start inside the box; the joint-space path is refused when it leaves the box by more than
    half a sample step, and passes when a 0.1 mm sampling keeps it inside with a margin."""
    box = data.draw(box_around(tool_points([start])[0]))
    delta = data.draw(st.tuples(*(st.floats(-60, 60) for _ in range(6))))
    target = tuple(
        min(max(s + d, lo), hi) for s, d, (lo, hi) in zip(start, delta, JOINT_LIMITS, strict=True)
    )
    env = Envelope(x=box[0], y=box[1], z=box[2])
    # The tool point is at most 478 mm from any joint axis on the 2021 arm.
    length = sum(abs(b - a) for a, b in zip(start, target, strict=True)) * math.pi / 180 * 478.0
    n = max(2, math.ceil(length / 0.1))
    t = np.linspace(0.0, 1.0, n + 1)
    q = np.asarray(start)[None, :] + t[:, None] * (np.asarray(target) - np.asarray(start))[None, :]
    excess = box_excess(tool_points(q), box)
    worst = float(excess.max())
    if worst < -0.1:
        event("inside")
        env.check_joints(target, start=start)
        return
    if worst > env.path_step_mm / 2 + 0.1:
        event("outside")
        with pytest.raises(MirobotUsageError) as info:
            env.check_joints(target, start=start)
        sides = {int(s) for s in np.argwhere(excess > 0)[:, 1]}
        assert any(bound_name(s, box) in str(info.value) for s in sides), str(info.value)
        # The target alone may be inside: only the path check catches it.
        if float(excess[-1].max()) < -1e-3:
            event("only the path is outside")
            env.check_joints(target)
            assert "path" in str(info.value)


def test_joint_path_recovery_from_outside() -> None:
    """Starting below the floor, a move up is allowed; a move that goes lower first is not."""
    env = Envelope(z=(150, None))
    low = (0.0, 60.0, 0.0, 0.0, 0.0, 0.0)
    assert tool_points([low])[0][2] < 150
    assert not env.contains_joints(low)
    env.check_joints(HOME, start=low)  # straight back up
    with pytest.raises(MirobotUsageError, match="minimum z=150"):
        env.check_joints(low, start=HOME)  # the target is outside
    env_j = Envelope(joints={2: (-30, 40)})
    env_j.check_joints(HOME, start=low)  # joints: back into range
    with pytest.raises(MirobotUsageError, match="J2 range"):
        env_j.check_joints((0, 50, 0, 0, 0, 0), start=low)


def test_joint_path_explicit_steps() -> None:
    env = Envelope(x=(None, 100))  # J1 = +-90: x = 0; on the way (J1 = 0) x = 198.67
    start, target = (-90.0, 0.0, 0.0, 0.0, 0.0, 0.0), (90.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert env.contains_joints(start) and env.contains_joints(target)
    env.check_joint_path(start, target, steps=1)  # the two ends only
    with pytest.raises(MirobotUsageError, match=r"joint-space path reaches .* maximum x=100"):
        env.check_joint_path(start, target)
    with pytest.raises(MirobotUsageError, match="maximum x=100"):
        env.check_joints(target, start=start)
    env.check_joints(target)  # the target alone is inside
    with pytest.raises(MirobotUsageError, match="steps"):
        env.check_joint_path(start, target, steps=0)


# --------------------------------------------------------------------------------------------
# Cartesian straight lines and arcs


def fine_line(a: Sequence[float], b: Sequence[float], step: float) -> Array:
    dist = math.dist(a[:3], b[:3])
    turn = max(abs(v - u) for u, v in zip(a[3:], b[3:], strict=True))
    n = max(2, math.ceil(max(dist / step, turn / step)))
    t = np.linspace(0.0, 1.0, n + 1)
    out: Array = np.asarray(a)[None, :] + t[:, None] * (np.asarray(b) - np.asarray(a))[None, :]
    return out


@SETTINGS
@given(
    data=st.data(),
    start=joints_in(((-60, 60), (-20, 50), (-60, 40), (-90, 90), (-90, 20), (-90, 90))),
    end=joints_in(((-60, 60), (-20, 50), (-60, 40), (-90, 90), (-90, 20), (-90, 90))),
)
def test_linear_paths_against_a_fine_reference(
    data: st.DataObject, start: tuple[float, ...], end: tuple[float, ...]
) -> None:
    """The box is exact for lines; joint limits are judged on the firmware IK of samples."""
    a = inverse_pose(start)
    b = inverse_pose(end)
    try:
        qa = inverse(a, DH_2021, "firmware")
    except (Unreachable, BehindShoulder):
        assume(False)
    # The arm starts well within the firmware's ranges (else: a recovery move).
    assume(all(lo + 0.5 < v < hi - 0.5 for v, (lo, hi) in zip(qa, JOINT_LIMITS, strict=True)))
    box = data.draw(st.one_of(st.just((None, None, None)), box_around(np.asarray(a))))
    joints = data.draw(narrowed_around(qa))
    env = Envelope(x=box[0], y=box[1], z=box[2], joints=joints)
    limits = np.asarray([joints.get(i + 1, JOINT_LIMITS[i]) for i in range(6)])
    fine = fine_line(a, b, 0.5)
    box_ex = box_excess(fine[:, :3], box)
    assume(float(box_ex[0].max()) < -1e-3)  # the arm starts inside (else: a recovery move)
    if float(box_ex.max()) > 1e-3:
        event("box outside")
        with pytest.raises(MirobotUsageError) as info:
            env.check_linear_path(a, b)
        sides = {int(s) for s in np.argwhere(box_ex > 0)[:, 1]}
        assert any(bound_name(s, box) in str(info.value) for s in sides), str(info.value)
        return
    assume(float(box_ex.max()) < -1e-3)
    bad = np.zeros(len(fine), dtype=bool)
    margin = np.inf
    names: set[str] = set()
    for i, pose in enumerate(fine):
        try:
            q = np.asarray(inverse(tuple(pose.tolist()), DH_2021, "firmware"))
        except (Unreachable, BehindShoulder):  # a point the firmware solves elsewhere: refused
            bad[i] = True
            names.add("unreachable")
            continue
        ex = np.maximum(limits[:, 0] - q, q - limits[:, 1])
        margin = min(margin, float(-ex.max()))
        if ex.max() > 1e-3:  # clearly out (the envelope itself allows rounding, 1e-6 deg)
            bad[i] = True
            names.update(f"J{j + 1} range" for j in np.flatnonzero(ex > 0))
    if not bad.any() and margin > 0.5:
        event("inside")
        env.check_linear_path(a, b)
        return
    # A run of violating fine samples longer than one envelope step must contain a sample.
    per_sample = math.dist(a[:3], b[:3]) / (len(fine) - 1)
    longest = run = 0
    for flag in bad:
        run = run + 1 if flag else 0
        longest = max(longest, run)
    if bad[-1] or (longest - 1) * per_sample > env.path_step_mm + 1.0:
        event("joints outside")
        with pytest.raises(MirobotUsageError) as info:
            env.check_linear_path(a, b)
        assert any(name in str(info.value) for name in names), (str(info.value), names)


def inverse_pose(joints: Sequence[float]) -> tuple[float, ...]:
    """A reachable pose: the tool point of ``joints``, orientation fixed at (0, -20, 0)."""
    point = tool_points([joints])[0]
    return (*point.tolist(), 0.0, -20.0, 0.0)


def test_linear_path_box_is_exact_for_a_line_that_dips() -> None:
    env = Envelope(z=(150, None))
    a = (220.0, -40.0, 200.0, 0.0, 0.0, 0.0)
    env.check_linear_path(a, (220.0, 40.0, 160.0, 0.0, 0.0, 0.0))
    with pytest.raises(MirobotUsageError, match=r"target z=140\.000 mm is below .* z=150 mm"):
        env.check_linear_path(a, (220.0, 40.0, 140.0, 0.0, 0.0, 0.0))


def test_linear_path_recovery_from_outside() -> None:
    """A line that starts outside (box or joint limits) may come back in, not go farther out."""
    low = (220.0, 0.0, 100.0, 0.0, 0.0, 0.0)  # firmware IK: j2 = 28.24
    high = (220.0, 0.0, 200.0, 0.0, 0.0, 0.0)  # j2 = 10.88
    env = Envelope(z=(150, None))
    env.check_linear_path(low, high)
    low_joints = inverse(low, DH_2021, "firmware")
    got = check_envelope_line(env, "M20 G90 G1 Z200 F100", low_joints, low)
    assert got.pose == high and got.joints is not None
    with pytest.raises(MirobotUsageError, match="minimum z=150"):
        check_envelope_line(env, "M20 G90 G1 Z90 F100", low_joints, low)
    with pytest.raises(MirobotUsageError, match="minimum z=150"):
        env.check_linear_path(low, (260.0, 0.0, 140.0, 0.0, 0.0, 0.0))
    env_j = Envelope(joints={2: (-30, 20)})
    env_j.check_linear_path(low, high)
    with pytest.raises(MirobotUsageError, match=r"J2 range -30\.\.20"):
        env_j.check_linear_path(low, (260.0, 0.0, 140.0, 0.0, 0.0, 0.0))  # j2 = 38.28


def test_linear_path_through_an_unreachable_region() -> None:
    env = Envelope()
    # Both ends reachable, the straight line passes through the J1 axis column at low height.
    a = (150.0, -60.0, 60.0, 0.0, 0.0, 0.0)
    b = (-150.0, 60.0, 60.0, 0.0, 0.0, 0.0)
    with pytest.raises(MirobotUsageError, match=r"unreachable|range"):
        env.check_linear_path(a, b)


@SETTINGS
@given(
    cx=st.floats(200, 230),
    cy=st.floats(-40, 40),
    radius=st.floats(5, 40),
    a0=st.floats(-math.pi, math.pi),
    sweep=st.floats(0.05, math.pi - 0.05),
    clockwise=st.booleans(),
    data=st.data(),
)
def test_arcs_against_a_fine_reference(
    cx: float,
    cy: float,
    radius: float,
    a0: float,
    sweep: float,
    clockwise: bool,
    data: st.DataObject,
) -> None:
    """The box test of a G2/G3 minor arc is exact: its extremes count, not just its end points."""
    a1 = a0 - sweep if clockwise else a0 + sweep
    start = (cx + radius * math.cos(a0), cy + radius * math.sin(a0), 200.0, 0.0, 0.0, 0.0)
    end = (cx + radius * math.cos(a1), cy + radius * math.sin(a1), 190.0, 0.0, 0.0, 0.0)
    angles = np.linspace(a0, a1, 2000)
    pts = np.stack(
        [cx + radius * np.cos(angles), cy + radius * np.sin(angles), np.linspace(200, 190, 2000)],
        axis=1,
    )
    box = data.draw(box_around(np.asarray(start), 0.05, 60.0))
    excess = box_excess(pts, box)
    assume(abs(float(excess.max())) > 0.01)
    env = Envelope(x=box[0], y=box[1], z=box[2])
    if float(excess.max()) < 0:
        event("inside")
        env.check_arc(start, end, radius, clockwise=clockwise)
        # 8 significant digits at most: the firmware drops the others
        line = f"M20 G90 G{2 if clockwise else 3} X{end[0]:.4f} Y{end[1]:.4f} Z190 R{radius:.4f}"
        try:
            got = check_envelope_line(env, line, inverse(start, DH_2021, "firmware"), start)
        except MirobotUsageError as exc:  # rounding to 4 decimals may graze a bound
            assert "mm (line" in str(exc) or "Arc radius" in str(exc), str(exc)
            return
        assert got.moves and got.pose is not None
        assert np.allclose(got.pose[:3], end[:3], atol=1e-4)
        return
    event("outside")
    with pytest.raises(MirobotUsageError) as info:
        env.check_arc(start, end, radius, clockwise=clockwise)
    sides = {int(s) for s in np.argwhere(excess > 0)[:, 1]}
    assert any(bound_name(s, box) in str(info.value) for s in sides), str(info.value)


def test_arc_errors() -> None:
    env = Envelope()
    a = (200.0, 0.0, 200.0, 0.0, 0.0, 0.0)
    with pytest.raises(MirobotUsageError, match="Arc radius error"):
        env.check_arc(a, (250.0, 0.0, 200.0, 0, 0, 0), 10, clockwise=True)
    with pytest.raises(MirobotUsageError, match="zero chord"):
        env.check_arc(a, a, 10, clockwise=True)
    with pytest.raises(MirobotUsageError, match="radius must be > 0"):
        env.check_arc(a, (210.0, 0.0, 200.0, 0, 0, 0), -10, clockwise=True)
    with pytest.raises(MirobotUsageError, match="needs R"):
        check_envelope_line(env, "M20 G2 X210 Y0", HOME)
    with pytest.raises(MirobotUsageError, match="need the 2021 firmware and M20"):
        check_envelope_line(env, "M21 G2 X10 Y0 R20", HOME)
    # From (200, 0) to (240, 0) with R20: G2 (clockwise seen from above) is the half circle on
    # the +y side, G3 the one on the -y side.
    env_y = Envelope(y=(-10, None))
    with pytest.raises(MirobotUsageError, match="minimum y=-10"):
        env_y.check_arc(a, (240.0, 0.0, 200.0, 0, 0, 0), 20, clockwise=False)
    env_y.check_arc(a, (240.0, 0.0, 200.0, 0, 0, 0), 20, clockwise=True)


# --------------------------------------------------------------------------------------------
# Raw lines


def test_lines_that_do_not_move_always_pass() -> None:
    env = Envelope(x=(1000, 1001))  # nothing reachable is inside: any move is refused
    modes = MotionModes(cartesian=True, relative=True, motion=1)
    lines: list[str | bytes] = [
        "",
        "   ",
        "M3 S1000",
        "M4 E65",
        "M5",
        "G4 P1.5",
        "F2000",
        "G90",
        "G91",
        "M20",
        "M21 G90",
        "G1",  # sets the motion mode only
        "M50",
        "$$",
        "$X",
        "$20=1",
        "$130=100",
        "N10",
        "(a comment X10)",
        "; X10",
        b"M3S0\n",
    ]
    for line in lines:
        got = check_envelope_line(env, line, None, None, modes)
        assert not got.moves, line
        assert got.joints is None and got.pose is None
    assert check_envelope_line(env, "G90", HOME, None, modes).modes == MotionModes(True, False, 1)
    still = check_envelope_line(env, "M3 S0", HOME)
    assert still.joints == HOME and still.pose is not None


def test_absolute_joint_lines_with_missing_axes() -> None:
    env = Envelope(joints={1: (-50, 50)})
    cur = (10.0, 5.0, -5.0, 1.0, 2.0, 3.0)
    got = check_envelope_line(env, "M21 G90 G0 X20 C-4", cur)
    assert got.moves
    assert got.joints == (20.0, 5.0, -5.0, 1.0, 2.0, -4.0)
    assert got.modes == MotionModes(cartesian=False, relative=False, motion=0)
    assert got.pose is not None and np.allclose(got.pose[:3], tool_points([got.joints])[0])
    with pytest.raises(MirobotUsageError, match=r"j1=60\.000 is outside the envelope's J1 range"):
        check_envelope_line(env, "M21 G90 G1 X60 F100", cur)
    # Missing axes without a known position cannot be judged; a full target can.
    with pytest.raises(MirobotUsageError, match="unknown"):
        check_envelope_line(env, "X20", None)
    assert check_envelope_line(env, "X1Y2Z3A4B5C6", None).joints == (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)


def test_relative_joint_lines() -> None:
    env = Envelope(joints={2: (-30, 40)})
    cur = (10.0, 30.0, 0.0, 0.0, 0.0, 0.0)
    got = check_envelope_line(env, "M21 G91 Y5 X-10", cur)
    assert got.joints == (0.0, 35.0, 0.0, 0.0, 0.0, 0.0)
    assert got.modes.relative
    with pytest.raises(MirobotUsageError, match=r"j2=45\.000 .* J2 range -30\.\.40"):
        check_envelope_line(env, "Y15", cur, None, got.modes)
    with pytest.raises(MirobotUsageError, match="relative move needs the current joint"):
        check_envelope_line(env, "M21 G91 X1 Y1 Z1 A1 B1 C1", None)


def test_cartesian_lines_absolute_and_relative() -> None:
    env = Envelope(z=(150, None))
    modes = MotionModes()
    got = check_envelope_line(env, "M20 G90 G0 Z200", HOME, None, modes)  # x, y, orientation stay
    assert got.pose is not None and np.allclose(got.pose, (198.67, 0, 200, 0, 0, 0))
    assert got.joints is not None
    assert np.allclose(tool_points([got.joints])[0], (198.67, 0, 200), atol=1e-6)
    modes = got.modes
    assert modes == MotionModes(cartesian=True, relative=False, motion=0)
    with pytest.raises(MirobotUsageError, match=r"target z=140\.000 mm is below .* z=150 mm"):
        check_envelope_line(env, "Z140", got.joints, got.pose, modes)
    rel = check_envelope_line(env, "G91 G1 Z-40 F500", got.joints, got.pose, modes)
    assert rel.pose is not None and math.isclose(rel.pose[2], 160.0)
    assert rel.modes == MotionModes(cartesian=True, relative=True, motion=1, feed=500.0)
    with pytest.raises(MirobotUsageError, match="minimum z=150"):
        check_envelope_line(env, "Z-20", rel.joints, rel.pose, rel.modes)  # 160 - 20 = 140
    with pytest.raises(MirobotUsageError, match="current pose"):
        check_envelope_line(env, "G1 X1 Y1 Z200 A0 B0 C0", None, None, rel.modes)


@SETTINGS
@given(
    cur=joints_in(((-60, 60), (-20, 50), (-60, 40), (-90, 90), (-90, 20), (-90, 90))),
    words=st.dictionaries(st.sampled_from("XYZABC"), st.floats(-40, 40), min_size=1),
    relative=st.booleans(),
)
def test_relative_and_partial_joint_lines_match_check_joints(
    cur: tuple[float, ...], words: dict[str, float], relative: bool
) -> None:
    """check_line builds the target by hand-checkable rules and agrees with check_joints."""
    env = Envelope(z=(100, None), joints={2: (-20, 45), 3: (-60, 30)})
    want = tuple(
        (c + words.get(k, 0.0)) if relative else words.get(k, c)
        for k, c in zip("XYZABC", cur, strict=True)
    )
    line = (
        "M21 "
        + ("G91 " if relative else "G90 ")
        + " ".join(f"{k}{v:.6f}" for k, v in words.items())
    )
    # Parse what we wrote, so that rounding to 6 decimals is the same on both sides.
    want = tuple(
        (c + round(words[k], 6))
        if (relative and k in words)
        else (round(words[k], 6) if k in words else c)
        for k, c in zip("XYZABC", cur, strict=True)
    )
    try:
        env.check_joints(want, start=cur)
    except MirobotUsageError as exc:
        with pytest.raises(MirobotUsageError) as info:
            check_envelope_line(env, line, cur)
        assert str(info.value).split(" (")[0] == str(exc).split(" (")[0]
        return
    got = check_envelope_line(env, line, cur)
    assert got.moves
    assert got.joints is not None and np.allclose(got.joints, want, atol=1e-9)


def test_modes_persist_and_update() -> None:
    m = MotionModes()
    assert m == MotionModes(cartesian=False, relative=False, motion=0)
    m = update_modes("M20 G91", m)
    assert m == MotionModes(True, True, 0)
    m = update_modes(b"g1 x10 f200\n", m)
    assert m == MotionModes(True, True, 1)
    assert update_modes("M3 S100", m) == m
    assert update_modes("G0 G1", m) == m  # the firmware rejects it: nothing changes
    assert update_modes("garbage!", m) == m
    assert update_modes("$20=1", m) == m
    assert update_modes("$H", m) == HOMED  # (feed 0)
    assert update_modes("$HH", m) == HOMED
    assert update_modes("M21G90G0", m) == MotionModes()
    assert update_modes("G20", m) == MotionModes(True, True, 1, inches=True)
    assert update_modes("M21G91G21", m) == MotionModes(False, True, 1, inches=False)
    assert update_modes("M20 M21", m) == MotionModes(None, True, 1)  # refused; mode unsure
    assert update_modes("G21 M21", m) == MotionModes(None, True, 1)  # refused; M21 ran
    assert update_modes("$H8", m) == HOMED  # any $H... homes
    assert update_modes("M16404", m) == replace(m, cartesian=True)  # read as the firmware does


def test_lines_the_envelope_cannot_judge_are_refused() -> None:
    env = Envelope()
    for line, words in [
        ("G5 X10 Y10", "G5"),
        ("G28", "G28"),
        ("G92 X0", "G92"),
        ("G0 G1 X1", "Modal group violation"),
        ("G90 G91 X1", "G90 and G91"),
        ("M20 M21 X1", "M20 and M21"),
        ("X1 X2", "twice"),
        ("HELLO", "rejects"),
        ("G1 X1 I5 J5", "letter I"),
        ("$J=X10 F100", "jog"),
        ("G0 X0000000030", "reads it as 0"),
        ("M20.001 G0 X200", "plain command number"),
        ("M16404 G0 X200", "reads it as M20"),
        ("G21 M21 G0 X10", "Modal group violation"),
        ("$46=10", "geometry"),
        ("$N0=G20", "startup line"),
        ("$RST=$", "RST"),
        ("$041.5=1", "write it that way"),
    ]:
        with pytest.raises(MirobotUsageError) as info:
            check_envelope_line(env, line, HOME)
        assert words in str(info.value), (line, str(info.value))


def test_homing_and_zero_move_lines() -> None:
    env = Envelope(z=(240, None))  # the all-zero pose (z=230.72) is below the floor
    got = check_envelope_line(env, "$H", HOME, None, MotionModes(True, True, 1))
    assert got == LineCheck(HOMED, True, None, None, None)
    with pytest.raises(MirobotUsageError, match="minimum z=240"):
        check_envelope_line(env, "$M", (0, -20, -20, 0, 0, 0))
    ok = check_envelope_line(Envelope(z=(200, None)), "$M", (0, -20, -20, 0, 0, 0))
    assert ok.moves and ok.joints == HOME


def test_rail_lines() -> None:
    env = Envelope(rail=(0, 300))
    got = check_envelope_line(env, "M21 G90 D100", HOME, current_rail=50.0)
    assert got.rail == 100.0 and got.joints == HOME
    assert check_envelope_line(env, "G91 D100", HOME, current_rail=150.0).rail == 250.0
    with pytest.raises(MirobotUsageError, match=r"rail d=350\.000 mm is above"):
        check_envelope_line(env, "G91 D200", HOME, current_rail=150.0)
    with pytest.raises(MirobotUsageError, match="current rail"):
        check_envelope_line(env, "G91 D1", HOME)
    assert check_envelope_line(Envelope(), "G91 D1", HOME).moves  # no rail bound: nothing to check


def test_tool_offset_moves_the_checked_point() -> None:
    tool = (0.0, 0.0, 50.0)  # 50 mm along z6, which points up at the all-zero pose
    env = Envelope(z=(None, 250), tool=tool)
    assert float(tool_points([HOME], tool=tool)[0][2]) > 250
    with pytest.raises(MirobotUsageError, match="maximum z=250"):
        env.check_joints(HOME)
    Envelope(z=(None, 250)).check_joints(HOME)


def test_unknown_modes_must_be_stated_in_the_line() -> None:
    env = Envelope()
    unknown = MotionModes.unknown()
    for line, missing in [
        ("X10", "coordinate mode"),
        ("M21 X10", "distance mode"),
        ("M21 G90 X10", "motion mode"),
        ("M21 G90 G0 X10", "units"),
    ]:
        with pytest.raises(MirobotUsageError, match=missing):
            check_envelope_line(env, line, HOME, None, unknown)
    got = check_envelope_line(env, "M21 G90 G0 G21 X10", HOME, None, unknown)
    assert got.joints == (10.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert got.modes == MotionModes(feed=None)  # (the feed rate is unknown until stated)
    # Lines that do not move pass whatever is unknown, and state what they set.
    got_modes = check_envelope_line(env, "G91", None, None, unknown).modes
    assert got_modes == MotionModes(None, True, None, None, feed=None)
    assert update_modes("M20", unknown) == MotionModes(True, None, None, None, feed=None)


def test_program_end_resets_distance_and_motion_modes() -> None:
    """GRBL's program end (M2/M30): G90 and G1 (as the emulator's firmware model)."""
    env = Envelope()
    modes = MotionModes(cartesian=False, relative=True, motion=0, inches=True)
    got = check_envelope_line(env, "M2", HOME, None, modes)
    assert not got.moves and got.modes == MotionModes(False, False, 1, inches=True)
    assert update_modes("M30", modes) == MotionModes(False, False, 1, inches=True)
    # A move in the same line still runs with the modes in effect before the program end.
    moved = check_envelope_line(env, "X5 M2", HOME, None, replace(modes, inches=False))
    assert moved.joints == (5.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert moved.modes == MotionModes(False, False, 1)


def test_a_pose_behind_the_shoulder_is_refused_with_where_the_arm_would_go() -> None:
    # oracle (classic): M20 G90 G0 X1 Y5 Z182 A0 B0 C0 with $20=0 ends at X 11.551 Y 57.749: the
    # firmware solves a wrist centre behind the shoulder as its mirror in front of it
    env = Envelope(dh=DH_CLASSIC)
    with pytest.raises(MirobotUsageError, match=r"behind the shoulder.*\(11\.55\d, 57\.7\d\d"):
        env.check_pose((1.0, 5.0, 182.0, 0.0, 0.0, 0.0))
    # a straight line that passes within A1 of the base axis is refused too
    with pytest.raises(MirobotUsageError, match="unreachable"):
        env.check_linear_path((150.0, 0.0, 182.0, 0.0, 0.0, 0.0), (1.0, 5.0, 182.0, 0.0, 0.0, 0.0))
    env.check_pose((150.0, 5.0, 182.0, 0.0, 0.0, 0.0))  # in front of the shoulder: fine
