"""What one bus node still owes the host: the replies to the requests sent to it (sans-IO).

Replies on the controller bus carry no address (EXBOX.md 2), so the host talks to one node at
a time and every line it receives belongs to that node. :class:`NodeLedger` says which of the
node's requests each received line belongs to and what to do with it:

* the arm answers the line ends it receives in order (PROTOCOL.md 2: ``\\r`` and ``\\n`` each end
  a line, so a line sent with ``\\r\\n`` is answered twice: its own reply, then an ``ok`` for the
  empty line), so *final* lines (``ok``, a glued ``...ok``, an error) are matched first come,
  first served to the requests in the order they were sent;
* a status report (``<...>``) answers the oldest status request, whatever is still owed before
  it (the arm prints it at once, like GRBL's realtime ``?``);
* any other text belongs to the oldest request still owed (text printed before its final reply,
  an alarm, a banner): it is passed to the arm's client unless a controller command owns it.

Only the first final reply of a forwarded line reaches the arm's client; the extra ``ok`` of the
line end and those of status or realtime requests are consumed here, so the client sees what a
direct link would show. Pure: no I/O, no clock.
"""

from __future__ import annotations

import enum
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

from mirobot_async._core.line import parse_line

__all__ = ["Kind", "NodeLedger", "Owed", "forwarded_line", "is_final", "is_status"]


def is_final(text: str) -> bool:
    """A final reply: ``ok`` (possibly glued to a text) or an error line."""
    stripped = text.strip()
    return stripped.endswith("ok") or stripped.lower().startswith("error")


def is_status(text: str) -> bool:
    """An arm's status report line."""
    return text.startswith("<")


def forwarded_line(text: str, ends: int) -> Owed:
    """A line forwarded to the arm, owed ``ends`` final replies; what it may occupy (the
    planner, a homing search) is read from its one parse."""
    parsed = parse_line(text)
    return Owed(Kind.LINE, text, ends, moves=parsed.queues_motion, homing_kind=parsed.homing_kind)


class Kind(enum.Enum):
    """What a request sent to a node is."""

    LINE = "line"  # a line forwarded to the arm (G-code, $ commands, M codes)
    STATUS = "status"  # "?" forwarded to the arm
    REALTIME = "realtime"  # "!", "~", "%" forwarded to the arm
    CONTROLLER = "controller"  # an O command or $V answered by the controller


@dataclass(slots=True)
class Owed:
    """One request sent to a node and what of its reply is still to come."""

    kind: Kind
    command: str
    finals: int
    """Final reply lines still owed (the arm answers every line end; a controller command one)."""
    status_owed: bool = False
    for_client: bool = True
    """Deliver the reply to the arm's client (False: a probe of the bus itself, consumed)."""
    main_final_pending: bool = True
    """A LINE's own reply has not come yet (the first final; later ones are line-end ``ok``s)."""
    lines: list[str] = field(default_factory=list)
    """A controller command's reply lines."""
    sent_at: float = 0.0
    answered_before: int = 0
    moves: bool = True
    """A LINE that may put a block in the arm's planner (an axis word or a ``G4`` dwell:
    :attr:`ParsedLine.queues_motion <mirobot_async._core.line.ParsedLine.queues_motion>`; ``$``
    commands do not: ``$H`` is answered when homing ends, whatever the planner holds)."""
    homing_kind: Literal["$H", "$HH"] | None = None
    """A LINE that starts a homing search (:attr:`ParsedLine.homing_kind
    <mirobot_async._core.line.ParsedLine.homing_kind>`): the arm answers no ``?`` meanwhile."""
    copies: int = 1
    """A status request of the client: how many of its ``?`` it stands for (those written
    while it waited to be sent; its report, printed after all of them, answers each)."""
    """A status request: the node's lines answered when it was sent (see
    :attr:`NodeLedger.unfinished`)."""

    @property
    def done(self) -> bool:
        return self.finals <= 0 and not self.status_owed


