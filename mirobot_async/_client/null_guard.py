"""What the client follows of each line written without an envelope (:class:`NullGuard`), what
a guard keeps of a line to undo its prediction if the firmware refuses it (:class:`Tracked`),
and what both guards own alike (:class:`LineFollower`: the chaining). No I/O here.

The guard of a connection is the one owner of what follows from the lines written: the modal
words, the chaining, the base offset (and, with an envelope, the predicted position). The
scheduler, the router and the motion commands *tell* it what happened (:meth:`track_written`,
:meth:`~LineFollower.line_answered`, :meth:`~LineFollower.arm_at_rest`,
:meth:`~LineFollower.move_completed`, ``forget``) and ask it what follows; none assigns its
fields."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

from mirobot_async._client.condition import RobotCondition
from mirobot_async._core.acceptance import line_fate, modes_after_refusal
from mirobot_async._core.events import LineAcknowledged, LineRejected
from mirobot_async._core.line import ParsedLine
from mirobot_async._core.modal import Chaining, LineCheck, MotionModes
from mirobot_async._core.replies import State, StatusReport
from mirobot_async._core.validation import ModalState
from mirobot_async.errors import RefusalReason

if TYPE_CHECKING:
    from mirobot_async._safety.envelope import Envelope
    from mirobot_async._safety.prediction import MachineState

__all__ = [
    "NEED_POSITION",
    "QUIET",
    "LineFollower",
    "NeedPosition",
    "NullGuard",
    "Tracked",
    "base_offset_from_settings",
]

QUIET: Final = frozenset({State.IDLE, State.ALARM, State.CHECK})
"""States in which nothing moves."""


class NeedPosition:
    """The line moves the arm and no position is predicted: learn one first."""

    def __repr__(self) -> str:
        return "NEED_POSITION"


NEED_POSITION: Final = NeedPosition()


def base_offset_from_settings(settings: Mapping[int, float]) -> tuple[float, float, float] | None:
    """The 2021 base offset ``$41..$43`` in a ``$$`` listing, if it lists all three."""
    if all(n in settings for n in (41, 42, 43)):
        return (float(settings[41]), float(settings[42]), float(settings[43]))
    return None


@dataclass(frozen=True, slots=True)
class Tracked:
    """What the prediction assumed when a line was written (to undo it if the line fails)."""

    line_id: int
    check: LineCheck | None  # the envelope's verdict on the line (its target), if it had one
    state_before: MachineState | None  # the predicted machine state before it (no envelope: None)
    moved: bool
    modes_changed: bool
    epoch: int = 0  # the guard's epoch when it was written (a later change: do not undo)
    coordinate: int | None = None  # the work coordinate system in effect before it
    modes_before: MotionModes | None = None  # no envelope: the modes before the line
    parsed: ParsedLine | None = None  # the line
    refusal_expected: bool = False  # the firmware's refusal was predicted (and followed)


class LineFollower:
    """What both guards own alike: the chaining (which joints may still move, which the parser
    took from a mode word) and the newest line written; told, never assigned."""

    def __init__(self) -> None:
        self._chain = Chaining()
        self._last_line_id: int | None = None  # the newest line written

    @property
    def chain(self) -> Chaining:
        """Which joints may still move, which the parser took from a mode word (every line)."""
        return self._chain

    def arm_at_rest(self) -> None:
        """A status printed after the last line's reply shows the arm quiet with nothing in
        flight (GRBL starts queued motion before it answers a ``?``): a mode word now restarts
        from where the motion ended."""
        self._chain = self._chain.at_rest()

    def move_completed(self, line_id: int) -> None:
        """The motion of line ``line_id`` was seen to end (``wait=True``): the arm is at rest
        if nothing was written after it."""
        if line_id == self._last_line_id:
            self._chain = self._chain.at_rest()

    def line_answered(
        self,
        parsed: ParsedLine | None,
        tracked: Tracked | None,
        reply: LineAcknowledged | LineRejected,
    ) -> None:
        """The robot answered a line (``parsed``, ``tracked`` when the guard kept what it
        assumed; ``None`` for a line no caller waits for): undo what the reply contradicts."""
        refusal = reply.refusal if isinstance(reply, LineAcknowledged) else None
        if refusal is not None and refusal.reason is RefusalReason.LOCKED:
            # a locked arm moves nothing: every line before this one was refused too
            self._chain = self._chain.at_rest()
        if refusal is not None and parsed is not None:
            self._refused(parsed)
        if tracked is None:
            return
        if isinstance(reply, LineRejected):
            self.line_failed(tracked, rejected=True, error=reply.text)
        elif refusal is not None:
            self.line_failed(tracked, rejected=False, reason=refusal.reason)

    def _refused(self, parsed: ParsedLine) -> None:
        """``parsed`` was answered ``ok`` but dropped."""

    def line_failed(
        self,
        tracked: Tracked,
        *,
        rejected: bool,
        reason: RefusalReason | None = None,
        error: str | None = None,
    ) -> None:
        """A line the guard tracked was rejected (``rejected``) or its motion refused."""
        raise NotImplementedError


class NullGuard(LineFollower):
    """No envelope: every line passes, no position is predicted; only the modal words
    (``M20``/``M21``, ``G90``/``G91``) are followed, for the validation of raw lines."""

    epoch = 0
    parser_apart = False

    def __init__(self, condition: RobotCondition | None = None) -> None:
        super().__init__()
        self._condition = condition
        self._modes = MotionModes.unknown()
        self._base_offset: tuple[float, float, float] | None = None

    @property
    def envelope(self) -> Envelope | None:
        """``None``: there is no envelope."""
        return None

    @property
    def modes(self) -> MotionModes:
        """The modal words stated by the lines written since connect (``None``: unknown)."""
        return self._modes

    @property
    def base_offset(self) -> tuple[float, float, float] | None:
        """The 2021 base offset ``$41..$43`` from the last ``$$`` listing (``None``: unknown,
        or a line written since may have changed it; zero on classic)."""
        if self._firmware == "classic":
            return (0.0, 0.0, 0.0)
        return self._base_offset

    wants_settings = False  # no settings are needed

    def wanted_queries(self) -> tuple[str, ...]:
        """None: nothing stored in the firmware is needed."""
        return ()

    def adopt_query(self, query: str, output: Sequence[str] | None) -> None:
        """Nothing to learn."""

    def modal_state(self) -> ModalState:
        """The modal words stated by the lines written since connect (unknown before)."""
        return ModalState.of(self._modes, self._chain)

    @property
    def _firmware(self) -> str | None:
        return None if self._condition is None else self._condition.firmware

    def needs_firmware(self, parsed: ParsedLine) -> bool:
        """Never: no kinematic model is needed."""
        return False

    def verdict(self, parsed: ParsedLine, what: str | None) -> LineCheck | NeedPosition | None:
        """Nothing to check."""
        return None

    def preview(self, lines: Sequence[ParsedLine]) -> list[LineCheck] | NeedPosition:
        """Nothing to check."""
        return []

    def adopt_status(self, report: StatusReport) -> None:
        """A status at rest with nothing in flight: no motion is queued."""
        if report.state in QUIET:
            self._chain = self._chain.at_rest()

    def adopt_settings(self, settings: Mapping[int, float]) -> None:
        """A ``$$`` listing: the base offset (for where an absolute ``M20`` move reads back)."""
        offset = base_offset_from_settings(settings)
        if offset is not None:
            self._base_offset = offset

    def track_written(
        self,
        line_id: int,
        command: str,
        parsed: ParsedLine,
        verdict: LineCheck | None,
        *,
        checked: bool,
        what: str | None,
        warn_unchecked: bool,
    ) -> Tracked | None:
        """Follow the line's modal words and chaining (tracked: a line that changed the modes
        or that the firmware will refuse), as the firmware leaves them, accepted or refused."""
        self._chain = self._chain.after(parsed, self._modes)
        self._last_line_id = line_id
        if parsed.changes_base_offset:
            self._base_offset = None  # read again by the next $$
        if parsed.kind == "empty":
            return None
        before = self._modes
        fate = line_fate(parsed, before, self._firmware)
        self._modes = fate.modes
        if self._modes == before and fate.accepted is not False:
            return None
        return Tracked(
            line_id, None, None, False, True, 0, None, before, parsed,
            refusal_expected=fate.accepted is False,
        )  # fmt: skip

    def _refused(self, parsed: ParsedLine) -> None:
        """``ok`` but dropped: the parser's position may have moved, the arm did not (an
        envelope guard follows the parser's position itself: :meth:`line_failed`)."""
        self._chain = self._chain.after_refusal(parsed)

    def line_failed(
        self,
        tracked: Tracked,
        *,
        rejected: bool,
        reason: RefusalReason | None = None,
        error: str | None = None,
    ) -> None:
        """A rejected line the client predicted as accepted (``Alarm lock``, or a rule not
        modelled): undone if it was the last line written (on classic its M20/M21 still acts),
        else unknown. A refused move ran its modal words."""
        if rejected and not tracked.refusal_expected:
            last = tracked.line_id == self._last_line_id
            before = tracked.modes_before
            if last and before is not None and tracked.parsed is not None:
                self._modes = modes_after_refusal(tracked.parsed, before, self._firmware, error)
            else:
                self._modes = MotionModes.unknown()

    def forget(self, why: str) -> None:
        """A reset restores the power-on modes; a lost reply makes them unknown."""
        self._last_line_id = None
        if why in ("reset", "lost"):
            self._modes = MotionModes() if why == "reset" else MotionModes.unknown()
            self._chain = Chaining() if why == "reset" else self._chain.moved_anything()

    def warn_stream_unchecked(self) -> None:
        """No envelope, nothing to warn about."""
