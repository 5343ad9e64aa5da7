"""Unit tests of mirobot_async.kinematics: FK/IK against the protocol vectors, and round trips."""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import (
    DH,
    DH_2021,
    DH_CLASSIC,
    JOINT_LIMITS,
    BehindShoulder,
    OutOfLimits,
    Unreachable,
    firmware_pose,
    forward,
    forward_many,
    in_limits,
    inverse,
    inverse_all,
    line_reachable,
    matrix_to_rpy,
    rpy_to_matrix,
    sample_line,
)

# An exact copy of shared/protocol/vectors.json, so the tests do not depend on the workplace layout.
VECTORS: dict[str, Any] = json.loads(
    (Path(__file__).parent.parent / "data" / "vectors.json").read_text(encoding="utf-8")
)
DH_BY_NAME = {"2021": DH_2021, "classic": DH_CLASSIC}
HOME_2021 = (198.67, 0.0, 230.72, 0.0, 0.0, 0.0)


def angle_diff(a: float, b: float) -> float:
    """|a - b| modulo 360, in [0, 180]."""
    d = abs(a - b) % 360.0
    return min(d, 360.0 - d)


def assert_pose_close(
    got: Sequence[float], want: Sequence[float], mm: float, deg: float, ctx: object = ""
) -> None:
    for i in range(3):
        assert abs(got[i] - want[i]) <= mm, (i, got, want, ctx)
    for i in range(3, 6):
        assert angle_diff(got[i], want[i]) <= deg, (i, got, want, ctx)


def assert_same_orientation(got: Sequence[float], want: Sequence[float], tol: float) -> None:
    """Compare orientations as matrices (robust at the RPY gimbal lock ry = +-90)."""
    diff = rpy_to_matrix(*got[3:]) - rpy_to_matrix(*want[3:])
    assert float(np.max(np.abs(diff))) <= tol, (got, want)


def assert_joints_close(got: Sequence[float], want: Sequence[float], deg: float) -> None:
    assert all(angle_diff(a, b) <= deg for a, b in zip(got, want, strict=True)), (got, want)


# ------------------------------------------------------------------------------------------
# Vectors


# SHA-256 of the shared protocol/vectors.json this copy was taken from (device data: never edit).
VECTORS_SHA256 = "11349f616cc37ace6b75f6f2ec0aab1e2d86e202df730eb7bf1956658d8218df"


def test_vectors_copy_is_the_shared_file() -> None:
    """The copy in tests/data is byte-identical to the reference (and to shared/, when beside)."""
    copy = Path(__file__).parents[1] / "data" / "vectors.json"
    assert hashlib.sha256(copy.read_bytes()).hexdigest() == VECTORS_SHA256
    shared = Path(__file__).parents[2].parent / "shared" / "protocol" / "vectors.json"
    if shared.exists():
        assert hashlib.sha256(shared.read_bytes()).hexdigest() == VECTORS_SHA256


def test_vector_dh_sets_match_constants() -> None:
    for name, dh in DH_BY_NAME.items():
        d = VECTORS["dh_sets"][name]
        assert (d["D1"], d["A1"], d["A2"], d["A3"], d["D4"], d["L"]) == (
            dh.d1,
            dh.a1,
            dh.a2,
            dh.a3,
            dh.d4,
            dh.l,
        )


@pytest.mark.parametrize(
    "entry", VECTORS["fk"], ids=[f"{e['origin']}-{i}" for i, e in enumerate(VECTORS["fk"])]
)
def test_fk_vectors(entry: dict[str, Any]) -> None:
    pose = forward(entry["joints"], DH_BY_NAME[entry["dh"]])
    if entry["origin"] == "computed":
        # Printed to 3 decimals: allow the rounding (and a little more).
        assert_pose_close(pose, entry["pose"], 0.0015, 0.0015, entry)
    else:
        # Device prints: joints and pose are both quantised (PROTOCOL 8.4).
        assert_pose_close(pose, entry["pose"], 0.002, 0.001, entry)


def test_fk_zero_pose_formula() -> None:
    for dh in (DH_2021, DH_CLASSIC):
        pose = forward((0,) * 6, dh)
        want = (dh.a1 + dh.d4, 0.0, dh.d1 + dh.a2 + dh.a3 + dh.l, 0.0, 0.0, 0.0)
        assert pose == pytest.approx(want, abs=1e-9)
    # No negative zeros: a status line must print "0.000", not "-0.000".
    assert all(not f"{v:.3f}".startswith("-") for v in forward((0,) * 6))
    assert forward((0,) * 6, DH_CLASSIC)[:3] == pytest.approx((202, 0, 181), abs=1e-9)


