"""Which silences of the robot are expected while lines await their replies, and which mean
that a reply was lost (the liveness rules; ARCHITECTURE.md, "Timeouts and liveness").

A call waiting for a reply checks the robot's liveness after the scheduler's
``liveness_interval`` without progress (:meth:`ReplyWatch.check`): a quiet robot that answered a
``?`` written well after the oldest unanswered line has lost that line's reply, and the line is
given up (:class:`MirobotTimeoutError`); the following replies keep their lines.

Two silences are expected and never taken for a lost reply: a homing line (``$H``...) is
answered when the switch search ends and the firmware answers no ``?`` until then
(:class:`~mirobot_async._client.condition.HomingCycle`: no ``?`` is asked until its bound has
passed), and a ``G4`` dwell is answered after the planner has emptied *and* the dwell has run,
while the robot reports ``Idle`` (its lines keep their slots until the dwells could have ended,
counted from the first quiet report). After a homing line's ``ok`` the arm makes its return move,
and the firmware zeroes the position when it ends: nothing is written until a status shows the arm
at rest (:attr:`ReplyWatch.homing_return`).
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

from mirobot_async._client.condition import HomingCycle, RobotCondition, homing_bound
from mirobot_async._client.deadline import clip
from mirobot_async._client.guard import EnvelopeGuard, NullGuard, Tracked
from mirobot_async._client.poller import StatusPoller
from mirobot_async._client.wire import Wire
from mirobot_async._core.protocol import Event, LineAcknowledged, LineRejected, PendingLine
from mirobot_async._core.replies import State, StatusReport
from mirobot_async.errors import MirobotTimeoutError

if TYPE_CHECKING:
    from mirobot_async._core.line import ParsedLine
    from mirobot_async._core.outgoing import OutgoingLine
    from mirobot_async._safety.envelope import LineCheck

__all__ = ["DWELL_CLOCK_SLACK", "QUIET", "ReplyWatch", "Slot"]

_log = logging.getLogger("mirobot_async.client")

QUIET: Final = frozenset({State.IDLE, State.ALARM, State.CHECK})
DWELL_CLOCK_SLACK: Final = 2.0
"""A dwell is timed by the robot's clock, not the host's: lines pending behind dwells keep their
slots for this many times the dwells (a simulated firmware slips under load, 2x seen with the
oracle on a loaded machine); a reply lost after a dwell is given up that much later."""

Outcome = LineAcknowledged | LineRejected | BaseException


@dataclass(slots=True, eq=False)
class Slot:
    """A line written to the robot and owed a reply; ``fut`` is cancelled if the caller leaves."""

    pending: PendingLine
    line: OutgoingLine  # the line as the caller made it: bytes, one parse, label
    fut: asyncio.Future[Outcome]
    sent_at: float
    tracked: Tracked | None = None  # what the envelope guard assumed when it was written
    dwell: float = 0.0  # seconds of G4 dwell the line holds the robot (after the planner empties)
    reply_epoch: int = -1  # the reset epoch when its reply came (a line may run after a reset)
    # Called synchronously when the reply (or failure) is settled, before anything else runs.
    watch: Callable[[Slot], None] | None = None

    @property
    def command(self) -> str:
        """The line's text, as errors quote it."""
        return self.line.command

    @property
    def parsed(self) -> ParsedLine:
        """The line's one parse."""
        return self.line.parsed

    @property
    def check(self) -> LineCheck | None:
        """The envelope's verdict on the line (its target), if it was checked."""
        return None if self.tracked is None else self.tracked.check

    def settle(self, outcome: Outcome) -> None:
        """Give the slot its outcome and tell its watcher at once (no loop iteration between)."""
        self.fut.set_result(outcome)
        if self.watch is not None:
            self.watch(self)


