"""Hold to jog: a joint or a Cartesian axis moves while its button is held and the arm stands
still soon after the button is let go.

The page (viser's hold buttons) sends a keep-alive every :data:`KEEPALIVE_HZ`\\ th of a second
while a button is held and a click when it is let go. Both are taken on viser's event loop the
moment they arrive (:meth:`HoldJog.press`, :meth:`HoldJog.release`: plain calls under a lock,
no hop through a thread pool or onto the client's loop). The jog itself runs on the client's
loop: it reads fresh statuses and sends short moves only while the motion queued ahead of the
arm is about its braking distance (:mod:`~mirobot_async._view.jogplan`), so

- once the release is known no move is sent and the arm stands still at the end of the queued
  motion: about its braking time (40 ms at 2 deg/s) and a status period later;
- a keep-alive of another button means this one was let go: the page sends at most one GUI
  message per 50 ms, the latest, so a click followed at once by another press can be lost;
- when the page goes away the keep-alives stop: viser's disconnect ends the jog at once (page
  closed), :data:`WATCHDOG` seconds without a keep-alive end it otherwise (the page stalled or
  its link silently lost); when the link to the arm goes, nothing more is sent and the arm
  stops by itself;
- a status other than ``Run`` or ``Idle`` (Hold, Alarm) ends it;
- every move goes through the client, which checks it against the envelope when one is given;
  a move the envelope or the firmware refuses, a joint's range or the arm's reach ends the jog
  there, with the reason on the page (and it is not started again until the button is let go).

Keep-alives are few on purpose: the page's one GUI sender sends at most one message per 50 ms
(later when the page is busy rendering), so a release within that time after a keep-alive
waits for it; at :data:`KEEPALIVE_HZ` that is one release in ten or fewer.
"""

from __future__ import annotations

import asyncio
import sys
import threading
import time
from typing import TYPE_CHECKING, Final

