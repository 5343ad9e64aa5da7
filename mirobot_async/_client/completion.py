"""Motion completion: where a move should end, and waiting until the robot is there.

:class:`Target` is a motion's goal (``None`` entries are not checked) with the tolerances the
firmware's printed values allow; :class:`MotionCompletion` polls back-to-back until a status
received after the motion's ``ok`` shows it finished (``Idle`` at the target, or ``Idle`` after
the arm was seen moving), failing on an alarm or a reset in between.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from typing import Final

from mirobot_async._client.condition import RobotCondition
from mirobot_async._client.deadline import clip
from mirobot_async._client.poller import StatusPoller
from mirobot_async._core.replies import State, StatusReport
from mirobot_async.errors import MirobotAlarmError, MirobotResetError, MirobotTimeoutError

__all__ = [
    "JOINT_TOLERANCE",
    "ORIENTATION_TOLERANCE",
    "POSITION_TOLERANCE",
    "MotionCompletion",
    "Target",
]

# Completion tolerances for wait=True: the firmware moves in whole motor steps ($100..$106 steps
# per degree, as few as 11.11 on the classic J6: 0.09 deg a step) and prints 3 decimals, so a
# reached target reads back within half a step.
JOINT_TOLERANCE: Final = 0.05  # degrees (joints) and mm (rail)
RELATIVE_JOINT_TOLERANCE: Final = 0.1
"""A relative joint move's target measured from a status: the firmware adds to its parser's
exact position, up to half a motor step from the whole steps a status shows, and the arm then
stops at whole steps again: up to one step (J6: 0.09 degrees) from the status plus the move."""
POSITION_TOLERANCE: Final = 0.1  # mm (pose x, y, z)
ORIENTATION_TOLERANCE: Final = 0.1  # degrees (pose rx, ry, rz)

BUSY: Final = frozenset({State.RUN, State.HOME, State.HOLD, State.DOOR})
# Alarms printed by a reset that interrupts motion or homing; the banner follows.
_RESET_ALARMS: Final = ("abort during cycle", "homing fail")


def _angle_diff(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@dataclass(frozen=True, slots=True)
class Target:
    """Where a motion should end (``None`` entries are not checked)."""

    joints: tuple[float | None, ...] = (None,) * 6
    rail: float | None = None
    pose: tuple[float | None, ...] = (None,) * 6
    joint_tolerance: float = JOINT_TOLERANCE
    """Degrees (mm for the rail): :data:`RELATIVE_JOINT_TOLERANCE` for a relative move whose
    target was measured from a status."""

    def reached(self, report: StatusReport) -> bool:
        """Whether ``report`` shows the arm at this target (within the tolerances)."""
        tolerance = self.joint_tolerance
        for want, have in zip(self.joints, report.joints, strict=True):
            if want is not None and abs(want - have) > tolerance:
                return False
        if (
            self.rail is not None
            and report.rail is not None
            and abs(self.rail - report.rail) > tolerance
        ):
            return False
        for index, (want, have) in enumerate(zip(self.pose, report.pose, strict=True)):
            if want is None:
                continue
            if index < 3:
                if abs(want - have) > POSITION_TOLERANCE:
                    return False
            elif _angle_diff(want, have) > ORIENTATION_TOLERANCE:
                return False
        return True


class MotionCompletion:
    """Waits for motions to finish, from status reports."""

    def __init__(self, poller: StatusPoller, condition: RobotCondition) -> None:
        self._poller = poller
        self._condition = condition
        self.status_timeout = 2.0
        self.depth = 2  # "?" kept in flight while waiting (see StatusPoller.fetch)

    async def wait(
        self,
        command: str,
        target: Target | None,
        *,
        deadline: float | None,
        timeout: float | None,
        epoch: int,
        alarm_epoch: int,
        homing: bool = False,
    ) -> StatusReport:
        """Poll back-to-back until a status received after this call shows the motion done.

        ``epoch``/``alarm_epoch`` are the reset and alarm epochs from before the motion was
        sent: a reset or an alarm since fails the wait (:class:`MirobotResetError`,
        :class:`MirobotAlarmError`). Raises :class:`MirobotTimeoutError` at ``deadline``.
        Cancellation is safe.
        """
        what = f"the robot to finish {command!r} (Idle at the target)"
        seen_busy = False
        condition = self._condition
        poller = self._poller
        loop_time = asyncio.get_running_loop().time
        while True:
            current = loop_time()
            if deadline is not None and current >= deadline:
                raise MirobotTimeoutError(what, timeout, command=command)
            try:
                report, _ = await poller.fetch(
                    fresh=False,
                    timeout=clip(self.status_timeout, deadline, current),
                    depth=self.depth,
                )
            except MirobotTimeoutError as err:
                if deadline is not None and loop_time() >= deadline:
                    raise MirobotTimeoutError(what, timeout, command=command) from err
                raise
            except MirobotAlarmError as err:
                raise MirobotAlarmError(command, condition.alarm or err.text) from err
            if condition.reset_epoch != epoch:
                raise MirobotResetError(command, "the robot reset before the motion finished")
            if condition.alarm_epoch != alarm_epoch or report.state is State.ALARM:
                alarm = condition.alarm or "the robot is in Alarm"
                if alarm.strip().lower() in _RESET_ALARMS:
                    raise MirobotResetError(command, f"the motion was aborted: ALARM: {alarm}")
                raise MirobotAlarmError(command, alarm)
            if report.state in BUSY:
                seen_busy = True
                continue
            if homing:
                if all(abs(j) <= JOINT_TOLERANCE for j in report.joints):
                    return report
                continue
            if target is None or seen_busy or target.reached(report):
                return report
