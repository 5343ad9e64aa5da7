"""The line scheduler: when a line may be written, and what its reply means.

Lines are written in call order (one FIFO lock) and only when they fit in the robot's 127-byte
receive buffer (GRBL character counting). ``$`` lines are written only when nothing else is in
flight, and nothing follows them until they are answered (the ``$`` barrier). Each written line
gets a :class:`Slot` whose future gets its reply. A call waiting for a reply checks the robot's
liveness after :attr:`LineScheduler.liveness_interval` without progress
(:class:`~mirobot_async._client.liveness.ReplyWatch`: lost replies, homing, dwells).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

from mirobot_async._client.condition import RobotCondition
from mirobot_async._client.deadline import clip, within
from mirobot_async._client.guard import EnvelopeGuard, NeedPosition, NullGuard
from mirobot_async._client.liveness import QUIET, ReplyWatch, Slot
from mirobot_async._client.observers import LineObservers
from mirobot_async._client.poller import StatusPoller
from mirobot_async._client.wire import Wire
from mirobot_async._core.line import ParsedLine
from mirobot_async._core.outgoing import OutgoingLine
from mirobot_async._core.protocol import (
    DoubtResolved,
    Event,
    LineAcknowledged,
    LineOutcomeUnknown,
    LineRejected,
    ResetDetected,
)
from mirobot_async._core.replies import StatusReport
from mirobot_async._core.validation import (
    InvalidLineError,
    ModalState,
    line_problems,
    may_differ_by_profile,
    validate_line,
)
from mirobot_async.errors import (
    MirobotAlarmError,
    MirobotCommandError,
    MirobotError,
    MirobotOutcomeUnknownError,
    MirobotResetError,
    MirobotTimeoutError,
    MotionRefusedError,
)

if TYPE_CHECKING:
    from mirobot_async._safety.envelope import LineCheck

__all__ = ["PLAIN", "QUIET", "LineScheduler", "SendRules", "Slot", "StreamStopped"]

_log = logging.getLogger("mirobot_async.client")

_PROFILES: Final = ("2021", "classic")

Outcome = LineAcknowledged | LineRejected | BaseException


@dataclass(frozen=True, slots=True)
class SendRules:
    """How a call sends its line: what may refuse it, what is checked before it is written."""

    motion: bool = False
    """A motion call: refused while an alarm is remembered (not only a reset-only one)."""
    check_envelope: bool = True
    """Check the line against the safety envelope (``False``: sent unchecked, with a WARNING)."""
    warn_unchecked: bool = True
    """Log an unchecked line at WARNING (``False``: DEBUG, the caller warned once already)."""
    idle: bool = False
    """Write it only with nothing in flight and the arm at rest (``$$``)."""
    validate: bool = False
    """Refuse what the firmware would refuse or misread (``validate_line``)."""


PLAIN: Final = SendRules()
"""A one-line call's rules: not a motion, envelope checked, not validated."""


class StreamStopped(Exception):
    """Raised by :meth:`LineScheduler.submit` when a stream's ``should_stop`` says so."""


def _disagree(parsed: ParsedLine, guard: EnvelopeGuard | NullGuard) -> bool:
    """Only one of the two firmware profiles would refuse the line (then learn the profile).
    Judged twice only for a line whose verdict may depend on the profile."""
    if not may_differ_by_profile(parsed, guard.modal_state()):
        return False
    verdicts = {
        bool(line_problems(parsed, firmware=profile, state=guard.modal_state()))
        for profile in _PROFILES
    }
    return len(verdicts) > 1


def _judged(judged_from: ModalState | None, guard: EnvelopeGuard | NullGuard) -> bool:
    """The line was found free of problems from the modal state the guard now predicts (a
    stream's line, judged before the stream began): judging it again would say the same.
    Assumes a line's verdict is a pure function of the line, the profile and the modal state."""
    return judged_from is not None and judged_from == guard.modal_state()


def _validate(parsed: ParsedLine, firmware: str | None, guard: EnvelopeGuard | NullGuard) -> None:
    """:func:`validate_line` with the profile (unknown: a line both profiles refuse) and the
    modal state the guard follows."""
    if firmware is not None:
        validate_line(parsed, firmware=firmware, state=guard.modal_state())
        return
    try:
        validate_line(parsed, firmware="2021", state=guard.modal_state())
    except InvalidLineError:
        validate_line(parsed, firmware="classic", state=guard.modal_state())


