"""The connection state machine (sans-IO, h11 style; PURE: no asyncio, no serial, no OS calls).

:class:`MirobotConnection` knows which lines are owed a reply and how many bytes sit in the robot's
127 bytes of receive buffer; it turns the bytes the robot prints into :data:`Event` objects. It
never reads or writes anything itself: the caller writes what :meth:`MirobotConnection.send_line`
and the realtime helpers return, feeds every received byte to
:meth:`MirobotConnection.receive_data`, and drains :meth:`MirobotConnection.next_event` (or
:meth:`MirobotConnection.events`).

The rules (PROTOCOL.md sections 2-4 and 10):

* Every line sent gets exactly one final reply, ``ok`` or an error line, **in order**: each final
  reply resolves the *oldest* pending line (:class:`LineAcknowledged` / :class:`LineRejected`).
* Text printed while a line is pending (bare text, ``Info, ...``, ``[...]``) belongs to the oldest
  pending line and is attached to its reply as ``output``; with nothing pending it is
  :class:`UnsolicitedText`. An ``ok`` glued to a text (``in homeing moving...ok``) is both.
* ``<...>`` status lines and ``ALARM:`` lines are never replies to a line: they are always their
  own events (:class:`StatusReceived` / :class:`StatusCorrupted`, :class:`AlarmRaised`).
* The first banner line means the robot reset: every pending line is lost
  (:class:`ResetDetected`); the banner is then collected into one :class:`BannerReceived`.
* Character counting: the bytes of unacknowledged lines never exceed ``rx_buffer_size``; the
  caller asks :meth:`MirobotConnection.fits` before writing and waits for acknowledgements.
* Nothing the robot prints raises an exception: surprises become :class:`ProtocolViolation`
  events (a stray ``ok``, an overlong line) and the machine carries on.

Events come out in the order their bytes arrived. Lines are handled as soon as they are complete
(in :meth:`~MirobotConnection.receive_data`), so an ``ok`` that arrived before a line was sent can
never be matched to that line.
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Callable, Iterator

from mirobot_async._core.events import (
    AlarmRaised,
    BannerReceived,
    ConnectionClosed,
    DoubtResolved,
    Event,
    LineAcknowledged,
    LineOutcomeUnknown,
    LineRejected,
    PendingLine,
    ProtocolViolation,
    ResetDetected,
    StatusCorrupted,
    StatusReceived,
    UnsolicitedText,
)
from mirobot_async._core.outgoing import encode_line
from mirobot_async._core.replies import (
    Reply,
    ReplyKind,
    classify_line,
    find_refusal,
    parse_status,
)
from mirobot_async.errors import MirobotProtocolError, MirobotUsageError

FinalReply = LineAcknowledged | LineRejected  # a line's final reply

__all__ = [
    "AlarmRaised",
    "BannerReceived",
    "ConnectionClosed",
    "DoubtResolved",
    "Event",
    "LineAcknowledged",
    "LineOutcomeUnknown",
    "LineRejected",
    "MirobotConnection",
    "PendingLine",
    "ProtocolViolation",
    "ResetDetected",
    "StatusCorrupted",
    "StatusReceived",
    "UnsolicitedText",
    "encode_line",
]


# ---- the state machine ---------------------------------------------------------------------------

_LINE_END_RE = re.compile(rb"[\r\n]")
_OK = b"ok"


class MirobotConnection:
    """Sans-IO state of one link to a Mirobot: lines owed a reply, bytes in flight, events.

    ``rx_buffer_size`` is what the robot's receive buffer holds: its ring has 128 slots and one
    stays free, so 127 bytes (the firmware oracle: with 128 counted in flight a byte is lost when
    the firmware prints a status report as the buffer fills; with 127 never);
    ``max_reply_length`` bounds a line from the robot: a longer one is reported once as a
    :class:`ProtocolViolation` and skipped up to the next line end, so memory stays bounded
    whatever the robot (or line noise) sends. ``max_output_lines`` bounds the text lines kept
    for one pending line (``$$`` prints 85 on the 2021 firmware): further ones are dropped until
    that line's reply, and the drop is reported once as a :class:`ProtocolViolation`.
    """

    #: A banner that has not ended after this many non-empty lines is closed anyway (the classic
    #: banner has 19).
    MAX_BANNER_LINES = 40

    __slots__ = (
        "_banner",
        "_buffer",
        "_bytes_in_flight",
        "_closed",
        "_discarding",
        "_doubt_replies",
        "_events",
        "_in_doubt",
        "_next_id",
        "_output",
        "_output_dropped",
        "_pending",
        "_reset_mark",
        "_status_outstanding",
        "max_output_lines",
        "max_reply_length",
        "rx_buffer_size",
    )

    def __init__(
        self, *, rx_buffer_size: int = 127, max_reply_length: int = 512, max_output_lines: int = 256
    ) -> None:
        if rx_buffer_size < 2:
            raise MirobotUsageError(f"rx_buffer_size must be at least 2, not {rx_buffer_size}")
        if max_reply_length < 1:
            raise MirobotUsageError(f"max_reply_length must be positive, not {max_reply_length}")
        if max_output_lines < 1:
            raise MirobotUsageError(f"max_output_lines must be positive, not {max_output_lines}")
        self.rx_buffer_size = rx_buffer_size
        self.max_reply_length = max_reply_length
        self.max_output_lines = max_output_lines
        self._buffer = bytearray()  # an incomplete line, never longer than max_reply_length
        self._discarding = False  # skipping the rest of an overlong line
        self._closed = False
        self._events: deque[Event] = deque()
        self._pending: deque[PendingLine] = deque()
        self._output: list[str] = []  # text printed so far for the oldest pending line
        self._output_dropped = False  # more than max_output_lines of it: the rest is dropped
        self._bytes_in_flight = 0
        self._status_outstanding = 0
        self._next_id = 0
        self._banner: list[str] | None = None  # lines of a banner being collected
        self._reset_mark: int | None = None  # first line id written after a requested "%"
        self._in_doubt: list[PendingLine] = []  # lines that may have run after a reset
        self._doubt_replies: list[Callable[[PendingLine], FinalReply]] = []  # replies seen for them

    # ---- introspection ----

    @property
    def bytes_in_flight(self) -> int:
        """Sum of ``len(wire)`` of the pending lines: what the robot's receive buffer may hold."""
        return self._bytes_in_flight

    @property
    def pending_count(self) -> int:
        """How many lines are owed a final reply."""
        return len(self._pending)

    @property
    def pending_lines(self) -> tuple[PendingLine, ...]:
        """The lines owed a final reply, oldest first."""
        return tuple(self._pending)

    @property
    def status_requests_outstanding(self) -> int:
        """``?`` bytes sent whose status report has not arrived yet (never below 0)."""
        return self._status_outstanding

    @property
    def in_doubt_count(self) -> int:
        """Lines whose fate after a reset is not settled yet (see :class:`ResetDetected`);
        write nothing until it is 0, or their late replies could not be told apart."""
        return len(self._in_doubt)

    @property
    def closed(self) -> bool:
        """True once end of file was received."""
        return self._closed

    @property
    def in_banner(self) -> bool:
        """True while a reset banner is being collected (between its first and last line)."""
        return self._banner is not None

    @property
    def buffered_bytes(self) -> int:
        """Bytes of an incomplete line held until its line end (at most ``max_reply_length``)."""
        return len(self._buffer)

    def fits(self, nbytes: int) -> bool:
        """Whether ``nbytes`` more bytes can be written without overflowing the receive buffer."""
        return self._bytes_in_flight + nbytes <= self.rx_buffer_size

    # ---- host -> robot ----

    def send_line(self, line: str | bytes) -> PendingLine:
        """Register ``line`` as sent and owed a reply; return it with the exact bytes to write.

        The line must be one ASCII line (one trailing ``"\\n"`` is accepted and stripped) without
        ``"\\r"``, ``"\\n"`` or the realtime bytes ``? ! ~ %`` and its wire form (``line + "\\n"``)
        must fit in the receive buffer at all; otherwise :class:`MirobotUsageError` is raised and
        nothing is registered. It is *not* refused for not fitting right now: the caller checks
        :meth:`fits` and waits for acknowledgements (character counting is the caller's pacing).
        The line must be written right after this call, before any further ``receive_data``.
        """
        data = encode_line(line, self.rx_buffer_size, strip=False)
        wire = data + b"\n"
        pending = PendingLine(self._next_id, data, wire)
        self._next_id += 1
        self._pending.append(pending)
        self._bytes_in_flight += len(wire)
        return pending

    def request_status(self) -> bytes:
        """Return ``b"?"`` to write (realtime: no line, no ``ok``) and count the request."""
        self._status_outstanding += 1
        return b"?"

    def request_reset(self) -> bytes:
        """Return ``b"%"``, the Mirobot's soft reset. Lines pending now fail when the banner
        starts; lines registered after this call are in doubt (see :class:`ResetDetected`)."""
        if self._reset_mark is None:
            self._reset_mark = self._next_id
        return b"%"

    def resolve_doubt(self) -> None:
        """No more replies can come for the lines in doubt (the robot is quiet and answered a
        status request written well after the banner): settle them now (:class:`DoubtResolved`
        and a reply event for each line that was answered)."""
        if self._in_doubt:
            self._settle_doubt()

    def feed_hold(self) -> bytes:
        """Return ``b"!"``: decelerate to a stop (state ``Hold``)."""
        return b"!"

    def cycle_start(self) -> bytes:
        """Return ``b"~"``: resume from ``Hold``."""
        return b"~"

    def expire_oldest(self) -> PendingLine:
        """Give up on the oldest pending line (its reply was lost) and return it.

        Later final replies resolve the following lines. Text collected for it is dropped.
        Raises :class:`MirobotUsageError` when nothing is pending.
        """
        if not self._pending:
            raise MirobotUsageError("expire_oldest() with no line pending")
        line = self._pending.popleft()
        self._bytes_in_flight -= len(line.wire)
        self._output.clear()
        self._output_dropped = False
        return line

    # ---- robot -> host ----

    def receive_data(self, data: bytes) -> None:
        """Feed bytes received from the robot; ``b""`` means end of file.

        Complete lines (ended by ``"\\r\\n"``, ``"\\n"`` or ``"\\r"``) are handled at once and their
        events queued; an incomplete line waits in a buffer bounded by ``max_reply_length``.
        After end of file, more end of file is ignored and data raises :class:`MirobotUsageError`.
        """
        if self._closed:
            if data:
                raise MirobotUsageError("receive_data() after end of file")
            return
        if not data:
            self._close()
            return
        if self._discarding:
            m = _LINE_END_RE.search(data)
            if m is None:
                return
            self._discarding = False
            data = data[m.end() :]
            if not data:
                return
        buf = self._buffer
        if buf:
            buf += data
            chunk = bytes(buf)
            buf.clear()
        else:
            chunk = bytes(data)
        lines = chunk.splitlines()
        if chunk[-1] not in b"\r\n":
            # The last line is incomplete: keep it for later, unless it is already too long.
            tail = lines.pop()
            if len(tail) > self.max_reply_length:
                self._discarding = True
                tail_violation: bytes | None = tail
            else:
                buf += tail
                tail_violation = None
        else:
            tail_violation = None
        limit = self.max_reply_length
        for raw in lines:
            if raw == _OK:
                self._final_ok("", None)
            elif len(raw) > limit:
                self._overlong(raw)
            elif raw:
                self._handle_line(raw)
        if tail_violation is not None:
            self._overlong(tail_violation)

    def next_event(self) -> Event | None:
        """The next event in arrival order, or ``None`` when more data is needed."""
        if self._events:
            return self._events.popleft()
        return None

    def events(self) -> Iterator[Event]:
        """Yield the queued events until none is left (then more data is needed)."""
        events = self._events
        while events:
            yield events.popleft()

    # ---- internals ----

    def _close(self) -> None:
        self._closed = True
        if self._discarding:
            self._discarding = False
        elif self._buffer.strip():
            self._events.append(
                ProtocolViolation("incomplete line at end of file", bytes(self._buffer))
            )
        self._buffer.clear()
        self._events.append(ConnectionClosed())

    def _overlong(self, raw: bytes) -> None:
        what = f"line longer than {self.max_reply_length} bytes; skipped to the next line end"
        self._events.append(ProtocolViolation(what, raw[: self.max_reply_length]))

    def _handle_line(self, raw_bytes: bytes) -> None:
        """Turn one complete, non-empty, not-too-long line into events."""
        events = self._events
        raw = raw_bytes.decode("ascii", "replace")
        if raw_bytes.isspace():
            return  # whitespace only: an empty line
        reply = classify_line(raw)
        kind = reply.kind
        if self._banner is not None and kind in _BANNER_BODY and not reply.ok:
            self._banner_line(reply.raw.strip(), kind is ReplyKind.BANNER_END)
            return
        if kind is ReplyKind.OK:
            self._final_ok("", None)
        elif kind is ReplyKind.ERROR:
            self._final_error(reply.text, reply.code, raw_bytes)
        elif kind is ReplyKind.STATUS:
            self._status(reply.text)
        elif kind is ReplyKind.ALARM:
            if reply.code is not None and (self._pending or self._doubt_open()):
                self._add_output(reply.raw.strip(), raw_bytes)  # 2024: maybe a refusal
            events.append(AlarmRaised(reply.text, reply.code))
        elif kind in _BANNER_FIRST:  # (a 2024 BANNER is a whole banner in one line)
            self._reset()
            self._banner = []
            self._banner_line(reply.raw.strip(), kind is not ReplyKind.BANNER_START)
        elif kind is ReplyKind.UNKNOWN:
            events.append(ProtocolViolation("a line in none of the known reply forms", raw_bytes))
        elif reply.ok:  # TEXT, INFO, FEEDBACK from here on
            self._final_ok(reply.raw.strip(), reply, raw_bytes)
        elif self._pending or (self._doubt_open() and kind is not ReplyKind.FEEDBACK):
            self._add_output(reply.raw.strip(), raw_bytes)  # ([...] after a reset: its own)
            if kind is ReplyKind.FEEDBACK and reply.text.lower() == "reset to continue":
                events.append(UnsolicitedText(kind, reply.text))  # no reply comes until "%"
        else:
            events.append(UnsolicitedText(kind, reply.text))

    def _status(self, line: str) -> None:
        if self._status_outstanding:
            self._status_outstanding -= 1
        try:
            report = parse_status(line)
        except MirobotProtocolError as err:
            self._events.append(StatusCorrupted(line, str(err)))
        else:
            self._events.append(StatusReceived(report, line))

    def _add_output(self, text: str, raw_bytes: bytes) -> None:
        """Keep ``text`` for the oldest pending line, up to ``max_output_lines`` lines."""
        output = self._output
        if len(output) < self.max_output_lines:
            output.append(text)
        elif not self._output_dropped:
            self._output_dropped = True
            self._events.append(
                ProtocolViolation(
                    f"more than {self.max_output_lines} text lines for one pending line; "
                    "dropping the rest until its reply",
                    raw_bytes,
                )
            )

    def _final_ok(self, text: str, reply: Reply | None, raw_bytes: bytes = _OK) -> None:
        """Acknowledge the oldest pending line; ``text`` is a line with a glued ``ok`` or ``""``."""
        if not self._pending and not self._doubt_open():
            if text and reply is not None:
                self._events.append(UnsolicitedText(reply.kind, reply.text))
            self._events.append(ProtocolViolation("'ok' with no line pending", raw_bytes))
            return
        output = self._output
        self._output_dropped = False
        if text:
            output.append(text)  # even past the cap: one line, and it may hold a refusal
        out = tuple(output)
        output.clear()
        refusal = find_refusal(out) if out else None
        if not self._pending:
            self._doubt_reply(lambda line: LineAcknowledged(line, out, refusal))
            return
        line = self._pending.popleft()
        self._bytes_in_flight -= len(line.wire)
        self._events.append(LineAcknowledged(line, out, refusal))

    def _final_error(self, text: str, code: int | None, raw_bytes: bytes) -> None:
        if not self._pending and not self._doubt_open():
            self._events.append(ProtocolViolation("error reply with no line pending", raw_bytes))
            return
        out = tuple(self._output)
        self._output.clear()
        self._output_dropped = False
        if not self._pending:
            self._doubt_reply(lambda line: LineRejected(line, text, code, out))
            return
        line = self._pending.popleft()
        self._bytes_in_flight -= len(line.wire)
        self._events.append(LineRejected(line, text, code, out))

    def _doubt_open(self) -> bool:
        """True while lines in doubt may still get replies."""
        return len(self._doubt_replies) < len(self._in_doubt)

    def _doubt_reply(self, make: Callable[[PendingLine], FinalReply]) -> None:
        self._doubt_replies.append(make)
        if not self._doubt_open():
            self._settle_doubt()

    def _settle_doubt(self) -> None:
        lines, replies = self._in_doubt, self._doubt_replies
        self._in_doubt, self._doubt_replies = [], []
        self._bytes_in_flight -= sum(len(line.wire) for line in lines)
        ran = len(lines) - len(replies)
        self._events.append(DoubtResolved(tuple(lines[:ran])))
        answered = [make(line) for line, make in zip(lines[ran:], replies, strict=True)]
        if answered:  # the first may have been cut by the reset: its reply may be its tail's
            self._events.append(LineOutcomeUnknown(answered[0].line, answered.pop(0)))
        self._events.extend(answered)

    def _reset(self) -> None:
        """The robot reset: lines written before it are lost; later ones may run (in doubt)."""
        if self._in_doubt:
            self._settle_doubt()  # their replies would have come before this banner
        mark, self._reset_mark = self._reset_mark, None
        failed = tuple(line for line in self._pending if mark is not None and line.id < mark)
        doubt = [line for line in self._pending if mark is None or line.id >= mark]
        self._pending.clear()
        self._output.clear()
        self._output_dropped = False
        self._in_doubt = doubt
        self._bytes_in_flight = sum(len(line.wire) for line in doubt)
        self._status_outstanding = 0
        self._events.append(ResetDetected(failed, tuple(doubt)))

    def _banner_line(self, line: str, last: bool) -> None:
        banner = self._banner
        assert banner is not None
        banner.append(line)
        if last or len(banner) >= self.MAX_BANNER_LINES:
            self._banner = None
            self._events.append(BannerReceived(tuple(banner)))


_BANNER_FIRST = frozenset({ReplyKind.BANNER_START, ReplyKind.BANNER_END, ReplyKind.BANNER})

# Line kinds that are part of a banner while one is being collected. OK, ERROR, STATUS and ALARM
# keep their meaning; a second BANNER_START (the classic banner has "Grbl 0.9j ..." and then
# "Qinnew Robot ... based on Grbl 0.9j ...") belongs to the same banner, not to a second reset.
_BANNER_BODY = frozenset(
    {
        ReplyKind.TEXT,
        ReplyKind.INFO,
        ReplyKind.FEEDBACK,
        ReplyKind.BANNER_START,
        ReplyKind.BANNER_END,
    }
)
