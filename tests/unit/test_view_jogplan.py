"""Hold to jog's pure parts: the next move of a held jog, its speeds, and which button counts
as held (``mirobot view``; no viser, no event loop)."""

from __future__ import annotations

import itertools
import math
from typing import Any, Literal, cast

import pytest
from hypothesis import given
from hypothesis import strategies as st
from mirobot_emulator.settings import default_settings

from mirobot_async import kinematics
from mirobot_async._urdf import dh_of
from mirobot_async._view import holdjog
from mirobot_async._view.holdjog import HoldJog
from mirobot_async._view.jogplan import (
    CARTESIAN_JOINT_RATE,
    JOINT_RATE,
    LINEAR_RATE_MAX,
    MIN_STEP_SECONDS,
    TURN_RATE_MAX,
    JogAxis,
    angle_delta,
    brake_seconds,
    cartesian_speed,
    firmware_branch,
    grid_pose,
    next_step,
    on_grid,
    pose_sensitivity,
    reachable,
    step_sizes,
)

DH = dh_of("2021")
HOME = (0.0,) * 6


def test_a_move_is_due_only_while_the_queue_would_run_out_soon() -> None:
    brake = brake_seconds(JOINT_RATE)  # 40 ms
    assert brake == pytest.approx(0.04)
    # 10 ms of motion queued: runs out in 10 + 20 ms, under 40 + 8: a move of 8 ms
    assert next_step(0.02, 90.0, JOINT_RATE, brake, 0.008) == pytest.approx(0.02)
    # 40 ms queued: runs out in 60 ms, no move
    assert next_step(0.08, 90.0, JOINT_RATE, brake, 0.008) == 0.0
    # a fast loop still adds at least MIN_STEP_SECONDS of motion
    assert next_step(0.0, 90.0, JOINT_RATE, brake, 0.001) == pytest.approx(
        JOINT_RATE * MIN_STEP_SECONDS
    )
    # clamped to the edge, none at it
    assert next_step(0.0, 0.005, JOINT_RATE, brake, 0.008) == 0.005
    assert next_step(0.0, 0.0, JOINT_RATE, brake, 0.008) == 0.0


@given(
    st.floats(0.004, 0.02),  # the loop's period (s)
    st.lists(st.floats(0.5, 1.5), min_size=150, max_size=200),  # each round's length / period
)
def test_a_cruising_jog_stops_within_one_braking_time_and_two_periods(
    period: float, jitter: list[float]
) -> None:
    """A joint jog against a model of the arm (it accelerates at 50 deg/s^2 up to the jog's
    speed, never faster than lets it stop at the end of its queue): let go at any reading while
    it cruises, it would stand still within the braking time and two periods (three while it
    speeds up: the queue is planned for the jog's speed), and once under way it cruises at
    nearly the jog's speed (a late round lets it slow down a little)."""
    rate, accel = JOINT_RATE, 50.0
    brake = brake_seconds(rate, accel)
    ahead = speed = moved = elapsed = 0.0
    for factor in jitter:
        ahead += next_step(ahead, math.inf, rate, brake, period)
        stands_in = _stands_in(ahead, speed, rate, accel)  # let go here: nothing more is sent
        periods = 2 if speed >= rate * 0.999 else 3
        assert stands_in <= brake + periods * max(period, MIN_STEP_SECONDS) + 0.001
        for _ in range(10):  # the round, in tenths
            before = ahead
            ahead, speed = _arm(ahead, speed, rate, accel, period * factor / 10)
            moved += (before - ahead) if elapsed > 0.1 else 0.0
            elapsed += period * factor / 10
    assert moved / (elapsed - 0.1) > 0.8 * rate


def _stands_in(left: float, speed: float, rate: float, accel: float) -> float:
    """Seconds the model arm takes to run out a queue of ``left`` from ``speed``."""
    if speed * speed / (2 * accel) >= left:  # braking already
        return math.sqrt(2 * left / accel)
    peak = min(rate, math.sqrt(accel * left + speed * speed / 2))
    cruise = left - (peak * peak - speed * speed) / (2 * accel) - peak * peak / (2 * accel)
    return (peak - speed) / accel + cruise / peak + peak / accel


