"""What the connection state machine (:mod:`mirobot_async._core.protocol`) reports (PURE data).

:class:`PendingLine` is a line owed a reply; the other classes are the events of
:meth:`MirobotConnection.next_event <mirobot_async._core.protocol.MirobotConnection.next_event>`,
all importable from :mod:`mirobot_async._core.protocol` too.
"""

from __future__ import annotations

from dataclasses import dataclass

from mirobot_async._core.replies import Refusal, ReplyKind, StatusReport

__all__ = [
    "AlarmRaised",
    "BannerReceived",
    "ConnectionClosed",
    "DoubtResolved",
    "Event",
    "LineAcknowledged",
    "LineOutcomeUnknown",
    "LineRejected",
    "PendingLine",
    "ProtocolViolation",
    "ResetDetected",
    "StatusCorrupted",
    "StatusReceived",
    "UnsolicitedText",
]


@dataclass(frozen=True, slots=True)
class PendingLine:
    """A line sent to the robot and owed a final reply.

    ``id`` is unique per connection (increasing); ``line`` the command without line ending;
    ``wire`` the exact bytes to write (``line + b"\\n"``), whose length is what character counting
    charges against the robot's receive buffer.
    """

    id: int
    line: bytes
    wire: bytes


# ---- events ------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class LineAcknowledged:
    """The oldest pending line got ``ok``.

    ``output`` holds the non-empty lines printed for it before (or glued to) the ``ok``, exactly as
    printed minus surrounding whitespace. ``refusal`` is set when that output says the firmware
    dropped the motion anyway (locked axes, soft limit, unreachable target).
    """

    line: PendingLine
    output: tuple[str, ...]
    refusal: Refusal | None


@dataclass(frozen=True, slots=True)
class LineRejected:
    """The oldest pending line got an error reply; ``code`` is the 2021 ``E<nnn>`` number."""

    line: PendingLine
    text: str
    code: int | None
    output: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class LineOutcomeUnknown:
    """The first line in doubt that was answered after a reset: ``reply`` (its
    :class:`LineAcknowledged` or :class:`LineRejected`) may be for the line's tail alone (the
    reset cut it on its way), so whether it ran is unknown."""

    line: PendingLine
    reply: LineAcknowledged | LineRejected


@dataclass(frozen=True, slots=True)
class StatusReceived:
    """A well-formed ``<...>`` status report; ``raw`` is the line as printed."""

    report: StatusReport
    raw: str


@dataclass(frozen=True, slots=True)
class StatusCorrupted:
    """A ``<...`` line that is not a valid status report (drop it, count it, poll again)."""

    raw: str
    reason: str


@dataclass(frozen=True, slots=True)
class AlarmRaised:
    """``ALARM: <text>``: the robot entered Alarm (hard limit, abort during cycle...); 2024
    ``Error,A102,Soft limit:B`` -> text ``Soft limit:B``, ``code`` 102 (None when unnumbered)."""

    text: str
    code: int | None = None


@dataclass(frozen=True, slots=True)
class UnsolicitedText:
    """Text printed while no line was pending; ``text`` is the payload (see ``Reply.text``)."""

    kind: ReplyKind
    text: str


@dataclass(frozen=True, slots=True)
class ResetDetected:
    """The robot reset (its banner started): the ``failed`` lines were lost and never run.

    ``in_doubt`` lines were written after the ``%`` the host asked for (all pending lines, for a
    reset the host did not ask for): the robot may have received them after it reset, and then
    ran them. Their replies, if any, follow the banner: the robot runs the lines it received
    after resetting, which are the last ones written, so ``k`` replies answer the last ``k``
    lines in doubt. They are settled by :class:`DoubtResolved` and the usual reply events.
    """

    failed: tuple[PendingLine, ...]
    in_doubt: tuple[PendingLine, ...] = ()


@dataclass(frozen=True, slots=True)
class DoubtResolved:
    """The lines in doubt after a reset are settled: ``not_run`` were lost with the robot's
    buffer; the first answered one may have been cut by the reset (:class:`LineOutcomeUnknown`),
    the others ran and their :class:`LineAcknowledged` / :class:`LineRejected` events
    follow this one (emitted once every line in doubt got a reply, or by
    :meth:`MirobotConnection.resolve_doubt` when the host knows no more replies can come)."""

    not_run: tuple[PendingLine, ...]


@dataclass(frozen=True, slots=True)
class BannerReceived:
    """The complete reset banner: its non-empty lines, stripped, first to ``Using reset pos!``.

    A banner that does not end within ``MirobotConnection.MAX_BANNER_LINES`` lines is reported
    with the lines seen so far.
    """

    lines: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class ProtocolViolation:
    """The robot printed something the protocol does not allow; ``data`` is (a prefix of) it."""

    description: str
    data: bytes


@dataclass(frozen=True, slots=True)
class ConnectionClosed:
    """End of file: the peer closed the link (``receive_data(b"")``)."""


Event = (
    LineAcknowledged
    | LineRejected
    | LineOutcomeUnknown
    | StatusReceived
    | StatusCorrupted
    | AlarmRaised
    | UnsolicitedText
    | ResetDetected
    | DoubtResolved
    | BannerReceived
    | ProtocolViolation
    | ConnectionClosed
)
