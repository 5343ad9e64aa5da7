"""Status and realtime commands of :class:`~mirobot_async._client.client.Mirobot` (a mixin):
``status``, ``statuses``, ``wait_idle``, ``axes_locked``, ``hold``, ``resume``, ``reset``,
``hold_on_exit``."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncGenerator, AsyncIterator
from typing import Final

from mirobot_async._client.deadline import check_timeout, deadline_after, within
from mirobot_async._client.parts import MOVE_TIMEOUT, RESET_TIMEOUT, STATUS_TIMEOUT, ClientParts
from mirobot_async._client.scheduler import QUIET, SendRules
from mirobot_async._core.modal import lock_probe
from mirobot_async._core.outgoing import OutgoingLine
from mirobot_async._core.replies import State, StatusReport
from mirobot_async.errors import (
    MirobotAlarmError,
    MirobotError,
    MirobotUsageError,
    MotionRefusedError,
    RefusalReason,
)

_PROBE: Final = SendRules(idle=True, validate=True)
"""The lock probe's lines: at rest, judged as the firmware would."""

STANDING_SECONDS = 0.25
"""A held arm stands once its reports show the same motor steps for this long: braking at the
factory acceleration (``$120..$126`` = 50 deg/s^2) its last motor step takes at most 60 ms (J6,
0.09 degrees a step)."""

__all__ = ["StatusCommands"]


