"""Stateful test: random sequences of client calls against a real emulator process.

A hypothesis ``RuleBasedStateMachine`` owns an :class:`asyncio.Runner`; each example starts a
fresh emulator (profile drawn at random), connects the client, and runs random moves (valid and
invalid), homing, unlock, pump/valve, limit toggles, holds, resets, hard limits and status reads.
A plain-Python model of the arm predicts what each call must do (succeed, or raise which error)
and, after every step, the client's view (``last_status``, ``alarm``, ``needs_reset``,
``pending_count``), the emulator's status and the model must agree.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Coroutine, Iterator
from dataclasses import dataclass
from typing import Any, TypeVar

import pytest
from hypothesis import HealthCheck, note, settings
from hypothesis import strategies as st
from hypothesis.stateful import (
    RuleBasedStateMachine,
    initialize,
    invariant,
    precondition,
    rule,
)
from waiting import wait_until

from mirobot_async import (
    Mirobot,
    MirobotAlarmError,
    MirobotCommandError,
    MirobotUsageError,
    MotionRefusedError,
    RefusalReason,
    State,
    StatusReport,
)
from mirobot_async.kinematics import (
    DH_2021,
    DH_CLASSIC,
    JOINT_LIMITS,
    forward,
    in_limits,
    inverse,
)
from mirobot_async.testing import EmulatorPool, SyncEmulatorProcess

# 12 examples of 20 steps take 2-4 s (6-20 s at time scale 50), longer on a loaded CI host's pty
# lane (one run cut at 120 s in a 30 s wait_idle); every wait inside has its own bound, which
# names what it waited for: the test's bound stays above them.
pytestmark = pytest.mark.timeout(300)

_POOL: list[EmulatorPool] = []  # the session's pool while a test of this module runs


@pytest.fixture(autouse=True)
def _emulator_pool(mirobot_emulator_pool: EmulatorPool) -> Iterator[None]:
    """Each example borrows a renewed emulator from the session's pool (milliseconds, not a
    process start); the state machine cannot take fixtures, so it finds the pool here."""
    _POOL.append(mirobot_emulator_pool)
    yield
    _POOL.remove(mirobot_emulator_pool)


T = TypeVar("T")
TIME_SCALE = 500.0
"""Nothing here judges the arm's timing, only where it ends: its moves and homing may be quick.
``hold_and_resume`` moves slowly enough (``HOLD_SPEED``) for its hold to land mid-move."""
HOLD_SPEED = 300.0
"""J1 moves at least 115 degrees at this speed: tens of milliseconds at ``TIME_SCALE``."""
JOINT_TOL = 0.05  # half a motor step (the firmware moves in whole steps)
# A relative move without M21 adds to the parser's exact position, which stands up to half a
# step from the arm's (the arm lands on the step nearest the parser's target): from the last
# status, a relative move ends within one step of the sum. Steps per degree of J1..J6 (both
# profiles): 56.73, 113.33, 64, 16, 22.22, 11.11 (2021 J6 +24.7 then +0.1: 24.662, 24.842).
STEP_TOL = tuple(
    max(JOINT_TOL, 1 / steps + 1e-6) for steps in (56.73, 113.33, 64, 16, 22.22, 11.11)
)
POSE_TOL = 0.1

# Targets comfortably inside the soft limits (so G0 joint moves never trip anything).
SAFE_RANGES = ((-90.0, 150.0), (-25.0, 65.0), (-160.0, 55.0), (-340.0, 340.0), (-200.0, 30.0),
               (-350.0, 350.0))  # fmt: skip
angles = st.integers(-1000, 1000).map(lambda n: n / 10)  # one decimal: exact on the wire


def joint_targets() -> st.SearchStrategy[tuple[float | None, ...]]:
    def one(lo_hi: tuple[float, float]) -> st.SearchStrategy[float | None]:
        lo, hi = lo_hi
        return st.none() | st.integers(int(lo * 10), int(hi * 10)).map(lambda n: n / 10)

    return st.tuples(*(one(r) for r in SAFE_RANGES)).filter(lambda t: any(v is not None for v in t))


poses = st.tuples(
    st.integers(120, 260),
    st.integers(-120, 120),
    st.integers(60, 260),
    st.sampled_from([0, 0, 10, -10, 30]),
    st.sampled_from([0, 0, 10, -15, 20]),
    st.sampled_from([0, 0, 15, -20, 45]),
).map(lambda p: tuple(float(v) for v in p))


@dataclass
class Model:
    """What the arm should be doing, in plain Python."""

    profile: str
    locked: bool = True
    alarm: bool = False  # the firmware is in Alarm (G-code lines get "Alarm lock")
    needs_reset: bool = False  # hard limit: nothing but a reset
    joints: tuple[float, ...] | None = (0.0,) * 6  # None: known only from the next status
    pose: tuple[float, ...] | None = None  # a pose target to check instead of joints
    pump: int = 0
    valve: int = 0
    mode: int = 0  # Motion_MODE: 1 after M20, 0 after M21 / homing / reset

    def __post_init__(self) -> None:
        self.alarm = self.profile != "classic"

    @property
    def dh(self) -> Any:
        return DH_CLASSIC if self.profile == "classic" else DH_2021

    def after_reset(self) -> None:
        # the axis lock survives a reset: only power-on sets it (oracle), M50 / homing clear it;
        # so does an Alarm (oracle: a second % after an abort still reports Alarm)
        self.alarm = self.alarm or self.needs_reset
        self.needs_reset = False
        self.pump = self.valve = 0
        self.mode = 0

    def after_home(self) -> None:
        self.locked = self.alarm = False
        self.joints = (0.0,) * 6
        self.pose = None
        self.pump = self.valve = 0
        self.mode = 0


class ClientMachine(RuleBasedStateMachine):
    def __init__(self) -> None:
        super().__init__()
        self.runner = asyncio.Runner()
        self.emu: SyncEmulatorProcess | None = None
        self.arm: Mirobot | None = None
        self.model = Model("2021")

    def run(self, coro: Coroutine[Any, Any, T]) -> T:
        return self.runner.run(coro)

    def teardown(self) -> None:
        async def close() -> None:
            if self.arm is not None:
                await self.arm.close()

        try:
            self.run(close())
        finally:
            self.runner.close()
            if self.emu is not None:
                _POOL[-1].release(self.emu)

    @initialize(profile=st.sampled_from(["2021", "classic", "2024"]))
    def start(self, profile: str) -> None:
        note(f"profile {profile}")
        self.model = Model(profile)

        self.emu = _POOL[-1].acquire(profile, TIME_SCALE)
        url = self.emu.url

        async def connect() -> Mirobot:
            return await Mirobot.connect(url)

        self.arm = self.run(connect())

    # ---- helpers ----

    @property
    def client(self) -> Mirobot:
        assert self.arm is not None
        return self.arm

    def expect_blocked(self, call: Coroutine[Any, Any, Any], *, motion: bool) -> bool:
        """If the model says the call cannot run, check that it raises; return True then."""
        m = self.model
        if m.needs_reset:
            sent = self.client.stats.bytes_sent
            with pytest.raises(MirobotAlarmError, match="Hard limit"):
                self.run(call)
            assert self.client.stats.bytes_sent == sent
            return True
        if motion and m.alarm:
            with pytest.raises(MirobotAlarmError):
                self.run(call)
            return True
        return False

    # ---- rules ----

    @rule()
    def read_status(self) -> None:
        call = self.client.status()
        if self.expect_blocked(call, motion=False):
            return
        report = self.run(call)
        self.check_report(report)

    @rule()
    def unlock(self) -> None:
        call = self.client.unlock()
        if self.expect_blocked(call, motion=False):
            return
        self.run(call)
        self.model.locked = self.model.alarm = False

    @rule(sequential=st.booleans())
    def home(self, sequential: bool) -> None:
        call = self.client.home(sequential)
        if self.expect_blocked(call, motion=False):
            return
        report = self.run(call)
        self.model.after_home()
        assert report.joints == (0.0,) * 6 and report.state is State.IDLE

    @rule(goal=joint_targets(), speed=st.none() | st.sampled_from([900.0, 3000.0]))
    def move_joints(self, goal: tuple[float | None, ...], speed: float | None) -> None:
        m = self.model
        call = self.client.move_joints(*goal, speed=speed)
        if self.expect_blocked(call, motion=True):
            return
        if m.locked:
            with pytest.raises(MotionRefusedError) as info:
                self.run(call)
            assert info.value.reason is RefusalReason.LOCKED
            m.mode = 0
            return
        report = self.run(call)
        assert report is not None and report.state is State.IDLE
        m.mode = 0
        if m.joints is None:
            m.joints = report.joints
        m.joints = tuple(
            old if new is None else new for old, new in zip(m.joints, goal, strict=True)
        )
        m.pose = None
        self.check_report(report)

    @rule(joint=st.integers(0, 5), delta=angles)
    def move_relative(self, joint: int, delta: float) -> None:
        m = self.model
        values: list[float | None] = [None] * 6
        values[joint] = delta
        call = self.client.move_joints(*values, relative=True, speed=3000)
        if self.expect_blocked(call, motion=True):
            return
        if m.locked:
            with pytest.raises(MotionRefusedError) as info:
                self.run(call)
            assert info.value.reason is RefusalReason.LOCKED
            m.mode = 0
            return
        if m.joints is None:
            m.joints = self.run(self.client.status()).joints
        lo, hi = JOINT_LIMITS[joint]
        goal = m.joints[joint] + delta
        m.mode = 0
        if not lo <= goal <= hi:
            with pytest.raises(MotionRefusedError) as info:
                self.run(call)
            assert info.value.reason is RefusalReason.SOFT_LIMIT
            return
        report = self.run(call)
        assert report is not None
        joints = list(m.joints)
        joints[joint] = goal
        m.joints = tuple(joints)
        m.pose = None
        self.check_report(report)

    @rule(pose=poses, linear=st.booleans())
    def move_pose(self, pose: tuple[float, ...], linear: bool) -> None:
        m = self.model
        call = self.client.move_pose(*pose, linear=linear, speed=3000 if linear else None)
        if self.expect_blocked(call, motion=True):
            return
        # the firmware's order for a point-to-point move (oracle): the IK (unreachable), the
        # lock, then the soft limits ($20=1 here: their ranges are the factory JOINT_LIMITS)
        try:
            solution = inverse(pose, m.dh, "firmware", limits=None)
        except MirobotUsageError as err:  # Unreachable
            expected: RefusalReason | None = RefusalReason.UNREACHABLE
            note(f"IK: {err}")
        else:
            note(f"IK: {solution}")
            if m.locked:
                expected = RefusalReason.LOCKED
            elif not in_limits(solution, JOINT_LIMITS):
                expected = RefusalReason.SOFT_LIMIT
            else:
                expected = None
        if expected is None and not linear:
            report = self.run(call)
            assert report is not None
            m.mode, m.joints, m.pose = 1, None, pose
            self.check_report(report)
            return
        try:
            report = self.run(call)
        except MotionRefusedError as err:
            m.mode = 1
            if not linear:
                assert err.reason is expected
            elif m.locked:
                assert err.reason in (
                    RefusalReason.LOCKED,
                    RefusalReason.UNREACHABLE,
                    RefusalReason.ANGLE_OUT_OF_LIMIT,
                    RefusalReason.SOFT_LIMIT,
                )
            else:  # a straight line may leave the workspace although both ends are inside
                # (the firmware checks each interpolated point: 'Soft limit triggered:<axis>')
                assert err.reason in (
                    RefusalReason.UNREACHABLE,
                    RefusalReason.ANGLE_OUT_OF_LIMIT,
                    RefusalReason.SOFT_LIMIT,
                )
            return
        assert expected is None, f"expected a refusal ({expected}), got {report}"
        assert report is not None
        m.mode, m.joints, m.pose = 1, None, pose
        self.check_report(report)

    @rule()
    def invalid_move(self) -> None:
        sent = self.client.stats.bytes_sent
        with pytest.raises(MirobotUsageError):
            self.run(self.client.move_joints(j2=200))
        with pytest.raises(MirobotUsageError):
            self.run(self.client.move_pose(x=math.inf))
        assert self.client.stats.bytes_sent == sent

    @rule()
    def bad_line(self) -> None:
        call = self.client.send("M99", validate=False)  # the firmware must refuse it
        if self.expect_blocked(call, motion=True):
            return
        with pytest.raises(MirobotCommandError, match="Unsupported command"):
            self.run(call)

    @rule(pwm=st.integers(0, 1000), valve=st.booleans())
    def set_output(self, pwm: int, valve: bool) -> None:
        call = self.client.set_valve(pwm) if valve else self.client.set_pump(pwm)
        if self.expect_blocked(call, motion=False):
            return
        if self.model.alarm:
            with pytest.raises(MirobotAlarmError, match="Alarm lock"):
                self.run(call)
            return
        self.run(call)
        if valve:
            self.model.valve = pwm
        else:
            self.model.pump = pwm

    @rule(soft=st.booleans(), on=st.booleans())
    def toggle_limits(self, soft: bool, on: bool) -> None:
        # (turned back on at once: a move beyond a switch would trip a hard limit)
        arm = self.client
        first = arm.set_soft_limits(on) if soft else arm.set_hard_limits(on)
        if self.expect_blocked(first, motion=False):
            return
        self.run(first)
        settings_now = self.run(arm.settings())
        assert settings_now[20 if soft else 21] == (1.0 if on else 0.0)
        self.run(arm.set_soft_limits(True) if soft else arm.set_hard_limits(True))
        assert arm.firmware == self.model.profile

    @precondition(lambda self: not self.model.locked and not self.model.alarm)
    @precondition(lambda self: not self.model.needs_reset)
    @rule()
    def hold_and_resume(self) -> None:
        m = self.model
        arm = self.client
        if m.joints is None:
            m.joints = self.run(arm.status()).joints
        goal = -80.0 if m.joints[0] > 35 else 150.0
        assert self.run(arm.move_joints(j1=goal, speed=HOLD_SPEED, wait=False)) is None
        held = self.run(arm.hold())
        note(f"held: {held.to_line()}")
        assert held.state in (State.HOLD, State.IDLE)
        if held.state is State.HOLD:
            assert self.run(arm.status()).state is State.HOLD
        self.run(arm.resume())
        report = self.run(arm.wait_idle(timeout=30))
        assert report.joints[0] == pytest.approx(goal, abs=JOINT_TOL)
        m.joints = (goal, *m.joints[1:])
        m.pose = None
        m.mode = 0

    @rule()
    def reset(self) -> None:
        banner = self.run(self.client.reset())
        if self.model.profile == "2024":  # its one-line banner (EVIDENCE-NEWER.md)
            assert banner and banner[-1].startswith("WLKATA Robot started successfully.")
        else:
            assert banner and banner[-1] == "Using reset pos!"
        self.model.after_reset()
        assert not self.client.needs_reset

    @precondition(lambda self: not self.model.needs_reset)
    @rule()
    def hard_limit(self) -> None:
        assert self.emu is not None
        self.emu.control("hard-limit")

        self.run(wait_until(lambda: self.client.needs_reset, 5, "the alarm"))
        self.model.needs_reset = True
        self.model.alarm = True

    # ---- agreement -------------------------------------------------------------------------------

    def check_report(self, report: StatusReport) -> None:
        m = self.model
        note(f"status: {report.to_line()}")
        expected_state = State.ALARM if m.alarm else State.IDLE
        assert report.state is expected_state, (report.state, m)
        if m.joints is not None:
            for got, want, tol in zip(report.joints, m.joints, STEP_TOL, strict=True):
                assert abs(got - want) <= tol, (report.joints, m.joints)
            expected_pose = forward(m.joints, m.dh)
            for got, want in zip(report.pose[:3], expected_pose[:3], strict=True):
                assert abs(got - want) <= POSE_TOL, (report.pose, expected_pose)
            # At rest the arm stands on its step grid, and a line with M21 restarts from there
            # (the firmware resynchronises its parser): a relative move adds to these joints,
            # not to the exact sum of the deltas (J6 -53.9 then +12.1: -41.854, not -41.8).
            m.joints = report.joints
        if m.pose is not None:
            for i, (got, want) in enumerate(zip(report.pose, m.pose, strict=True)):
                diff = abs(got - want) if i < 3 else abs((got - want + 180) % 360 - 180)
                assert diff <= POSE_TOL, (report.pose, m.pose)
        assert (report.pump_pwm, report.valve_pwm) == (m.pump, m.valve)
        assert report.motion_mode == m.mode

    @invariant()
    def client_and_robot_agree(self) -> None:
        if self.arm is None:
            return
        arm = self.client
        assert arm.pending_count == 0
        assert arm.needs_reset is self.model.needs_reset
        assert (arm.alarm is not None) is self.model.needs_reset
        if self.model.needs_reset:
            return
        report = self.run(arm.status())
        assert arm.last_status == report
        self.check_report(report)
        if self.model.joints is None:
            self.model.joints = report.joints
            self.model.pose = None


ClientMachine.TestCase.settings = settings(
    max_examples=12,
    stateful_step_count=20,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
TestClientStateful = ClientMachine.TestCase