def _arm(ahead: float, speed: float, rate: float, accel: float, dt: float) -> tuple[float, float]:
    """The arm after ``dt`` s: what is left of its queue and its speed (it speeds up to
    ``rate``, and never faster than lets it stop at the end of the queue)."""
    speed = min(rate, speed + accel * dt, math.sqrt(2 * accel * ahead))
    return ahead - min(ahead, speed * dt), speed


def test_cartesian_speeds_keep_the_joints_at_the_rate() -> None:
    for axis in range(6):
        for sensitivity in (0.05, 0.4, 0.75, 1.0, 3.0, 40.0):
            speed = cartesian_speed(axis, sensitivity)
            assert speed.joint_rate <= CARTESIAN_JOINT_RATE + 1e-9
            if axis < 3:
                assert speed.rate <= LINEAR_RATE_MAX
                assert speed.feed == pytest.approx(speed.rate * 60)
                assert speed.joint_rate == pytest.approx(speed.rate * sensitivity)
            else:
                # F (deg/min along the joints' path, as the virtual arm reads it) is at most
                # the turn cap and the joint rate, and read as the turn's own rate it still
                # keeps the joints at the rate
                assert speed.feed / 60 <= TURN_RATE_MAX
                assert speed.feed / 60 * sensitivity <= max(
                    CARTESIAN_JOINT_RATE, speed.feed / 60
                ) * max(1.0, sensitivity)
                assert speed.rate == pytest.approx(speed.feed / 60 / sensitivity)
    assert cartesian_speed(0, 0.75).rate == pytest.approx(2.0)  # X at home


@pytest.mark.parametrize(
    "joints",
    [HOME, (0, 0, 0, 0, -30, 0), (30, 20, 10, 0, -30, 0), (0, 30, -20, 10, -60, 20)],
)
@pytest.mark.parametrize("axis", range(6))
def test_pose_sensitivity_is_the_joint_motion_per_unit(
    joints: tuple[float, ...], axis: int
) -> None:
    sensitivity = pose_sensitivity(joints, axis, 1, DH)
    assert sensitivity is not None
    pose = list(kinematics.forward(joints, DH))
    pose[axis] += 0.5
    moved = kinematics.inverse(pose, DH, "firmware")
    gap = math.dist(moved, joints)
    assert sensitivity == pytest.approx(gap / 0.5, rel=0.05)


def test_the_edge_of_the_reach() -> None:
    # stretched out along x: further out has no solution, back in has one
    pose = list(kinematics.forward(HOME, DH))
    while reachable(tuple(pose), DH):
        pose[0] += 1.0
    pose[0] -= 1.0
    joints = kinematics.inverse(pose, DH, "firmware")
    assert pose_sensitivity(joints, 0, 1, DH) is None or not reachable(
        (pose[0] + 1.0, *pose[1:]), DH
    )
    assert pose_sensitivity(joints, 0, -1, DH) is not None


def test_the_firmware_branch() -> None:
    assert firmware_branch(HOME, DH)
    assert firmware_branch((30, 20, 10, 0, -30, 0), DH)
    # J4 and J6 a full turn round are the same configuration (the firmware keeps them)
    assert firmware_branch((0, 0, 0, 360, -30, -360), DH)
    # the wrist flipped (J5 beyond -90): the firmware would swing it over (J4, J6 half a
    # turn) before a Cartesian move
    assert not firmware_branch((0, 20, 10, 0, -120, 0), DH)


def test_motor_steps_from_the_settings() -> None:
    """``$100..$106`` are per axis letter (J4, J5, J6, rail, J1, J2, J3): the 2021 J6 turns
    0.09 deg a step, J2 under 0.01."""
    steps = step_sizes(default_settings("2021"))
    assert steps[5] == pytest.approx(0.09, abs=1e-3)
    assert steps[3] == pytest.approx(0.0625)
    assert steps[1] == pytest.approx(1 / 113.33)
    assert step_sizes({}) == (0.0,) * 6
    assert on_grid(0.1, 0.09) == pytest.approx(0.09)
    assert on_grid(0.04, 0.09) == 0.0
    assert on_grid(0.04, 0.0) == 0.04