class StatusCommands(ClientParts):
    """Status polling and the realtime bytes ``!``, ``~``, ``%``."""

    async def status(
        self, *, fresh: bool = False, timeout: float | None = STATUS_TIMEOUT
    ) -> StatusReport:
        """Send ``?`` (or join the one in flight) and return the next status report received.

        ``fresh=True`` waits for a report that answers a ``?`` written after this call started
        (so it reflects every byte written before the call, such as a line or a feed hold).
        A corrupted reply is dropped (counted in :attr:`corrupted_status_count`) and asked again;
        an ignored ``?`` is asked again after :attr:`status_retry_interval`, all within
        ``timeout`` seconds (default :data:`STATUS_TIMEOUT`), after which
        :class:`MirobotTimeoutError` ("a status report") is raised. While :meth:`home` (or a
        ``$H`` line) runs, the firmware answers no ``?`` until its switch search ends: a
        ``timeout`` longer than that returns the report it prints then (state ``Home``); a
        shorter one raises ``MirobotTimeoutError`` saying that the arm is homing. Cancellation
        is safe.
        """
        report, _ = await self._poller.fetch(fresh=fresh, timeout=timeout)
        return report

    async def statuses(
        self, interval: float = 0.1, *, timeout: float | None = STATUS_TIMEOUT
    ) -> AsyncGenerator[StatusReport, None]:
        """Yield a status report about every ``interval`` seconds, forever.

        Several consumers may iterate at once: their requests share the outstanding ``?``, and
        polling never disturbs lines in flight. Each report waits at most ``timeout`` seconds
        (:class:`MirobotTimeoutError`), except while this connection homes the arm: the
        firmware answers no ``?`` during the switch search, so the reports pause until it ends
        (at most the homing bound, see :attr:`homing`) and resume with its ``Home`` report.
        Stop by breaking out of the loop (or cancelling the task);
        prefer ``async with contextlib.aclosing(arm.statuses()) as reports:`` to release it at
        once (it is an async generator, so ``aclosing`` type-checks).
        """
        if not interval >= 0:
            raise MirobotUsageError(f"interval={interval!r} must be >= 0")
        check_timeout(timeout)
        loop = self._running_loop()
        next_time = loop.time()
        while True:
            report, _ = await self._poller.fetch(fresh=False, timeout=timeout, through_homing=True)
            yield report
            now = loop.time()
            next_time = max(next_time + interval, now)
            if next_time > now:
                await asyncio.sleep(next_time - now)

    async def wait_idle(self, *, timeout: float | None = MOVE_TIMEOUT) -> StatusReport:
        """Wait until every line sent before this call is answered and the robot is ``Idle``.

        Polls back-to-back, so it returns within milliseconds of the robot becoming idle (a
        report received after the last reply was printed after it; ignored ``?`` cost nothing).
        Raises :class:`MirobotAlarmError` if the robot is (or goes) into Alarm,
        :class:`MirobotTimeoutError` after ``timeout`` seconds (default :data:`MOVE_TIMEOUT`).
        Cancellation is safe.
        """
        deadline = deadline_after(self._running_loop(), timeout)
        # After a hard limit nothing is answered until reset(): fail at once, not after a
        # liveness check (the lost lines' slots stay registered to match late replies).
        self._condition.check_sendable(None, motion=False)
        async with within(deadline, "the robot to be Idle", timeout):
            await self._lines.wait_answered(deadline)
            while True:
                report, _ = await self._poller.fetch(fresh=False, timeout=None)
                if report.state is State.ALARM:
                    raise MirobotAlarmError(None, self._condition.alarm or "the robot is in Alarm")
                if report.state in QUIET:
                    return report

    async def axes_locked(self, *, timeout: float | None = MOVE_TIMEOUT) -> bool:
        """Whether the axes are locked (motion lines are dropped: ``Locked status of each
        axis!``), found without moving the arm. The status does not always show it: classic
        arms power on locked in ``Idle``, and a 2021 arm stays locked after ``$X``.

        ``True`` in ``Alarm`` (every G-code line is refused). Otherwise, once the arm is at rest
        (it waits for queued motion to end; in ``Hold`` until :meth:`resume`), a relative joint
        move of zero length is sent (``M21 G91 X0``: refused when locked, not a motor step
        otherwise), then the line that puts back the coordinate and distance modes (``M20``,
        ``G90``); a mode that was unknown is left known (``M21``, ``G90``, ``G0``, ``G21``:
        :func:`~mirobot_async._core.modal.lock_probe`). Both lines go through validation, the
        mode tracking and the envelope as any line. Raises as :meth:`send`;
        :class:`MirobotTimeoutError` after ``timeout`` seconds (default :data:`MOVE_TIMEOUT`).
        """
        loop = self._running_loop()
        deadline = deadline_after(loop, timeout)
        report = await self.status(timeout=STATUS_TIMEOUT if timeout is None else timeout)
        if report.state is State.ALARM:
            return True
        # at rest first: a mode word written behind moving joints would restart from where
        # they are (Chaining), and validation refuses it
        await self.wait_idle(timeout=None if deadline is None else max(0.0, deadline - loop.time()))
        probe = lock_probe(self._guard.modes)
        what = "axes_locked()"
        locked = False
        try:
            await self._command(
                OutgoingLine.of(probe.line.encode("ascii"), what),
                deadline=deadline, timeout=timeout, rules=_PROBE,
            )  # fmt: skip
        except MotionRefusedError as err:
            if err.reason is not RefusalReason.LOCKED:
                raise
            locked = True
        if probe.restore is not None:
            await self._command(
                OutgoingLine.of(probe.restore.encode("ascii"), what),
                deadline=deadline, timeout=timeout, rules=_PROBE,
            )  # fmt: skip
        return locked

    async def hold(self, *, timeout: float | None = STATUS_TIMEOUT) -> StatusReport:
        """Feed hold (``!``): decelerate to a stop; returns once the arm stands: in ``Hold`` at the
        same motor steps for :data:`STANDING_SECONDS` (``Hold`` is reported from the moment the
        firmware starts braking, and the arm moves on while it brakes, its last steps slowest),
        or in a quiet state.

        ``!`` is a realtime byte: it acts at once, ahead of queued lines. Not sent after a hard
        limit (the arm is already stopped; :meth:`reset` first). Raises
        :class:`MirobotTimeoutError` after ``timeout`` seconds (default :data:`STATUS_TIMEOUT`).
        Cancelling only stops waiting: the hold was already sent.
        """
        deadline = deadline_after(self._running_loop(), timeout)
        self._condition.check_sendable("!", motion=False)
        self._wire.write_realtime(self._wire.conn.feed_hold())
        what = "the robot to stop (Hold)"
        if self._condition.homing is not None:
            what += f"; {self._condition.homing.describe()}, and only reset() stops homing"
        async with within(deadline, what, timeout, command="!"):
            loop = self._running_loop()
            still: tuple[StatusReport, float] | None = None  # first report at these steps
            while True:
                report, _ = await self._poller.fetch(fresh=True, timeout=None)
                if report.state is State.RUN:
                    continue
                if report.state is not State.HOLD:
                    return report  # quiet (Idle, Alarm): nothing was moving
                now = loop.time()
                if still is None or report.joints != still[0].joints:
                    still = (report, now)
                elif now - still[1] >= STANDING_SECONDS:
                    return report

    async def resume(self, *, timeout: float | None = STATUS_TIMEOUT) -> StatusReport:
        """Cycle start (``~``): resume after :meth:`hold`; returns the first status not ``Hold``.

        The firmware drops a ``~`` that arrives while a hold is still braking (oracle: the arm
        stays in ``Hold``), so ``~`` is sent again after each status still in ``Hold``. Raises
        :class:`MirobotTimeoutError` after ``timeout`` seconds (default :data:`STATUS_TIMEOUT`)
        if the arm stays in ``Hold``. Cancelling only stops waiting (and resending).
        """
        deadline = deadline_after(self._running_loop(), timeout)
        self._condition.check_sendable("~", motion=False)
        async with within(deadline, "the robot to leave Hold", timeout, command="~"):
            while True:
                self._wire.write_realtime(self._wire.conn.cycle_start())
                report, _ = await self._poller.fetch(fresh=True, timeout=None)
                if report.state is not State.HOLD:
                    return report

    async def reset(self, *, timeout: float | None = RESET_TIMEOUT) -> tuple[str, ...]:
        """Soft reset (``%``): stop at once, clear the robot's buffers, await its banner.

        Sent immediately, ahead of queued lines (right after a reset-only alarm such as a hard
        limit, once the firmware's stall after it is over: its ``[Reset to continue]``, at most
        1.5 s after the alarm; a ``%`` written during the stall is lost). Pending lines fail with
        :class:`MirobotResetError` (they are not resent), lines of other calls still waiting for
        their turn fail the same way, and no line is written until the banner has ended. Calls
        that overlap before the banner starts share one ``%`` and its banner. Clears the
        hard-limit lock and remembered alarms (an alarm the reset itself causes, such as
        ``Abort during cycle``, stays). The axes are locked again afterwards: :meth:`home` or
        :meth:`unlock`. Returns the banner lines. Raises :class:`MirobotTimeoutError` when no
        banner comes within ``timeout`` seconds (default :data:`RESET_TIMEOUT`). Cancelling only
        stops waiting: the ``%`` was sent, and lines written before its banner arrives fail with
        :class:`MirobotResetError`.
        """
        check_timeout(timeout)
        condition = self._condition
        condition.raise_if_closed()
        loop = self._running_loop()
        asked_at = loop.time()
        fut: asyncio.Future[tuple[str, ...] | BaseException] = loop.create_future()
        condition.add_banner_waiter(asked_at, fut)
        alarm_epoch = condition.alarm_epoch
        condition.resetting += 1
        try:
            deadline = deadline_after(loop, timeout)
            async with within(deadline, "the banner after a reset", timeout, command="%"):
                if not condition.reset_requested:  # else join the "%" whose banner is due
                    condition.reset_requested = True
                    await self._after_alarm_stall(loop)
                    self._wire.write_realtime(self._wire.conn.request_reset())
                result = await fut
        finally:
            condition.resetting -= 1
            if not condition.resetting:
                condition.reset_requested = False  # (a banner that never came: ask anew)
            if not fut.done():
                fut.cancel()
            condition.remove_banner_waiter(asked_at, fut)
            self._wire.notify()
        if isinstance(result, BaseException):
            raise result
        condition.cleared_by_reset(alarm_epoch)
        return result

    async def _after_alarm_stall(self, loop: asyncio.AbstractEventLoop) -> None:
        """Wait until the firmware's stall after a reset-only alarm is over (it prints
        ``[Reset to continue]``; a ``%`` before that is lost), at most until
        :data:`~mirobot_async._client.condition.ALARM_STALL_WAIT` after the alarm arrived."""
        condition = self._condition
        stall = condition.alarm_stall
        if stall is None:
            return
        left = condition.alarm_stall_ends_by - loop.time()
        if left > 0:
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(left):
                    await stall.wait()
        if condition.alarm_stall is stall:
            condition.alarm_stall = None  # no "[Reset to continue]": not waited for again
        condition.raise_if_closed()

    @contextlib.asynccontextmanager
    async def hold_on_exit(self) -> AsyncIterator[None]:
        """``async with arm.hold_on_exit():`` sends a feed hold (``!``) if the block ends by an
        exception or a cancellation, so the arm decelerates to a stop instead of running on.

        The ``!`` is written at once (a realtime byte: ahead of queued lines) and nothing is
        awaited, so it works inside a cancelled task; the exception then propagates. Nothing is
        sent when the block ends normally, when the link is gone, or after a hard limit (the
        arm is already stopped). Resume with :meth:`resume` or clear with :meth:`reset`.
        """
        try:
            yield
        except BaseException:
            self._feed_hold_now()
            raise

    def _feed_hold_now(self) -> bool:
        try:
            self._condition.check_sendable("!", motion=False)
        except MirobotError:
            return False
        self._wire.write_realtime(self._wire.conn.feed_hold())
        return True
