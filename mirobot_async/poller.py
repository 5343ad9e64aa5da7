"""Status polling: shared ``?`` requests, retries, and which request a report answers.

Every caller that wants a status (``status()``, ``statuses()``, ``wait=True`` moves, liveness
checks) waits on :meth:`StatusPoller.fetch`; their waits share the ``?`` in flight.

Which report is fresh enough
----------------------------
A caller either wants the next report *received* after it started (``fresh=False``: enough for
"what is the state now" and for everything that follows a received reply, because the robot's
output is in order: a report received after an ``ok`` was printed after it), or a report that
answers a ``?`` *written* after it started (``fresh=True``: needed to know that the robot has
seen bytes written before, e.g. a feed hold or a line whose reply is overdue).

For the second kind, each report is credited to the **oldest** ``?`` not answered yet (the
robot answers in order, so a report never answers a request older than that one: the credit is
never newer than the truth). A ``?`` the robot ignored would make every later credit one
request too old; it is forgotten when a line's reply arrives that was written more than
:data:`ORDER_MARGIN` seconds after it (the robot prints a report as soon as it reads the ``?``,
before it reads a later line), and when a banner ends (the robot reset). So nothing is ever
credited to a request newer than the one it answers, and any number of ignored requests cost
nothing once a line has been answered.

While homing
------------
The firmware answers no ``?`` during its homing search: it prints one report when the search
ends, however many ``?`` came meanwhile (oracle). So while a homing line may still be searching
(:meth:`RobotCondition.homing_silent`) one ``?`` at most is written and not retried, and when the
homing line is answered the ``?`` written before are forgotten (:meth:`on_homing_end`). A wait
that times out meanwhile says that the arm is homing; ``through_homing`` waits (``statuses()``)
pause until the search ends instead.
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Final

from mirobot_async.condition import RobotCondition
from mirobot_async.deadline import check_timeout
from mirobot_async.errors import MirobotTimeoutError
from mirobot_async.replies import StatusReport
from mirobot_async.wire import Wire

__all__ = ["ORDER_MARGIN", "StatusPoller", "pipeline_gap"]

_log = logging.getLogger("mirobot_async.client")

ORDER_MARGIN: Final = 0.05
"""A ``?`` written this long before a line whose reply arrived first was ignored by the robot."""
PIPELINE_WINDOW: Final = 0.06
"""A completion wait's ``?`` unanswered this long no longer holds the next one back (it was
merged into the report being printed, or ignored): a report comes within about 50 ms of its
``?`` at 115200 baud with a 16 ms USB latency timer. It is still credited as usual, so the
credits stay conservative."""
MERGE_WINDOW_PER_BYTE: Final = 0.1425e-3
MERGE_WINDOW_OFFSET: Final = 12.355e-3
"""A ``?`` that reaches the robot while it still prints a report gets no report of its own, for
about ``length * MERGE_WINDOW_PER_BYTE - MERGE_WINDOW_OFFSET`` seconds after the ``?`` that
asked for it (``length`` with CR LF; measured on the vendor's firmware at rest: 12.6 ms for 175
bytes, 15.2 ms for 193; longer while the arm moves fast). Pipelined ``?`` are spaced wider."""
REPORT_BYTE_SECONDS: Final = 93.5e-6
"""The robot's UART sends a byte every 93.5 us (115200 baud with its gaps, vendor's firmware):
back-to-back reports follow each other this fast per byte, no faster."""
MERGE_MARGIN: Final = 0.0012
MAX_OUTSTANDING: Final = 4096
"""Unanswered ``?`` remembered at most; beyond, no ``?`` is written until one is answered."""


@dataclass(slots=True, eq=False)
class _Waiter:
    """Wants the next report received, or (``not_before`` finite) one answering a ``?`` written
    at or after ``not_before``."""

    fut: asyncio.Future[tuple[StatusReport, float] | BaseException]
    not_before: float
    depth: int = 1  # "?" it wants in flight at once (2+: a completion wait, see fetch)


class StatusPoller:
    """The shared status requests of one connection."""

    def __init__(self, wire: Wire, condition: RobotCondition) -> None:
        self._wire = wire
        self._condition = condition
        self._loop: asyncio.AbstractEventLoop | None = None
        self.retry_interval = 0.25
        self.min_gap = 0.002
        self.pipeline_gap = 0.0165
        self.last_status: StatusReport | None = None
        self._waiters: list[_Waiter] = []
        self._asks: deque[float] = deque()  # write times of unanswered "?", oldest first
        self._last_ask = -math.inf
        self._last_report = -math.inf  # when the last report (even a corrupted one) arrived
        self._timer: asyncio.TimerHandle | None = None

    def start(self, loop: asyncio.AbstractEventLoop) -> None:
        """Use ``loop`` (the connection's) for timers."""
        self._loop = loop

    @property
    def outstanding(self) -> int:
        """``?`` written and not answered (nor taken as ignored) yet."""
        return len(self._asks)

    @property
    def waiter_count(self) -> int:
        """Calls currently waiting for a report."""
        return sum(not waiter.fut.done() for waiter in self._waiters)

    # ---- received ----

    def on_status(self, report: StatusReport) -> None:
        """A well-formed report: credit it, give it to the waiters it satisfies."""
        self._wire.stats.status_reports += 1
        self.last_status = report
        self._last_report = self._running_loop().time()
        asked_at = self._asks.popleft() if self._asks else -math.inf
        keep: list[_Waiter] = []
        for waiter in self._waiters:
            if waiter.fut.done():
                continue
            if waiter.not_before <= asked_at:
                waiter.fut.set_result((report, asked_at))
            else:
                keep.append(waiter)
        self._waiters = keep
        self.pump()

    def on_corrupted(self, reason: str) -> None:
        """An unreadable report answered the oldest ``?``: drop it and ask again."""
        self._wire.stats.status_corrupted += 1
        _log.warning("dropped a corrupted status line (%s)", reason)
        if self._asks:
            self._asks.popleft()
        self._last_report = self._running_loop().time()
        self.pump()

    def on_line_reply(self, written_at: float) -> None:
        """A line written at ``written_at`` was answered: a ``?`` written well before it that is
        still unanswered was ignored by the robot (its report would have come first)."""
        asks = self._asks
        limit = written_at - ORDER_MARGIN
        forgotten = 0
        while asks and asks[0] < limit:
            asks.popleft()
            forgotten += 1
        if forgotten:
            self._wire.stats.status_requests_forgotten += forgotten
            _log.debug("%d status request(s) were ignored by the robot", forgotten)

    def on_homing_end(self) -> None:
        """The homing line was answered: the ``?`` written during the search were merged into
        the one report printed at its end; forget them (as after a banner) and ask anew."""
        self._asks.clear()
        self.pump()

    def on_banner(self) -> None:
        """The robot reset: a ``?`` written before may never be answered; forget them all (a late
        report is then credited to none, so it satisfies no waiter asking for a fresh one)."""
        self._asks.clear()
        self.pump()

    # ---- waiting ----

    async def fetch(
        self,
        *,
        fresh: bool,
        timeout: float | None,
        what: str = "a status report",
        depth: int = 1,
        through_homing: bool = False,
    ) -> tuple[StatusReport, float]:
        """The next report (``fresh``: one answering a ``?`` written after this call started) and
        the write time of the ``?`` it is credited to (``-inf``: none).

        ``depth`` > 1 (a wait for the end of motion) keeps up to that many ``?`` in flight,
        written :attr:`pipeline_gap` apart (about one report's time on a 115200-baud wire; more
        for a long report, so that the robot does not merge the next ``?`` into it), so
        that the robot samples its state every report instead of once per round trip; only
        while no line is in flight (the reports would delay their replies).

        Raises :class:`MirobotTimeoutError` naming ``what`` after ``timeout`` seconds (saying that
        the arm is homing, if it is), what the connection fails with (a lost link, a hard
        limit). With ``through_homing`` the timeout is extended while a homing search may still
        run (the wait pauses until its report comes). Cancellation is safe.
        """
        check_timeout(timeout)
        condition = self._condition
        condition.check_answering()
        loop = self._running_loop()
        waiter = _Waiter(loop.create_future(), loop.time() if fresh else -math.inf, depth)
        self._waiters.append(waiter)
        self.pump()
        end = None if timeout is None else loop.time() + timeout
        try:
            while True:
                wait = None if end is None else max(0.0, end - loop.time())
                done, _ = await asyncio.wait((waiter.fut,), timeout=wait)
                if done:
                    break
                homing = condition.homing_silent(loop.time())
                if through_homing and homing is not None and end is not None:
                    end = max(end, homing.ends_by + (timeout or 0.0))
                    continue
                homing = condition.homing
                if homing is not None:
                    what = f"{what} ({homing.describe()})"
                raise MirobotTimeoutError(what, timeout)
            result = waiter.fut.result()
        finally:
            if not waiter.fut.done():
                waiter.fut.cancel()
        if isinstance(result, BaseException):
            raise result
        return result

    def fail_all(self, error: Callable[[], BaseException]) -> None:
        """Every waiter fails with ``error()``; the retry timer stops."""
        for waiter in self._waiters:
            if not waiter.fut.done():
                waiter.fut.set_result(error())
        self._waiters.clear()
        self._stop_timer()

    # ---- writing "?" ----

    def pump(self) -> None:
        """Write a ``?`` if a waiter needs one now; otherwise arm the timer for when it will."""
        condition = self._condition
        if condition.fatal is not None or not condition.connected or condition.reset_only:
            return
        waiting = [w for w in self._waiters if not w.fut.done()]
        if not waiting:
            self._waiters.clear()
            self._stop_timer()
            return
        now = self._running_loop().time()
        homing = condition.homing_silent(now)
        if homing is not None and self._asks and self._asks[-1] >= homing.started:
            # One "?" asked during the homing search gets the one report printed when it ends;
            # more would only be merged into it. Ask again once the bound has passed.
            self._arm_timer(homing.ends_by)
            return
        newest_fresh = max(w.not_before for w in waiting)
        asks = self._asks
        depth = max(w.depth for w in waiting)
        pipelining = depth > 1 and newest_fresh == -math.inf and not self._wire.conn.pending_count
        if pipelining:
            # A completion wait: one "?" every pipeline gap, at most ``depth`` in flight (those
            # older than PIPELINE_WINDOW were merged or ignored), so the reports follow each other.
            recent = [asked for asked in asks if asked > now - PIPELINE_WINDOW]
            due = self._last_ask + (self._pipeline_gap() if recent else self.min_gap)
            if len(recent) >= depth:
                due = max(due, recent[0] + PIPELINE_WINDOW)
            if now < due:
                self._arm_timer(due)
                return
        elif asks and asks[-1] >= newest_fresh and asks[-1] > self._last_report:
            # A "?" that can satisfy everyone is in flight (no report came since it was
            # written; one that did may have answered it): ask again only if it is late.
            due = self._last_ask + self.retry_interval
            if now < due:
                self._arm_timer(due)
                return
            self._wire.stats.status_retries += 1
            _log.debug("no status reply after %.3f s; asking again", now - self._last_ask)
        else:
            due = self._last_ask + self.min_gap
            if now < due:
                self._arm_timer(due)
                return
        if len(asks) >= MAX_OUTSTANDING:
            self._arm_timer(now + self.retry_interval)
            return
        self._wire.request_status()
        asks.append(now)
        self._last_ask = now
        self._arm_timer(now + (self._pipeline_gap() if pipelining else self.retry_interval))

    def _pipeline_gap(self) -> float:
        """:func:`pipeline_gap` for the last report's length."""
        report = self.last_status
        if report is None:
            return self.pipeline_gap
        return pipeline_gap(len(report.to_line()) + 2, self.pipeline_gap)

    def _arm_timer(self, when: float) -> None:
        timer = self._timer
        if timer is not None:
            if timer.when() == when:
                return
            timer.cancel()
        self._timer = self._running_loop().call_at(when, self._on_timer)

    def _stop_timer(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _on_timer(self) -> None:
        self._timer = None
        self.pump()

    def _running_loop(self) -> asyncio.AbstractEventLoop:
        assert self._loop is not None
        return self._loop


def pipeline_gap(report_length: int, minimum: float) -> float:
    """Seconds between two pipelined ``?`` when reports are ``report_length`` bytes long (with
    CR LF), at least ``minimum``: back-to-back reports come one report's transmission apart,
    and a ``?`` sooner than that after the previous one would reach the robot while it still
    prints that one's report, and be merged into it (``MERGE_WINDOW_PER_BYTE``)."""
    merged_until = report_length * MERGE_WINDOW_PER_BYTE - MERGE_WINDOW_OFFSET
    sent_in = report_length * REPORT_BYTE_SECONDS
    return max(minimum, max(merged_until, sent_in) + MERGE_MARGIN)