def outcome_output(slot: Slot) -> tuple[str, ...]:
    """The output of a settled slot, or the error its outcome means."""
    result = slot.fut.result()
    if isinstance(result, BaseException):
        raise result
    if isinstance(result, LineRejected):
        if "alarm lock" in result.text.lower():
            raise MirobotAlarmError(slot.command, result.text, result.code, output=result.output)
        raise MirobotCommandError(slot.command, result.text, result.code, output=result.output)
    refusal = result.refusal
    if refusal is not None:
        raise MotionRefusedError(
            slot.command, refusal.text, refusal.reason, axis=refusal.axis, output=result.output
        )
    return result.output


def outcome_unknown(command: str, reply: LineAcknowledged | LineRejected) -> BaseException:
    """The error of a line a reset may have cut, quoting what the robot answered after it."""
    if isinstance(reply, LineRejected):
        return MirobotOutcomeUnknownError(command, reply.text)
    return MirobotOutcomeUnknownError(command, " / ".join((*reply.output, "ok")))


class LineScheduler:
    """Slots, pacing and liveness of the lines of one connection."""

    def __init__(
        self,
        wire: Wire,
        condition: RobotCondition,
        poller: StatusPoller,
        guard: EnvelopeGuard | NullGuard,
        require_firmware: Callable[[float | None, float | None], Awaitable[object]],
    ) -> None:
        self._wire = wire
        self._condition = condition
        self._poller = poller
        self._guard = guard
        self.require_firmware = require_firmware
        """``await require_firmware(deadline, timeout)``: learn the arm's firmware profile."""
        self._loop: asyncio.AbstractEventLoop | None = None
        self.slots: dict[int, Slot] = {}
        self._send_lock = asyncio.Lock()
        self._barrier: int | None = None  # id of an in-flight "$" line (send-response)
        self.liveness_interval = 1.0
        self.status_timeout = 2.0
        self.watch = ReplyWatch(wire, condition, poller, guard, self.slots, self._take)
        self.observers = LineObservers()
        """Who watches the lines (``Mirobot.view()``): told each line written, answered or
        refused before it was written."""

    @property
    def reply_grace(self) -> float:
        """A line unanswered although a quiet robot answered a ``?`` sent this long after it
        is lost (see :class:`~mirobot_async._client.liveness.ReplyWatch`)."""
        return self.watch.reply_grace

    @reply_grace.setter
    def reply_grace(self, value: float) -> None:
        self.watch.reply_grace = value

    @property
    def dispatch(self) -> Callable[[Event], None] | None:
        """The event router's dispatch, for the events of settling the lines in doubt."""
        return self.watch.dispatch

    @dispatch.setter
    def dispatch(self, value: Callable[[Event], None] | None) -> None:
        self.watch.dispatch = value

    def start(self, loop: asyncio.AbstractEventLoop) -> None:
        """Use ``loop`` (the connection's)."""
        self._loop = loop

    @property
    def rx_buffer_size(self) -> int:
        """The robot's receive buffer in bytes (the longest line with its line end)."""
        return self._wire.rx_buffer_size

    def _now(self) -> float:
        assert self._loop is not None
        return self._loop.time()

    # ---- replies and failures (called by the event router) ----

    def on_reply(self, event: LineAcknowledged | LineRejected) -> None:
        """A final reply for the oldest pending line."""
        stats = self._wire.stats
        if isinstance(event, LineAcknowledged):
            stats.lines_acknowledged += 1
            stats.lines_refused += event.refusal is not None
        else:
            stats.lines_rejected += 1
        self.watch.replied(event.line.id, acknowledged=isinstance(event, LineAcknowledged))
        slot = self._take(event.line.id)
        if slot is None:
            self._guard.line_answered(None, None, event)
            return
        if self.observers:
            self.observers.answered(slot.line, event)
        self._poller.on_line_reply(slot.sent_at)
        self._condition.on_line_answered(slot.parsed, event)
        self._guard.line_answered(slot.parsed, slot.tracked, event)
        if slot.fut.done():
            stats.replies_discarded += 1
            _log.debug("discarding the reply to %r (its caller left)", slot.command)
        else:
            slot.settle(event)

    def on_reset(self, event: ResetDetected) -> None:
        """A banner started: ``event.failed`` lines were not run; ``event.in_doubt`` lines keep
        their slots until their fate is known (:meth:`on_doubt_resolved`, or their replies)."""
        failed = event.failed
        self._barrier = None
        self.watch.on_reset()
        for pending in event.in_doubt:
            slot = self.slots.get(pending.id)
            if slot is not None:
                slot.tracked = None  # the prediction it was written under is void
        if event.in_doubt:
            _log.info("the robot reset: %d line(s) may run after it", len(event.in_doubt))
        if failed:  # loudly only if some line has nobody left to tell (else each caller hears)
            unseen = any((slot := self.slots.get(p.id)) is None or slot.fut.done() for p in failed)
            (_log.warning if unseen else _log.info)(
                "the robot reset: %d line(s) not run", len(failed)
            )
        for pending in failed:
            if (slot := self.slots.pop(pending.id, None)) and not slot.fut.done():
                slot.settle(MirobotResetError(slot.command))

    def on_banner(self) -> None:
        """A banner ended: lines may be written again (once no line is in doubt)."""

    def on_outcome_unknown(self, event: LineOutcomeUnknown) -> None:
        """The first line answered after a reset may have been cut by it: its caller gets
        :class:`MirobotOutcomeUnknownError` with the robot's reply, never the reply as its own."""
        slot = self._take(event.line.id)
        if slot is not None and not slot.fut.done():
            _log.warning("a reset cut %r on its way: did it run? unknown", slot.command)
            slot.settle(outcome_unknown(slot.command, event.reply))

    def _take(self, line_id: int) -> Slot | None:
        """The slot of a line the robot answered, off the books (and off the barrier)."""
        slot = self.slots.pop(line_id, None)
        if self._barrier == line_id:
            self._barrier = None
        self.watch.taken(line_id)
        if slot is not None:
            slot.reply_epoch = self._condition.reset_epoch
        return slot

    def on_doubt_resolved(self, event: DoubtResolved) -> None:
        """Lines in doubt after a reset that did not run: they fail with MirobotResetError."""
        for pending in event.not_run:
            slot = self._take(pending.id)
            if slot is not None and not slot.fut.done():
                slot.settle(MirobotResetError(slot.command, "it was lost with the robot's buffer"))

    def fail_waiting(self, error: Callable[[Slot], BaseException], *, forget: bool) -> bool:
        """Every slot still awaited fails with ``error(slot)``; True if one was awaited. With
        ``forget`` the slots are dropped (a dead link), else kept to match late replies."""
        told = False
        for slot in self.slots.values():
            if not slot.fut.done():
                told = True
                slot.settle(error(slot))
        if forget:
            self.slots.clear()
        return told

    @property
    def awaited(self) -> bool:
        """True while some caller awaits a reply."""
        return any(not slot.fut.done() for slot in self.slots.values())

    # ---- writing ----

    def _ready(self, exclusive: bool, nbytes: int) -> bool:
        conn = self._wire.conn
        if self._condition.resetting or conn.in_banner or conn.in_doubt_count:
            return False
        if self._barrier is not None:
            if self._barrier in self.slots:
                return False
            self._barrier = None
        if exclusive:
            return conn.pending_count == 0
        return conn.fits(nbytes)

    async def submit(
        self,
        line: OutgoingLine,
        *,
        deadline: float | None,
        timeout: float | None,
        rules: SendRules = PLAIN,
        should_stop: Callable[[], bool] | None = None,
        watch: Callable[[Slot], None] | None = None,
        judged_from: ModalState | None = None,
    ) -> Slot:
        """Wait for ``line``'s turn and for room in the receive buffer, then write it; its slot
        keeps ``line`` (the guard, the validation, the ``$`` barrier, the homing search and the
        dwell all read its one parse).

        With ``rules.validate`` the line is judged by ``validate_line`` (modal state as the
        guard predicts it) right before it would be written: a problem raises
        ``InvalidLineError`` and nothing is written. A line already found free of problems from
        ``judged_from`` (a stream judged whole before it began) is not judged again when the
        guard predicts that same state.

        ``should_stop`` (a stream's) is asked right before the write, with no await in between:
        if true, :class:`StreamStopped` is raised and nothing is written. ``watch`` is set on the
        slot as the line is written (see :attr:`Slot.watch`).

        The envelope guard checks the line under the send lock (``rules.check_envelope``),
        against the position and modes predicted from every line written before it, again if
        they were invalidated while it waited; a violation raises MirobotUsageError and nothing
        of the line is written.

        With ``rules.idle`` the line is written only when nothing is in flight and a status
        received since shows the robot at rest (the firmware refuses ``$$`` with ``Not idle``
        while the arm moves); nothing else is written in between (the send lock is held).

        After a homing line's ``ok`` nothing is written until a status received since shows the
        arm at rest: the firmware zeroes the position when the return move ends, and a line
        queued behind that move is lost (oracle: a ``G0 X10`` sent right after the ``ok`` of
        ``$H`` ends at 0).
        """
        try:
            return await self._submit(
                line, deadline, timeout, rules, should_stop, watch, judged_from
            )
        except MirobotError as err:  # nothing of the line was written
            if self.observers:
                self.observers.not_sent(line.command, err)
            raise

    async def _submit(
        self,
        line: OutgoingLine,
        deadline: float | None,
        timeout: float | None,
        rules: SendRules,
        should_stop: Callable[[], bool] | None,
        watch: Callable[[Slot], None] | None,
        judged_from: ModalState | None,
    ) -> Slot:
        command, parsed, what = line.command, line.parsed, line.what
        motion, validate = rules.motion, rules.validate
        condition, guard = self._condition, self._guard
        condition.check_sendable(command, motion=motion)
        unknown = condition.firmware is None
        if guard.needs_firmware(parsed) or (
            validate and unknown and not _judged(judged_from, guard) and _disagree(parsed, guard)
        ):
            await self.require_firmware(deadline, timeout)
        exclusive = parsed.kind == "dollar"
        nbytes = len(line.data) + 1
        epoch = condition.reset_epoch
        verdict: LineCheck | None = None
        checked_epoch: int | None = None
        room = f"room in the robot's receive buffer to send {command!r}"
        checking = rules.check_envelope and guard.envelope is not None
        at_rest = False
        async with within(deadline, room, timeout, command=command) as limit, self._send_lock:
            while True:
                condition.check_sendable(command, motion=motion)
                if condition.reset_epoch != epoch:
                    raise MirobotResetError(
                        command, "the robot reset while it waited to be sent; not sent"
                    )
                if should_stop is not None and should_stop():
                    raise StreamStopped
                if validate and not _judged(judged_from, guard):
                    _validate(parsed, condition.firmware, guard)
                if checking and checked_epoch != guard.epoch:
                    position_epoch = guard.epoch
                    found = guard.verdict(parsed, what)
                    if isinstance(found, NeedPosition):
                        limit.what = (
                            f"the arm to come to rest (its position, for the safety envelope) "
                            f"before sending {command!r}"
                        )
                        await self._learn_position(command, deadline)
                        limit.what = room
                        continue  # re-check everything after the awaits
                    verdict = found
                    checked_epoch = position_epoch
                    continue
                if self.watch.homing_return:
                    limit.what = f"the arm to finish homing (its return move) before {command!r}"
                    await self.watch.await_homing_return(deadline, self.status_timeout)
                    limit.what = room
                    continue
                if self._ready(exclusive, nbytes):
                    if rules.idle and not at_rest:
                        limit.what = f"the robot to be at rest before sending {command!r}"
                        report, _ = await self._poller.fetch(
                            fresh=False, timeout=clip(self.status_timeout, deadline, self._now())
                        )
                        at_rest = report.state in QUIET and not self._wire.conn.pending_count
                        limit.what = room
                        continue
                    if should_stop is not None and should_stop():
                        raise StreamStopped  # a reply received meanwhile stopped it
                    slot = self._write(line, exclusive)
                    slot.watch = watch  # no reply can come before this
                    slot.tracked = guard.track_written(
                        slot.pending.id,
                        command,
                        parsed,
                        verdict,
                        checked=rules.check_envelope,
                        what=what,
                        warn_unchecked=rules.warn_unchecked,
                    )
                    return slot
                await self.wait_progress(deadline)

    def _write(self, line: OutgoingLine, exclusive: bool) -> Slot:
        """Register ``line`` with the state machine and write it (synchronous: no gap)."""
        assert self._loop is not None
        pending = self._wire.write_line(line.data)
        now = self._loop.time()
        slot = Slot(pending, line, self._loop.create_future(), now)
        self.slots[pending.id] = slot
        if exclusive:
            self._barrier = pending.id
        self.watch.written(slot, now)
        if self.observers:  # before the guard follows it: the modes it is parsed with
            self.observers.written(line, self._guard.modes, self._guard.base_offset)
        return slot

    async def learn_position(self, command: str, deadline: float | None) -> None:
        """Wait until nothing is in flight and a status shows the arm at rest; the guard adopts
        it as the predicted position (for checks of lines not written yet). Raises
        :class:`MirobotTimeoutError` at ``deadline``; cancellation is safe."""
        async with self._send_lock:
            await self._learn_position(command, deadline)

    async def _learn_position(self, command: str, deadline: float | None) -> None:
        """Wait until nothing is in flight and a status shows the arm at rest; adopt it."""
        conn = self._wire.conn
        while True:
            while conn.pending_count:
                await self.wait_progress(deadline)
                self._condition.check_sendable(command, motion=False)
            report, _ = await self._poller.fetch(
                fresh=False,
                timeout=clip(self.status_timeout, deadline, self._now()),
                what=f"a status report (the arm's position for the safety envelope, {command!r})",
            )
            if conn.pending_count or conn.in_banner or report.state not in QUIET:
                continue  # still moving (or a banner): poll again
            self._guard.adopt_status(report)
            return

    # ---- waiting ----

    async def wait_progress(self, deadline: float | None) -> None:
        """Wait for any progress; after :attr:`liveness_interval` without any, check liveness."""
        if not await self._wire.wait_progress(self.liveness_interval):
            await self.check_liveness(deadline)

    async def check_liveness(self, deadline: float | None) -> None:
        """:meth:`ReplyWatch.check` with this scheduler's status timeout."""
        await self.watch.check(deadline, self.status_timeout)

    async def await_slot(
        self, slot: Slot, deadline: float | None, timeout: float | None
    ) -> tuple[str, ...]:
        """Wait for the reply of ``slot`` (liveness-checked); return its output or raise what
        it means. Cancellation leaves the slot: its reply is consumed and discarded."""
        fut = slot.fut
        try:
            while not fut.done():
                now = self._now()
                if deadline is not None and now >= deadline:
                    raise MirobotTimeoutError(
                        f"the reply to {slot.command!r}", timeout, command=slot.command
                    )
                wait = self.liveness_interval
                if deadline is not None:
                    wait = min(wait, deadline - now)
                await asyncio.wait((fut,), timeout=wait)
                if fut.done() or (deadline is not None and self._now() >= deadline):
                    continue
                try:
                    await self.check_liveness(deadline)
                except MirobotTimeoutError:
                    if fut.done() or (deadline is not None and self._now() >= deadline):
                        continue
                    raise
        finally:
            if not fut.done():
                fut.cancel()  # the caller left: the reply will be consumed and discarded
        return outcome_output(slot)

    async def wait_answered(self, deadline: float | None) -> None:
        """Wait until every line written before this call is answered (or given up)."""
        waiting_for = set(self.slots)
        while waiting_for & self.slots.keys():
            await self.wait_progress(deadline)
            self._condition.check_sendable(None, motion=False)

    async def baseline(self, deadline: float | None) -> StatusReport | None:
        """A status to compute a relative target from, if the arm is at rest with nothing in
        flight (``None`` otherwise)."""
        conn = self._wire.conn
        if conn.pending_count:
            return None
        report, _ = await self._poller.fetch(
            fresh=False, timeout=clip(self.status_timeout, deadline, self._now())
        )
        if report.state not in QUIET or conn.pending_count:
            return None
        return report