class ReplyWatch:
    """The liveness of the lines of one connection: homing, dwells, lost replies."""

    def __init__(
        self,
        wire: Wire,
        condition: RobotCondition,
        poller: StatusPoller,
        guard: EnvelopeGuard | NullGuard,
        slots: dict[int, Slot],
        take: Callable[[int], Slot | None],
    ) -> None:
        self._wire = wire
        self._condition = condition
        self._poller = poller
        self._guard = guard
        self._slots = slots  # the scheduler's (shared)
        self._take = take  # the scheduler's: a line off the books (and off the barrier)
        self._dwell_until = -math.inf
        # When a status first showed the robot quiet after the newest line was written (None:
        # not seen, or seen busy since): pending dwells run from no earlier than that.
        self._quiet_anchor: float | None = None
        self._last_write = -math.inf
        self._homing_line: int | None = None  # id of the homing line in flight
        self.homing_return = False
        """A homing line was answered ``ok``: its return move runs, and the firmware zeroes the
        position when it ends, so nothing is written until a status shows the arm at rest."""
        self.reply_grace = 0.5
        # The event router's dispatch, for the events of settling the lines in doubt.
        self.dispatch: Callable[[Event], None] | None = None

    def _now(self) -> float:
        return asyncio.get_running_loop().time()

    # ---- what the scheduler tells ----

    def written(self, slot: Slot, now: float) -> None:
        """``slot``'s line was written at ``now``: a homing line starts the silent search, a
        ``G4`` holds the robot for its dwell (both read from the line's one parse)."""
        self._last_write = now
        parsed = slot.parsed
        kind = parsed.homing_kind
        if kind is not None:
            condition = self._condition
            bound = homing_bound(kind, condition.homing_rates, condition.homing_bounds)
            condition.homing = HomingCycle(slot.command, now, bound)
            self._homing_line = slot.pending.id
            _log.info(
                "%r sent: the robot answers nothing until homing ends (<= %g s)",
                slot.command,
                bound,
            )
        dwell = parsed.dwell_seconds
        if dwell is not None and dwell > 0:
            slot.dwell = dwell
            self._dwell_until = max(self._dwell_until, now) + dwell

    def replied(self, line_id: int, *, acknowledged: bool) -> None:
        """The line ``line_id`` got its final reply (``ok`` when ``acknowledged``)."""
        if self._homing_line == line_id and acknowledged:
            self.homing_return = True

    def taken(self, line_id: int) -> None:
        """The line ``line_id`` is off the books (answered, given up, not run)."""
        if self._homing_line == line_id:
            self.end_homing()

    def on_reset(self) -> None:
        """A banner started: dwells and homing (search and return move) ended with it."""
        self._dwell_until = -math.inf
        self.end_homing()  # a reset stops the homing search
        self.homing_return = False

    def end_homing(self) -> None:
        """The homing line was answered (or a reset ended it): the robot answers ``?`` again;
        the ``?`` written during the search were merged into the one report it printed then."""
        if self._homing_line is None and self._condition.homing is None:
            return
        self._homing_line = None
        self._condition.homing = None
        self._poller.on_homing_end()

    def on_status(self, report: StatusReport) -> None:
        """A report arrived: printed after the homing ``ok``, a quiet one ends the return move
        (whoever asked for it: ``home()``'s own wait, a monitor)."""
        if self.homing_return and report.state in QUIET and not self._wire.conn.in_banner:
            self.homing_return = False

    async def await_homing_return(self, deadline: float | None, status_timeout: float) -> None:
        """One status (received after the homing line's ``ok``); the return move has ended if
        it shows the robot quiet."""
        report, _ = await self._poller.fetch(
            fresh=False,
            timeout=clip(status_timeout, deadline, self._now()),
            what="a status report (the arm's return move after homing)",
        )
        if report.state in QUIET and not self._wire.conn.in_banner:
            self.homing_return = False

    async def check(self, deadline: float | None, status_timeout: float) -> None:
        """Ask for a status; if the robot is quiet, give up on lines whose reply was lost.

        While a homing line may still be searching (:meth:`RobotCondition.homing_silent`)
        nothing is asked: the firmware answers no ``?`` then, and a closed port fails the call
        anyway. Past the homing bound a status reply that does not come names homing."""
        now = self._now()
        if deadline is not None and deadline <= now:
            return  # the caller's own deadline decides
        if self._condition.homing_silent(now) is not None:
            return
        what = "a status reply (checking that the robot is alive while waiting for a reply)"
        homing = self._condition.homing
        if homing is not None:
            what = (
                f"a status reply: no reply to {homing.command!r} after "
                f"{now - homing.started:.1f} s, longer than homing can take ({homing.bound:g} s; "
                "the firmware answers no '?' while homing, so the link or the robot is dead)"
            )
        report, asked_at = await self._poller.fetch(
            fresh=True, timeout=clip(status_timeout, deadline, now), what=what
        )
        if report.state in QUIET:
            self._expire_lost_replies(asked_at, report.state)
        else:
            self._quiet_anchor = None  # busy: a dwell queued behind motion has not started

    def _pending_dwell_end(self, asked_at: float) -> float:
        """The latest the dwells of the pending lines can end, judged from a quiet report
        answering a ``?`` written at ``asked_at`` (the firmware runs a ``G4`` only once its
        planner is empty, and reports ``Idle`` during it: oracle, 1.8 s of ``Idle`` before the
        ``ok`` of a ``G4 P2`` sent behind a 1.5 s move)."""
        dwells = [slot.dwell for slot in self._slots.values() if slot.dwell > 0]
        if not dwells:
            return -math.inf
        if self._quiet_anchor is None or self._quiet_anchor < self._last_write:
            self._quiet_anchor = max(asked_at, self._last_write, self._now())
        return self._quiet_anchor + DWELL_CLOCK_SLACK * math.fsum(dwells)

    def _expire_lost_replies(self, asked_at: float, state: State) -> None:
        conn = self._wire.conn
        if conn.in_banner:
            return
        if conn.in_doubt_count and asked_at >= self._condition.banner_started + self.reply_grace:
            # A quiet robot answered a "?" written well after the banner: every reply to a
            # line that ran after the reset has come; the others were lost with its buffer.
            conn.resolve_doubt()
            dispatch = self.dispatch
            assert dispatch is not None
            for event in conn.events():
                dispatch(event)
        self._dwell_until = max(self._dwell_until, self._pending_dwell_end(asked_at))
        if asked_at < self._dwell_until + self.reply_grace:
            return
        expired = False
        while conn.pending_count:
            oldest = conn.pending_lines[0]
            slot = self._slots.get(oldest.id)
            if slot is not None and asked_at - slot.sent_at < self.reply_grace:
                break
            conn.expire_oldest()
            self._take(oldest.id)
            self._wire.stats.replies_lost += 1
            expired = True
            self._guard.forget("lost")  # did it run? Unknown: forget position and modes
            command = oldest.line.decode("ascii", "replace")
            _log.warning(
                "no reply to %r although the robot is %s and answered a later status request: "
                "giving up on it",
                command,
                state.value,
            )
            if slot is not None and not slot.fut.done():
                elapsed = self._now() - slot.sent_at
                slot.settle(
                    MirobotTimeoutError(
                        f"the reply to {command!r} (lost: the robot is {state.value} and answered "
                        "a later status request)",
                        round(elapsed, 3),
                        command=command,
                    )
                )
        if expired:
            self._wire.notify()
