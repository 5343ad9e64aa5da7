"""Hold to jog: a joint moves while its button is held and stops soon after it is let go.

The page (viser's hold buttons) sends a keep-alive every :data:`KEEPALIVE_HZ`\\ th of a second
while a button is pressed and a click when it is released. The jog never gives the arm more
than a few hundredths of a second of motion ahead: it sends short absolute joint moves of
:data:`SEGMENT` seconds each at :data:`SPEED` (deg/min), a new one only while less than
:data:`LEAD` seconds of motion is queued ahead of the arm (read from a fresh status each
time), clamped to the joint's range; the client checks each against the envelope, and a
refused one ends the jog at the edge. The arm's own planner always plans to stand still at the
end of what it was given, so

- on release no new move is sent and the arm stops at the end of the queued motion: at most
  ``LEAD + SEGMENT`` seconds of it, plus its braking (``SPEED / (2 a)``: at the default joint
  acceleration of 50 deg/s^2, $120.., 20 ms at 2 deg/s), under 100 ms;
- when the page goes away (closed, its link lost) the keep-alives stop: after
  :data:`WATCHDOG` seconds without one the jog ends the same way (viser's disconnect ends it
  at once); when the link to the arm goes, nothing more is sent and it stops by itself.

:data:`SPEED` is chosen for the 100 ms: braking alone takes ``v / a`` (at 25 deg/s, the step
jogs' default, half a second).
"""

from __future__ import annotations

import asyncio
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Final

from mirobot_async._core.replies import State, StatusReport
from mirobot_async._core.values import JOINT_NAMES, JOINT_RANGES

if TYPE_CHECKING:
    from mirobot_async._client.client import Mirobot

__all__ = ["KEEPALIVE_HZ", "LEAD", "SEGMENT", "SPEED", "WATCHDOG", "HoldJog"]

SPEED: Final = 120.0
"""Joint speed of a held jog, deg/min (2 deg/s: see the module)."""
SEGMENT: Final = 0.02
"""Seconds of motion each move of a held jog adds."""
LEAD: Final = 0.03
"""A new move is sent while less than this many seconds of motion are queued ahead."""
KEEPALIVE_HZ: Final = 4.0
"""Keep-alives per second the page sends while a jog button is held. Few: the page sends its
GUI messages through one sender throttled to one per 50 ms, so a release right after a
keep-alive waits for it (at 20 Hz nearly every release did)."""
WATCHDOG: Final = 0.75
"""Seconds without a keep-alive after which a held jog ends (the page or its link is gone)."""
_TICK: Final = 0.005
"""Seconds between the fresh statuses a held jog reads."""


class HoldJog:
    """The held jog's state (touched on the client's loop only) and its motion."""

    def __init__(self, arm: Mirobot, say: Callable[[str], None]) -> None:
        self.arm = arm
        self.say = say
        self.loop = asyncio.get_running_loop()
        self.pressed: tuple[int, int] | None = None
        """(joint 1..6, sign) held now, ``None`` once released."""
        self.active = False
        """A jog is queued or running (a keep-alive then only keeps it going)."""
        self.keepalive = 0.0
        self.released_at: float | None = None
        """``time.time()`` when the release (or the watchdog) ended the last jog."""
        self.ended_by = "release"
        """What ended the last jog: ``release`` (the page's click, or viser saw the page go)
        or ``watchdog`` (no keep-alive for :data:`WATCHDOG` s)."""
        self.latencies: list[float] = []
        """Seconds from each release to the first status showing the arm stopped."""

    # called in viser's threads ---------------------------------------------------------
    def press(self, joint: int, sign: int) -> bool:
        """A keep-alive of ``joint``/``sign``; ``True`` when it starts a jog (the caller then
        queues :meth:`run`)."""
        started = asyncio.run_coroutine_threadsafe(self._press(joint, sign), self.loop)
        return started.result(timeout=5)

    def release(self, why: str = "release") -> None:
        """The button was let go (``why``: or the page went away)."""
        now = time.time()
        self.loop.call_soon_threadsafe(self._release, now, why)

    # on the loop -----------------------------------------------------------------------
    async def _press(self, joint: int, sign: int) -> bool:
        self.keepalive = self.loop.time()
        if self.active:
            return False
        self.pressed = (joint, sign)
        self.released_at = None
        self.active = True
        return True

    def refused(self) -> None:
        """The jog :meth:`press` started was refused (not queued)."""
        self.active = False
        self.pressed = None

    def _release(self, when: float, why: str) -> None:
        if self.pressed is not None:
            self.pressed = None
            self.released_at = when
            self.ended_by = why

    def _held(self, joint: int, sign: int) -> bool:
        if self.pressed != (joint, sign):
            return False
        if self.loop.time() - self.keepalive > WATCHDOG:
            self.pressed = None
            self.released_at = time.time()
            self.ended_by = "watchdog"
            self.say(f"**J{joint} {'+' if sign > 0 else '-'}: no keep-alive from the page**")
            return False
        return True

    async def run(self, joint: int, sign: int) -> str:
        """Jog ``joint`` toward ``sign`` while it is held; returns once the arm stands."""
        name = f"{JOINT_NAMES[joint - 1]} {'+' if sign > 0 else '-'} (hold)"
        low, high = JOINT_RANGES[JOINT_NAMES[joint - 1]]
        edge = high if sign > 0 else low
        rate = SPEED / 60.0  # deg/s
        why = "released"
        try:
            report = await self.arm.status(fresh=True)
            target = report.joints[joint - 1]
            while self._held(joint, sign):
                ahead = (target - report.joints[joint - 1]) * sign
                if ahead < rate * LEAD and (edge - target) * sign > 1e-6:
                    step = target + sign * rate * SEGMENT
                    target = min(step, edge) if sign > 0 else max(step, edge)
                    moves: list[float | None] = [None] * 6
                    moves[joint - 1] = target
                    await self.arm.move_joints(*moves, speed=SPEED, wait=False)
                elif (edge - target) * sign <= 1e-6 and ahead <= 0.0:
                    why = "at the end of the joint's range"
                    break
                await asyncio.sleep(_TICK)
                report = await self.arm.status(fresh=True)
        finally:
            self.active = False
            if self.pressed == (joint, sign):  # ended by a refusal or an error: not held on
                self.pressed = None
                self.released_at = None
        stopped = await self._stopped(report)
        if self.released_at is None:
            return f"{name}: stopped ({why}) at {stopped.joints[joint - 1]:.2f}"
        latency = time.time() - self.released_at
        self.latencies.append(latency)
        print(
            f"mirobot: view: hold jog {name}: stopped {latency * 1000:.0f} ms after the "
            f"{self.ended_by} (at {self.released_at:.3f}, "
            f"stopped at {self.released_at + latency:.3f})",
            file=sys.stderr,
            flush=True,
        )
        return (
            f"{name}: stopped at {stopped.joints[joint - 1]:.2f}, "
            f"{latency * 1000:.0f} ms after the {self.ended_by}"
        )

    async def _stopped(self, report: StatusReport) -> StatusReport:
        """The first status showing the arm stopped (not ``Run``: ``Idle`` once its queue ran
        out)."""
        while report.state is State.RUN:
            report = await self.arm.status(fresh=True)
        return report