@pytest.mark.parametrize("entry", VECTORS["ik_firmware_branch"])
def test_ik_firmware_vectors(entry: dict[str, Any]) -> None:
    dh = DH_BY_NAME[entry["dh"]]
    joints = inverse(entry["pose"], dh)
    assert joints == pytest.approx(entry["joints"], abs=0.001)
    assert inverse_all(entry["pose"], dh)[0] == joints
    # And the firmware solution is within the factory ranges.
    assert in_limits(joints)
    assert inverse(entry["pose"], dh, limits=JOINT_LIMITS) == joints


@pytest.mark.parametrize(
    ("pose", "joints"),
    [
        ((180, 50, 150, 0, 0, 0), (15.524, -0.975, 28.626, 0, -27.651, -15.524)),
        ((250, 0, 100, 0, 0, 0), (0, 41.757, -5.703, 0, -36.054, 0)),
        ((150, -30, 55, 0, 0, 0), (-11.310, 21.532, 45.775, 0, -67.307, 11.310)),
    ],
)
def test_ik_protocol_section_8_4(pose: tuple[float, ...], joints: tuple[float, ...]) -> None:
    assert inverse(pose) == pytest.approx(joints, abs=0.001)


def test_ik_home_is_zero() -> None:
    assert inverse(HOME_2021) == pytest.approx((0,) * 6, abs=1e-9)
    assert inverse(forward((0,) * 6, DH_CLASSIC), DH_CLASSIC) == pytest.approx((0,) * 6, abs=1e-9)


# ------------------------------------------------------------------------------------------
# Round trips (hypothesis)

angles = st.floats(-180.0, 180.0, allow_nan=False)


def within_limits_joints() -> st.SearchStrategy[tuple[float, ...]]:
    return st.tuples(*(st.floats(lo, hi, allow_nan=False) for lo, hi in JOINT_LIMITS))


def wrist_singular(q: Sequence[float], margin: float = 0.01) -> bool:
    return abs(math.cos(math.radians(q[4]))) < math.sin(math.radians(margin))


def elbow_stretched(q: Sequence[float], dh: DH, margin: float = 0.01) -> bool:
    phi = q[2] + math.degrees(math.atan2(dh.d4, dh.a3))
    return abs(math.sin(math.radians(phi))) < math.sin(math.radians(margin))


@settings(max_examples=1500)
@given(q=within_limits_joints(), dh=st.sampled_from([DH_2021, DH_CLASSIC]))
def test_fk_ik_round_trip_firmware(q: tuple[float, ...], dh: DH) -> None:
    assume(not wrist_singular(q))
    pose = forward(q, dh)
    mirrored = firmware_pose(pose, dh)
    if mirrored is not None:  # wrist centre behind the shoulder: the arm goes to another pose
        with pytest.raises(BehindShoulder) as info:
            inverse(pose, dh)
        assert info.value.actual == mirrored
        assert firmware_pose(mirrored, dh) is None  # mirrored in front of the shoulder
        arm = forward(inverse(mirrored, dh), dh)
        assert_pose_close(arm, mirrored, 1e-6, 180.0)
        return
    sol = inverse(pose, dh)
    assert -90.0 <= sol[4] <= 90.0
    back = forward(sol, dh)
    assert_pose_close(back, pose, 1e-6, 180.0)
    assert_same_orientation(back, pose, 1e-9)
    if abs(pose[4]) < 85.0:
        assert_pose_close(back, pose, 1e-6, 1e-6)


@settings(max_examples=1500)
@given(q=within_limits_joints(), dh=st.sampled_from([DH_2021, DH_CLASSIC]))
def test_nearest_branch_recovers_joints(q: tuple[float, ...], dh: DH) -> None:
    assume(not wrist_singular(q) and not elbow_stretched(q, dh))
    pose = forward(q, dh)
    sol = inverse(pose, dh, branch="nearest", current=q, limits=JOINT_LIMITS)
    assert in_limits(sol)
    assert sol == pytest.approx(q, abs=1e-6)
    back = forward(sol, dh)
    assert_pose_close(back, pose, 1e-6, 180.0)
    assert_same_orientation(back, pose, 1e-9)