from mirobot_async._core.replies import State, StatusReport
from mirobot_async._core.values import JOINT_NAMES, JOINT_RANGES
from mirobot_async._urdf import dh_of
from mirobot_async._view.jogplan import (
    JOINT_RATE,
    CartesianSpeed,
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
from mirobot_async.errors import EnvelopeRefusedError, MirobotError, MotionRefusedError

if TYPE_CHECKING:
    from collections.abc import Callable

    from mirobot_async import kinematics
    from mirobot_async._client.client import Mirobot

__all__ = ["KEEPALIVE_HZ", "WATCHDOG", "HoldJog"]

KEEPALIVE_HZ: Final = 2.0
"""Keep-alives per second the page sends while a hold button is held."""
WATCHDOG: Final = 1.0
"""Seconds without a keep-alive after which a held jog ends (the page stalled or its link is
gone): twice the keep-alive period, as a page rendering in software delays its timers."""
_TICK: Final = 0.005
"""Seconds between a jog's status and its next request."""
_PERIOD: Final = (0.005, 0.02)
"""Bounds of the status period a jog plans with (s): a slower loop lets the queue run dry
(the arm pauses between moves) rather than queue more than the aim allows."""
_EDGE: Final = 1e-6


class HoldJog:
    """Which button is held (any thread, under a lock) and the held jog's motion (the client's
    loop)."""

    def __init__(self, arm: Mirobot, say: Callable[[str], None], firmware: str) -> None:
        self.arm = arm
        self.say = say
        self.dh = dh_of(firmware)
        self._lock = threading.Lock()
        self._held: JogAxis | None = None
        """The button held now, per the page's last message."""
        self._running: JogAxis | None = None
        """What the jog queued or running moves (``None``: no jog)."""
        self._stuck: JogAxis | None = None
        """A jog that ended at an edge while its button stayed held: not started again until
        the button is let go."""
        self._keepalive = 0.0
        """``time.monotonic()`` of the last keep-alive."""
        self.released_at: float | None = None
        """``time.time()`` when the running jog's button was let go (or the watchdog ended it)."""
        self.ended_by = "release"
        """What ended the last jog: ``release`` (the page's click), ``page closed`` (viser saw
        the page go), ``another button`` (a keep-alive of another one) or ``watchdog``."""
        self.latencies: list[float] = []
        """Seconds from each release to the first status showing the arm stopped."""
        self.steps: tuple[float, ...] | None = None
        """Degrees per motor step of J1..J6 (from ``$$``, read before the first jog; empty
        when it cannot be read)."""

    # any thread: viser's event loop ---------------------------------------------------
    def press(self, axis: JogAxis) -> bool:
        """A keep-alive of ``axis``'s button; ``True`` when it starts a jog (the caller then
        queues :meth:`run`)."""
        with self._lock:
            self._keepalive = time.monotonic()
            if self._stuck != axis:
                self._stuck = None
            if self._running is not None and self._running != axis and self._held != axis:
                self._let_go("another button")
            self._held = axis
            if self._running is not None or self._stuck == axis:
                return False
            self._running = axis
            self.released_at = None
            return True

    def release(self, why: str = "release") -> None:
        """The button was let go (``why``: or the page went away)."""
        with self._lock:
            self._held = None
            self._stuck = None
            self._let_go(why)

    def refused(self) -> None:
        """The jog :meth:`press` started was refused (not queued)."""
        with self._lock:
            self._running = None
            self._held = None

    def take_next(self) -> JogAxis | None:
        """After :meth:`run`: the button held now if it is another one whose jog should start
        (``None`` otherwise); it then counts as started, as from :meth:`press`."""
        with self._lock:
            fresh = time.monotonic() - self._keepalive <= WATCHDOG
            held = self._held
            if self._running is not None or held is None or held == self._stuck or not fresh:
                return None
            self._running = self._held
            self.released_at = None
            return self._held

    def _let_go(self, why: str) -> None:
        if self._running is not None and self.released_at is None:
            self.released_at = time.time()
            self.ended_by = why

    def _holding(self, axis: JogAxis) -> bool:
        with self._lock:
            if self._held != axis or self.released_at is not None:
                return False
            if time.monotonic() - self._keepalive <= WATCHDOG:
                return True
            self._held = None
            self._let_go("watchdog")
        self.say(f"**{axis.label} (hold): no keep-alive from the page**")
        return False

    # on the client's loop -------------------------------------------------------------
    async def run(self, axis: JogAxis) -> str:
        """Jog ``axis`` while its button is held; returns, said for the page, once the arm
        stands still."""
        name = f"{axis.label} (hold)"
        loop = asyncio.get_running_loop()
        why = "released"
        try:
            report = await self.arm.status(fresh=True)
            if report.state is not State.IDLE:
                return f"{name}: refused: the arm is {report.state.value}, not Idle"
            if self.steps is None:
                self.steps = await self._read_steps()
            motion: _Motion = (
                _JointMotion(self.arm, axis, self.steps)
                if axis.kind == "joint"
                else _PoseMotion(self, axis, self.steps)
            )
            refusal = motion.start(report)
            if refusal is not None:
                return f"{name}: refused: {refusal}"
            try:
                seen = loop.time()
                period = _PERIOD[0]
                while self._holding(axis):
                    if report.state not in (State.RUN, State.IDLE):
                        why = f"the arm went {report.state.value}"
                        break
                    step = motion.plan(report, period)
                    if step is None:
                        why = motion.edge
                        break
                    if step > 0.0:
                        await motion.send(step)  # its reply took a while: no tick
                    else:
                        await asyncio.sleep(_TICK)
                    report = await self.arm.status(fresh=True)
                    now = loop.time()
                    period = min(max(0.7 * period + 0.3 * (now - seen), _PERIOD[0]), _PERIOD[1])
                    seen = now
            except (EnvelopeRefusedError, MotionRefusedError) as err:
                why = f"refused at the edge: {err}"
        finally:
            with self._lock:
                self._running = None
                if self.released_at is None and self._held == axis:
                    self._stuck = axis  # ended by an edge, a refusal or an error while held
        stopped = await self._stopped(report)
        where = _where(stopped, axis)
        if self.released_at is None:
            return f"{name}: stopped ({why}) at {where}"
        latency = time.time() - self.released_at
        self.latencies.append(latency)
        print(
            f"mirobot: view: hold jog {name}: stopped {latency * 1000:.0f} ms after the "
            f"{self.ended_by} (at {self.released_at:.3f}, "
            f"stopped at {self.released_at + latency:.3f})",
            file=sys.stderr,
            flush=True,
        )
        return f"{name}: stopped at {where}, {latency * 1000:.0f} ms after the {self.ended_by}"

    async def _read_steps(self) -> tuple[float, ...]:
        """The joints' motor steps from ``$$`` (``()``: unknown, every target then taken as
        the arm runs it)."""
        try:
            return step_sizes(await self.arm.settings())
        except MirobotError:
            return ()

    async def _stopped(self, report: StatusReport) -> StatusReport:
        """The first status showing the arm stopped (not ``Run``: ``Idle`` once its queue ran
        out)."""
        while report.state is State.RUN:
            report = await self.arm.status(fresh=True)
        return report


def _queued(ahead: float, report: StatusReport) -> float:
    """The motion queued ahead of the arm: ``ahead`` (its target less its position) while it
    runs, none once it reports ``Idle`` (its queue ran out)."""
    return ahead if report.state is State.RUN else 0.0


def _where(report: StatusReport, axis: JogAxis) -> str:
    """Where the arm stands along ``axis`` (for the page)."""
    if axis.kind == "joint":
        return f"{report.joints[axis.index]:.2f}"
    return f"{report.pose[axis.index]:.2f} {axis.unit}"


class _Motion:
    """One held jog's moves: where it stands along its axis and the next move."""

    edge = "at the edge"

    def start(self, report: StatusReport) -> str | None:
        """Take the arm's position; why the jog cannot start, or ``None``."""
        raise NotImplementedError

    def plan(self, report: StatusReport, period: float) -> float | None:
        """The next move's length (0: none now), ``None`` at the edge (:attr:`edge` says
        which)."""
        raise NotImplementedError

    async def send(self, step: float) -> None:
        raise NotImplementedError


class _JointMotion(_Motion):
    """Absolute moves of one joint at :data:`~mirobot_async._view.jogplan.JOINT_RATE`,
    clamped to its range."""

    edge = "at the end of the joint's range"

    def __init__(self, arm: Mirobot, axis: JogAxis, steps: tuple[float, ...]) -> None:
        self.arm = arm
        self.axis = axis
        self.step = steps[axis.index] if steps else 0.0
        low, high = JOINT_RANGES[JOINT_NAMES[axis.index]]
        self.end = high if axis.sign > 0 else low
        self.target = 0.0

    def start(self, report: StatusReport) -> str | None:
        self.target = report.joints[self.axis.index]
        return None

    def plan(self, report: StatusReport, period: float) -> float | None:
        sign = self.axis.sign
        room = (self.end - self.target) * sign
        if room <= _EDGE:
            return None
        queued = on_grid(self.target, self.step) - report.joints[self.axis.index]
        ahead = _queued(queued * sign, report)
        return next_step(ahead, room, JOINT_RATE, brake_seconds(JOINT_RATE), period)

    async def send(self, step: float) -> None:
        target = self.target + self.axis.sign * step
        moves: list[float | None] = [None] * 6
        moves[self.axis.index] = target
        await self.arm.move_joints(*moves, speed=JOINT_RATE * 60.0, wait=False)
        self.target = target


class _PoseMotion(_Motion):
    """Relative straight-line moves of one pose coordinate (as the step jogs: ``relative``
    adds to the pose component-wise), at the speed that keeps the joints at
    :data:`~mirobot_async._view.jogplan.CARTESIAN_JOINT_RATE` where the arm is; each
    target's reach is checked first with the firmware's inverse kinematics. Poses here are the
    forward kinematics of the joints (the status's own pose may add the base offset)."""

    edge = "at the edge of the arm's reach"

    def __init__(self, jog: HoldJog, axis: JogAxis, steps: tuple[float, ...]) -> None:
        self.arm = jog.arm
        self.dh: kinematics.DH = jog.dh
        self.axis = axis
        self.steps = steps
        self.start_pose: tuple[float, ...] = ()
        self.sent = 0.0
        self.speed: CartesianSpeed | None = None

    def start(self, report: StatusReport) -> str | None:
        if not firmware_branch(report.joints, self.dh):
            return (
                "the arm stands in another configuration than the firmware's Cartesian moves "
                "use (a Cartesian move would first swing it over): jog its joints instead"
            )
        self.start_pose = self._pose(report.joints)
        return None

    def _pose(self, joints: tuple[float, ...]) -> tuple[float, ...]:
        from mirobot_async import kinematics

        return tuple(kinematics.forward(joints[:6], self.dh))

    def _target(self, distance: float) -> tuple[float, ...]:
        target = list(self.start_pose)
        target[self.axis.index] += self.axis.sign * distance
        return tuple(target)

    def _along(self, pose: tuple[float, ...], reference: tuple[float, ...]) -> float:
        i = self.axis.index
        delta = angle_delta(pose[i], reference[i]) if i >= 3 else pose[i] - reference[i]
        return delta * self.axis.sign

    def plan(self, report: StatusReport, period: float) -> float | None:
        axis, sign = self.axis.index, self.axis.sign
        sensitivity = pose_sensitivity(report.joints, axis, sign, self.dh)
        if sensitivity is None:
            return None
        self.speed = speed = cartesian_speed(axis, sensitivity)
        ends = grid_pose(self._target(self.sent), report.joints, self.steps, self.dh)
        queued = 0.0 if ends is None else self._along(ends, self._pose(report.joints))
        ahead = _queued(queued, report)
        brake = brake_seconds(speed.joint_rate)
        step = round(next_step(ahead, float("inf"), speed.rate, brake, period), 3)
        if step <= 0.0:
            return 0.0
        return step if reachable(self._target(self.sent + step), self.dh) else None

    async def send(self, step: float) -> None:
        assert self.speed is not None
        deltas: list[float | None] = [None] * 6
        deltas[self.axis.index] = self.axis.sign * step
        await self.arm.move_pose(
            *deltas, relative=True, linear=True, speed=self.speed.feed, wait=False
        )
        self.sent += step