def test_where_a_cartesian_target_ends_on_the_motor_steps() -> None:
    steps = step_sizes(default_settings("2021"))
    pose = list(kinematics.forward(HOME, DH))
    pose[5] += 0.04  # RZ: J6 alone, under half a step of it
    assert grid_pose(tuple(pose), HOME, steps, DH) == pytest.approx(kinematics.forward(HOME, DH))
    pose[5] += 0.04  # past half a step: one step
    ends = grid_pose(tuple(pose), HOME, steps, DH)
    assert ends is not None and ends[5] == pytest.approx(steps[5], abs=1e-6)
    assert grid_pose((400.0, 0.0, 230.0, 0.0, 0.0, 0.0), HOME, steps, DH) is None


def test_angles_wrap() -> None:
    assert angle_delta(179.0, -179.0) == pytest.approx(-2.0)
    assert angle_delta(-179.0, 179.0) == pytest.approx(2.0)
    assert angle_delta(10.0, 370.0) == pytest.approx(0.0)


def test_every_hold_button_has_its_own_text() -> None:
    kinds: tuple[Literal["joint", "pose"], ...] = ("joint", "pose")
    axes = [JogAxis(kind, i, sign) for kind, i, sign in itertools.product(kinds, range(6), (-1, 1))]
    labels = [a.label for a in axes]
    assert len(set(labels)) == 24
    assert JogAxis("joint", 0, 1).label == "J1 +"
    assert JogAxis("pose", 3, -1).label == "RX -"
    assert JogAxis("pose", 2, 1).unit == "mm" and JogAxis("pose", 5, 1).unit == "deg"


# ------------------------------------------------------------------------------------------
# Which button is held (HoldJog's state: keep-alives and releases from viser's thread)

X_PLUS = JogAxis("pose", 0, 1)
X_MINUS = JogAxis("pose", 0, -1)


def _jog() -> HoldJog:
    said: list[str] = []
    return HoldJog(cast(Any, None), said.append, "2021")


def test_the_first_keep_alive_starts_a_jog_and_the_next_ones_keep_it() -> None:
    jog = _jog()
    assert jog.press(X_PLUS)
    assert not jog.press(X_PLUS)
    assert jog._holding(X_PLUS)
    jog.release()
    assert not jog._holding(X_PLUS)
    assert jog.ended_by == "release" and jog.released_at is not None


def test_a_keep_alive_of_another_button_lets_go_of_the_first() -> None:
    """The page's click can be lost behind another press (it sends the latest message per
    50 ms): the running jog ends, and the other one starts after it."""
    jog = _jog()
    assert jog.press(X_PLUS)
    assert not jog.press(X_MINUS)  # the X + jog still runs (stopping)
    assert not jog._holding(X_PLUS)
    assert jog.ended_by == "another button"
    jog._running = None  # run() ended
    assert jog.take_next() == X_MINUS
    assert jog._holding(X_MINUS)


def test_no_keep_alive_for_the_watchdog_ends_the_jog() -> None:
    said: list[str] = []
    jog = HoldJog(cast(Any, None), said.append, "2021")
    assert jog.press(X_PLUS)
    assert jog._holding(X_PLUS)
    jog._keepalive -= holdjog.WATCHDOG + 0.01  # the last keep-alive that long ago
    assert not jog._holding(X_PLUS)
    assert jog.ended_by == "watchdog"
    assert said == ["**X + (hold): no keep-alive from the page**"]


def test_a_jog_ended_at_an_edge_is_not_restarted_until_let_go() -> None:
    jog = _jog()
    assert jog.press(X_PLUS)
    jog._running = None  # run() ended at the edge, the button still held
    jog._stuck = X_PLUS
    assert jog.take_next() is None
    assert not jog.press(X_PLUS)
    jog.release()
    assert jog.press(X_PLUS)


def test_a_refused_jog_is_forgotten() -> None:
    jog = _jog()
    assert jog.press(X_PLUS)
    jog.refused()
    assert jog.take_next() is None
    assert jog.press(X_PLUS)