@settings(max_examples=800)
@given(q=st.tuples(*[angles] * 6), dh=st.sampled_from([DH_2021, DH_CLASSIC]))
def test_inverse_all_contains_original_and_all_solve(q: tuple[float, ...], dh: DH) -> None:
    assume(not wrist_singular(q) and not elbow_stretched(q, dh))
    pose = forward(q, dh)
    # At ry = +-90 (to the last bit) the reported rx/rz split is the firmware's formula on
    # rounding noise (matrix_to_rpy): another branch's report then names another orientation,
    # and the round trip below would compare noise (q = (0, 0, 90, 1, 0, 0), DH_2021).
    assume(abs(math.cos(math.radians(pose[4]))) > 1e-9)
    sols = inverse_all(pose, dh)
    assert 1 <= len(sols) <= 8
    assert any(all(angle_diff(a, b) <= 1e-6 for a, b in zip(s, q, strict=True)) for s in sols)
    for s in sols:
        assert all(-180.0 < a <= 180.0 for a in s)
        back = forward(s, dh)
        assert_pose_close(back, pose, 1e-6, 180.0)
        assert_same_orientation(back, pose, 1e-9)


@settings(max_examples=300)
@given(
    q=within_limits_joints(),
    tool=st.tuples(*[st.floats(-80.0, 80.0, allow_nan=False)] * 3),
)
def test_tool_offset_round_trip(q: tuple[float, ...], tool: tuple[float, float, float]) -> None:
    assume(not wrist_singular(q) and not elbow_stretched(q, DH_2021))
    pose = forward(q, DH_2021, tool)
    flange = forward(q, DH_2021)
    # The tool point is the flange point moved by R06 @ tool.
    moved = np.array(flange[:3]) + rpy_to_matrix(*flange[3:]) @ np.array(tool)
    assert np.allclose(pose[:3], moved, atol=1e-9)
    assert_same_orientation(pose, flange, 1e-12)
    sol = inverse(pose, DH_2021, branch="nearest", current=q, tool=tool)
    assert sol == pytest.approx(q, abs=1e-6)
    assert_pose_close(forward(sol, DH_2021, tool), pose, 1e-6, 180.0)


@settings(max_examples=200)
@given(q=st.tuples(*[angles] * 6), tz=st.floats(-100.0, 100.0, allow_nan=False))
def test_tool_along_z6_equals_longer_l(q: tuple[float, ...], tz: float) -> None:
    longer = DH(DH_2021.d1, DH_2021.a1, DH_2021.a2, DH_2021.a3, DH_2021.d4, DH_2021.l + tz)
    a = forward(q, DH_2021, (0.0, 0.0, tz))
    b = forward(q, longer)
    assert_pose_close(a, b, 1e-9, 1e-9)


def test_forward_many_matches_forward() -> None:
    rng = np.random.default_rng(1234)
    q = rng.uniform(-200.0, 200.0, size=(500, 6))
    for dh, tool in ((DH_2021, (0.0, 0.0, 0.0)), (DH_CLASSIC, (5.0, -3.0, 40.0))):
        many = forward_many(q, dh, tool)
        assert many.shape == (500, 6)
        for row, got in zip(q, many, strict=True):
            want = forward(tuple(float(v) for v in row), dh, tool)
            assert np.allclose(got[:3], want[:3], atol=1e-9)
            for a, b in zip(got[3:], want[3:], strict=True):
                assert angle_diff(float(a), b) <= 1e-9
    assert forward_many(np.zeros((0, 6))).shape == (0, 6)
    with pytest.raises(MirobotUsageError):
        forward_many(np.zeros((3, 5)))


@pytest.mark.parametrize("q5", [90.0, -90.0])
def test_wrist_singularity(q5: float) -> None:
    q = (10.0, 20.0, -30.0, 40.0, q5, 60.0)
    pose = forward(q)
    sol = inverse(pose)
    assert sol[3] == 0.0
    assert sol[4] == pytest.approx(q5, abs=1e-6)
    assert_pose_close(forward(sol), pose, 1e-6, 1e-6)
    # The wrist flip of this arm configuration coincides with it: one solution, not two.
    same_arm = [s for s in inverse_all(pose) if s[:3] == pytest.approx(sol[:3], abs=1e-9)]
    assert len(same_arm) == 1
    # "nearest" keeps q4 where it is and moves q6 instead.
    near = inverse(pose, branch="nearest", current=q)
    assert near == pytest.approx(q, abs=1e-6)


