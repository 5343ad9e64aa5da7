"""The event router: received bytes -> state-machine events -> the part of the client they concern.

:class:`EventRouter` is the transport's callback target. It feeds the bytes through the wire,
hands each event to the line scheduler (replies, resets), the status poller (reports), the
robot's condition (alarms, banners) and the envelope guard (forget the prediction), and wakes the
waiting calls. A dead link (end of file, I/O error, :meth:`close`) fails everything once.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable

from mirobot_async._client.condition import RobotCondition
from mirobot_async._client.guard import EnvelopeGuard, NullGuard
from mirobot_async._client.poller import StatusPoller
from mirobot_async._client.scheduler import LineScheduler
from mirobot_async._client.wire import Wire
from mirobot_async._core.protocol import (
    AlarmRaised,
    BannerReceived,
    ConnectionClosed,
    DoubtResolved,
    Event,
    LineAcknowledged,
    LineOutcomeUnknown,
    LineRejected,
    ProtocolViolation,
    ResetDetected,
    StatusCorrupted,
    StatusReceived,
    UnsolicitedText,
)
from mirobot_async._core.replies import ReplyKind, State
from mirobot_async.errors import MirobotAlarmError, MirobotLinkLostError

_AT_REST = frozenset({State.IDLE, State.ALARM})

__all__ = ["EventRouter", "url_text"]

_log = logging.getLogger("mirobot_async.client")


def url_text(url: str | None) -> str:
    """``url`` quoted for messages."""
    return repr(url) if url is not None else "the port"


class EventRouter:
    """Routes one connection's events to its parts."""

    def __init__(
        self,
        wire: Wire,
        condition: RobotCondition,
        poller: StatusPoller,
        guard: EnvelopeGuard | NullGuard,
        lines: LineScheduler,
        url: Callable[[], str | None],
    ) -> None:
        self._wire = wire
        self._condition = condition
        self._poller = poller
        self._guard = guard
        self._lines = lines
        self._url = url
        self._loop: asyncio.AbstractEventLoop | None = None

    def start(self, loop: asyncio.AbstractEventLoop) -> None:
        """Use ``loop`` (the connection's)."""
        self._loop = loop
        self._lines.dispatch = self.dispatch

    def on_data(self, data: bytes) -> None:
        """The transport received ``data``."""
        if self._condition.fatal is not None:
            return
        try:
            for event in self._wire.receive(data):
                self.dispatch(event)
        except Exception as exc:  # a bug here must not kill the transport silently
            _log.exception("internal error while handling received data")
            self.set_fatal(f"internal error while handling received data: {exc!r}")

    def on_lost(self, exc: BaseException | None) -> None:
        """The transport ended by itself (``exc``: the error, ``None``: end of file)."""
        if self._condition.closing:
            return
        detail = f": {exc}" if exc is not None else " (end of file)"
        self.set_fatal(f"the link to {url_text(self._url())} was lost{detail}")

    def dispatch(self, event: Event) -> None:
        """Hand ``event`` to the part it concerns, then wake the waiting calls."""
        stats = self._wire.stats
        if isinstance(event, StatusReceived):
            self._poller.on_status(event.report)
            self._lines.watch.on_status(event.report)
            if event.report.state in _AT_REST and not self._wire.conn.pending_count:
                # printed after the last line's reply: nothing is queued (GRBL starts queued
                # motion before it answers a ?), so a mode word now restarts from the end
                self._guard.arm_at_rest()
            return
        if isinstance(event, LineAcknowledged | LineRejected):
            self._lines.on_reply(event)
        elif isinstance(event, StatusCorrupted):
            self._poller.on_corrupted(event.reason)
        elif isinstance(event, AlarmRaised):
            self._on_alarm(event.text, event.code)
        elif isinstance(event, ResetDetected):
            stats.resets += 1
            assert self._loop is not None
            self._condition.on_reset(self._loop.time())
            self._guard.forget("reset")  # power-on modes; the arm stopped wherever it was
            if event.in_doubt:
                self._guard.forget("lost")  # lines in doubt may change the modes
            self._lines.on_reset(event)
            if self._lines.observers:
                self._lines.observers.reset()
        elif isinstance(event, DoubtResolved):
            self._lines.on_doubt_resolved(event)
        elif isinstance(event, LineOutcomeUnknown):
            self._lines.on_outcome_unknown(event)
        elif isinstance(event, BannerReceived):
            self._condition.on_banner(event.lines)
            self._poller.on_banner()
            self._lines.on_banner()
        elif isinstance(event, UnsolicitedText):
            _log.info("robot says: %s", event.text)
            if event.kind is ReplyKind.FEEDBACK and self._condition.on_feedback(event.text):
                self._fail_for_reset_only(self._condition.reset_only or event.text)
        elif isinstance(event, ProtocolViolation):
            stats.protocol_violations += 1
            _log.warning("protocol violation: %s: %r", event.description, event.data)
        elif isinstance(event, ConnectionClosed):
            self.on_lost(None)
        self._wire.notify()

    def _on_alarm(self, text: str, code: int | None) -> None:
        if self._condition.refuses_a_line(text, code):
            return  # the line's output holds it: its reply says what was refused
        self._wire.stats.alarms += 1
        self._guard.forget("alarm")  # an alarm may stop the arm anywhere
        if self._lines.observers:
            self._lines.observers.alarm(text)
        assert self._loop is not None
        if not self._condition.on_alarm(text, self._loop.time()):
            return  # the firmware still answers lines, or a banner follows
        self._fail_for_reset_only(text)

    def _fail_for_reset_only(self, text: str) -> None:
        """Hard limit: the firmware processes nothing but "%", not even "?". Fail every pending
        line and status request now; their slots stay, so late replies are still matched."""
        self._lines.fail_waiting(
            lambda slot: MirobotAlarmError(slot.command, text, output=("ALARM: " + text,)),
            forget=False,
        )
        self._poller.fail_all(lambda: MirobotAlarmError(None, text))

    def set_fatal(self, message: str) -> None:
        """The link is unusable: fail everything pending, once, and every later call."""
        condition = self._condition
        told = self._lines.awaited or self._poller.waiter_count > 0
        told = told or condition.banner_waiters_waiting
        if not condition.set_fatal(message):
            return
        self._wire.end_tap("closed" if condition.closing else "lost")
        # The waiting calls raise MirobotLinkLostError with this message (and so does every later
        # call): log it loudly only when no call is waiting to show it.
        (_log.debug if condition.closing else _log.info if told else _log.warning)("%s", message)
        self._lines.fail_waiting(
            lambda slot: MirobotLinkLostError(f"{message}; no reply to {slot.command!r}"),
            forget=True,
        )
        self._poller.fail_all(lambda: MirobotLinkLostError(f"{message}; no status reply"))
        condition.fail_banner_waiters(message)
        self._wire.notify()
        self._wire.abort()