class NodeLedger:
    """The requests one node has not finished answering, oldest first."""

    def __init__(self, deliver: Callable[[bytes], None]) -> None:
        self.deliver: Callable[[bytes], None] | None = deliver
        """Where the arm's lines go (``None`` once the arm's client has closed: consumed)."""
        self.owed: deque[Owed] = deque()
        self.stray = 0
        """Lines received while nothing was owed (counted and dropped)."""
        self.lines_answered = 0
        """Forwarded lines the arm has answered ``ok`` (queued, not done; errors queue
        nothing)."""
        self.lines_finished = 0
        """Of those, how many are known to be done: all that were answered before a status
        request whose report said ``Idle`` or ``Alarm`` (nothing in the planner)."""

    @property
    def unfinished(self) -> int:
        """Lines answered or in flight that may still occupy the arm's planner."""
        in_flight = sum(
            1 for o in self.owed if o.kind is Kind.LINE and o.main_final_pending and o.moves
        )
        return self.lines_answered - self.lines_finished + in_flight

    def __bool__(self) -> bool:
        return bool(self.owed)

    def add(self, owed: Owed) -> None:
        self.owed.append(owed)

    @property
    def holds_controller_command(self) -> bool:
        return any(o.kind is Kind.CONTROLLER for o in self.owed)

    def take(self, raw: bytes) -> list[Owed]:
        """One received line (line end included); returns the requests it completed."""
        text = raw.decode("ascii", "replace").rstrip("\r\n")
        if not text.strip():
            return self._pop_done()  # empty lines (before some messages) mean nothing
        if is_status(text):
            owner = next((o for o in self.owed if o.status_owed), None)
            if owner is None:
                self.stray += 1
            else:
                owner.status_owed = False
                if text.startswith(("<Idle", "<Alarm")):
                    self.lines_finished = max(self.lines_finished, owner.answered_before)
                if owner.for_client:
                    for _ in range(owner.copies):
                        self._pass(raw)
            return self._pop_done()
        head = next((o for o in self.owed if o.finals > 0), None)
        if head is None:
            self.stray += 1
            if not is_final(text):
                self._pass(raw)  # an alarm or a banner: the arm's client must hear it
            return self._pop_done()
        if head.kind is Kind.CONTROLLER:
            head.lines.append(text)
            if is_final(text):
                head.finals -= 1
            return self._pop_done()
        if not is_final(text):
            self._pass(raw)  # text before a final reply, an alarm, a banner
            return self._pop_done()
        head.finals -= 1
        if head.kind is Kind.LINE and head.main_final_pending:
            head.main_final_pending = False
            if head.moves and not text.strip().lower().startswith("error"):
                self.lines_answered += 1
            if head.for_client:
                self._pass(raw)
        return self._pop_done()

    def settle(self, *, realtime: bool = False) -> list[Owed]:
        """The node went quiet: finish the head request if its reply is complete enough.

        A controller command with at least one line (a query's bare value), a line whose own
        reply came but whose line-end ``ok`` did not (a controller that does not relay it), a
        status request whose report came; with ``realtime`` also a realtime request that got
        no ``ok`` (the caller waits longer for those: a reset's banner takes a while).
        """
        if not self.owed:
            return []
        head = self.owed[0]
        complete = {
            Kind.CONTROLLER: bool(head.lines),
            Kind.LINE: not head.main_final_pending,
            Kind.STATUS: not head.status_owed,
            Kind.REALTIME: realtime,
        }
        if complete[head.kind]:
            head.finals = 0
        return self._pop_done()

    def clear(self) -> list[Owed]:
        """Forget everything owed (the node is gone); returns what was dropped."""
        dropped = list(self.owed)
        self.owed.clear()
        return dropped

    def _pass(self, raw: bytes) -> None:
        if self.deliver is not None:
            self.deliver(raw if raw.endswith(b"\n") else raw + b"\r\n")

    def _pop_done(self) -> list[Owed]:
        done: list[Owed] = []
        while self.owed and self.owed[0].done:
            done.append(self.owed.popleft())
        return done