def test_rpy_matrix_round_trip() -> None:
    rng = np.random.default_rng(7)
    for rx, ry, rz in rng.uniform(-179.0, 179.0, size=(200, 3)):
        ry = float(ry) / 2.0  # keep away from the gimbal lock
        m = rpy_to_matrix(float(rx), ry, float(rz))
        assert np.allclose(m @ m.T, np.eye(3), atol=1e-12)
        assert matrix_to_rpy(m) == pytest.approx((rx, ry, rz), abs=1e-9)
    # R = Rz Ry Rx about fixed axes: a pure yaw turns x towards y.
    assert rpy_to_matrix(0, 0, 90) @ np.array([1.0, 0, 0]) == pytest.approx([0, 1, 0], abs=1e-12)
    with pytest.raises(MirobotUsageError):
        matrix_to_rpy(np.eye(4))


# ------------------------------------------------------------------------------------------
# Branch selection and limits


def test_nearest_wraps_joint_angles_near_current() -> None:
    q = (0.0, 10.0, 10.0, 300.0, 10.0, -330.0)
    pose = forward(q)
    fw = inverse(pose)
    assert fw[3] == pytest.approx(-60.0, abs=1e-6)
    assert fw[5] == pytest.approx(30.0, abs=1e-6)
    near = inverse(pose, branch="nearest", current=q, limits=JOINT_LIMITS)
    assert near == pytest.approx(q, abs=1e-6)
    # Without current, "nearest" means nearest to all-zero joints.
    assert inverse(pose, branch="nearest") == pytest.approx(fw, abs=1e-6)


def test_nearest_respects_limits() -> None:
    # J5 = 30 near a current of 20 is fine; the flipped wrist (q5 = -210) would be out of range.
    q = (5.0, 10.0, 10.0, 20.0, 30.0, 40.0)
    pose = forward(q)
    flipped = (5.0, 10.0, 10.0, -160.0, -210.0, -140.0)
    assert_pose_close(forward(flipped), pose, 1e-9, 1e-9)
    near = inverse(pose, branch="nearest", current=flipped, limits=JOINT_LIMITS)
    assert in_limits(near)
    unlimited = inverse(pose, branch="nearest", current=flipped)
    assert unlimited == pytest.approx(flipped, abs=1e-6)


def test_firmware_branch_out_of_limits() -> None:
    pose = forward((170.0, 0.0, 0.0, 0.0, 0.0, 0.0))  # J1 beyond +160
    assert inverse(pose)[0] == pytest.approx(170.0, abs=1e-9)
    with pytest.raises(OutOfLimits, match="out of limit") as info:
        inverse(pose, limits=JOINT_LIMITS)
    assert isinstance(info.value, MirobotUsageError)
    assert isinstance(info.value, ValueError)
    assert not isinstance(info.value, Unreachable)
    with pytest.raises(OutOfLimits, match="out of limit"):
        inverse(pose, branch="nearest", limits=JOINT_LIMITS)


@pytest.mark.parametrize(
    "pose",
    [(1000.0, 0.0, 0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 700.0, 0.0, 0.0, 0.0), (400, 0, 230, 0, 0, 0)],
)
def test_unreachable(pose: tuple[float, ...]) -> None:
    with pytest.raises(MirobotUsageError, match="unreachable") as info:
        inverse(pose)
    assert isinstance(info.value, Unreachable)
    assert isinstance(info.value, ValueError)
    assert f"{pose[0]:.3f}" in str(info.value)
    with pytest.raises(Unreachable):
        inverse_all(pose)
    with pytest.raises(Unreachable):
        inverse(pose, branch="nearest", current=(0,) * 6, limits=JOINT_LIMITS)


def test_bad_arguments() -> None:
    with pytest.raises(MirobotUsageError):
        forward((0.0,) * 5)
    with pytest.raises(MirobotUsageError):
        inverse((200.0, 0.0, 230.0, 0.0, 0.0))
    with pytest.raises(MirobotUsageError):
        inverse((math.nan, 0.0, 230.0, 0.0, 0.0, 0.0))
    with pytest.raises(MirobotUsageError):
        inverse(HOME_2021, branch="closest")  # type: ignore[arg-type]
    with pytest.raises(MirobotUsageError):
        inverse(HOME_2021, branch="nearest", current=(0.0,) * 5)
    with pytest.raises(MirobotUsageError):
        sample_line(HOME_2021, HOME_2021, step_mm=0.0)


def test_dh_from_settings() -> None:
    settings_2021 = {29: 127, 30: 29.69, 31: 108, 32: 20, 33: 168.98, 34: -24.28, 35: 1}
    assert DH.from_settings(settings_2021) == DH_2021
    assert DH.from_settings(DH_CLASSIC.to_settings()) == DH_CLASSIC
    with pytest.raises(MirobotUsageError, match=r"\$33"):
        DH.from_settings({29: 1, 30: 1, 31: 1, 32: 1, 34: 1})
    with pytest.raises(AttributeError):
        DH_2021.d1 = 0.0  # type: ignore[misc]


# ------------------------------------------------------------------------------------------
# Lines


def test_sample_line_spacing() -> None:
    start = (200.0, 0.0, 230.0, 0.0, 0.0, 0.0)
    end = (200.0, 30.0, 190.0, 0.0, 0.0, 10.0)  # 50 mm
    samples = sample_line(start, end, step_mm=2.0)
    assert samples.shape == (26, 6)
    assert tuple(samples[0]) == start
    assert tuple(samples[-1]) == end
    steps = np.linalg.norm(np.diff(samples[:, :3], axis=0), axis=1)
    assert np.allclose(steps, 2.0)
    assert np.allclose(np.diff(samples[:, 5]), 10.0 / 25)
    # Zero-length line: start and end.
    assert sample_line(start, start).shape == (2, 6)
    # A pure re-orientation is still sampled (ASSUMED 2 degrees per sample).
    assert sample_line(start, (*start[:3], 0.0, 0.0, 40.0)).shape == (21, 6)


def test_line_reachable() -> None:
    near_home = (198.0, 0.0, 230.0, 0.0, 0.0, 0.0)
    assert line_reachable(near_home, (180.0, 40.0, 200.0, 0.0, 0.0, 20.0), DH_2021)
    assert line_reachable((180, 50, 150, 0, 0, 0), (250, 0, 100, 0, 0, 0), DH_2021)
    # Out of reach at the far end.
    assert not line_reachable(near_home, (400.0, 0.0, 230.0, 0.0, 0.0, 0.0), DH_2021)
    # Through the base axis to the back: J1 would have to reach 180 (limit 160).
    assert not line_reachable(near_home, (-198.0, 0.0, 230.0, 0.0, 0.0, 0.0), DH_2021)
    # Without limits it still fails: it passes within A1 of the base axis, where the firmware
    # solves every point as its mirror in front of the shoulder (BehindShoulder).
    assert not line_reachable(near_home, (-198.0, 0.0, 230.0, 0.0, 0.0, 0.0), DH_2021, limits=None)
    # A line that stays in front of the shoulder, across J1 = 0.
    assert line_reachable(
        (150.0, -150.0, 230.0, 0.0, 0.0, 0.0), (150.0, 150.0, 230.0, 0.0, 0.0, 0.0), DH_2021
    )
    # Classic geometry and a tool offset are honoured.
    home_classic = forward((0,) * 6, DH_CLASSIC)
    end = (home_classic[0] - 20, 10.0, home_classic[2] - 20, 0.0, 0.0, 0.0)
    assert line_reachable(home_classic, end, DH_CLASSIC)
    tool = (0.0, 0.0, -50.0)
    tool_home = forward((0,) * 6, DH_2021, tool)
    assert tool_home[2] == pytest.approx(230.72 - 50.0)
    assert line_reachable(tool_home, (180, 20, 150, 0, 0, 0), DH_2021, tool=tool)


def test_forward_is_fast() -> None:
    q = (10.0, 20.0, -30.0, 40.0, 50.0, 60.0)
    n = 2000
    best = math.inf
    for _ in range(3):
        t0 = time.process_time()  # CPU time: other processes on a loaded machine do not count
        for _ in range(n):
            forward(q)
        best = min(best, (time.process_time() - t0) / n)
    # Target is < 20 us; allow a wide margin for slow CI machines.
    assert best < 100e-6
