"""The client's side of the safety envelope: line checks and position prediction.

:class:`EnvelopeGuard` checks each line against the ``Envelope`` right before it is written,
from the machine state predicted from every line written before it (modal words, units,
position, the 2021 base offset ``$41..$43`` and gate lift ``$49``). The check is default-deny
(:func:`~mirobot_async._safety.prediction.predict`): a line passes only when its exact effect is
predicted. What is unknown at connect stays unknown until a line states it, a status at rest
shows it (the position) or a listing gives it: the guard asks (:meth:`wanted_queries`) for
``$$``, ``$N`` (startup lines), ``$#`` and ``$G`` before the first line that moves the arm. The
parser's position is kept apart from the arm's after a refused move. :class:`NullGuard` is the
same interface without an envelope: every line passes, only the modal words are followed. No
I/O here: the scheduler learns the position when :meth:`EnvelopeGuard.verdict` asks for it.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Final

from mirobot_async._client.condition import RobotCondition
from mirobot_async._client.null_guard import (
    NEED_POSITION,
    QUIET,
    LineFollower,
    NeedPosition,
    NullGuard,
    Tracked,
    base_offset_from_settings,
)
from mirobot_async._client.wire import ClientStats
from mirobot_async._core.acceptance import line_fate, modes_after_refusal, update_modes
from mirobot_async._core.line import ParsedLine
from mirobot_async._core.modal import Chaining, LineCheck, MotionModes
from mirobot_async._core.replies import StatusReport
from mirobot_async._core.validation import ModalState
from mirobot_async._safety.firmware_memory import (
    PARSER_UNKNOWN,
    Offset,
    WorkCoordinates,
    parse_startup_lines,
    reset_modes,
    soft_limits_from_settings,
)
from mirobot_async.errors import (
    EnvelopeRefusedError,
    MirobotUsageError,
    MotionChainError,
    PathRefused,  # defined with the error tree
    RefusalReason,
)

if TYPE_CHECKING:  # imported when an envelope is used (it needs numpy)
    from mirobot_async._safety.envelope import Envelope
    from mirobot_async._safety.prediction import MachineState

__all__ = [
    "NEED_POSITION",
    "EnvelopeGuard",
    "NeedPosition",
    "NullGuard",
    "PathRefused",
    "Tracked",
    "make_guard",
]

_log = logging.getLogger("mirobot_async.client")

_QUIET: Final = QUIET


class EnvelopeGuard(LineFollower):
    """Checks lines against ``envelope`` and predicts where they leave the arm."""

    def __init__(self, envelope: Envelope, condition: RobotCondition, stats: ClientStats) -> None:
        from mirobot_async._safety.prediction import MachineState

        super().__init__()
        self._envelope = envelope
        self._classic: Envelope | None = None  # the envelope with dh=DH_CLASSIC
        self._condition = condition
        self._stats = stats
        # Everything unknown at connect: the modes (units too), the position, the base offset,
        # what the firmware stores (startup lines, work offsets, soft limits, $35).
        self._state: MachineState = MachineState(
            MotionModes.unknown(), startup_lines=None, work_offset=None, linear_g1=None
        )
        self._soft_read = False  # $20 and $130..$146 known (state.soft_limits, None if off)
        self._work = WorkCoordinates()  # $#, $G
        self.epoch = 0  # bumped when the prediction or the modes are invalidated
        self._moves = False  # whether the last prediction moves the arm
        self._verdicts: tuple[LineCheck, MachineState] | None = None  # the last verdict's state

    @property
    def envelope(self) -> Envelope:
        """The envelope in use: on a classic arm, the default ``DH_2021`` becomes ``DH_CLASSIC``."""
        envelope = self._envelope
        if self._condition.firmware != "classic":
            return envelope
        from mirobot_async.kinematics import DH_2021, DH_CLASSIC

        if envelope.dh != DH_2021:
            return envelope
        if self._classic is None:
            self._classic = replace(envelope, dh=DH_CLASSIC)
        return self._classic

    @property
    def modes(self) -> MotionModes:
        """The modal words as predicted after every line written (``None`` parts: unknown)."""
        return self._state.modes

    @property
    def base_offset(self) -> tuple[float, float, float] | None:
        """The 2021 base offset ``$41..$43`` as predicted after every line written (from a
        ``$$`` listing, then the lines that set it; ``None``: unknown; zero on classic)."""
        if self._condition.firmware == "classic":
            return (0.0, 0.0, 0.0)
        return self._state.base_offset

    @property
    def parser_apart(self) -> bool:
        """The firmware's parser is not where the arm is, or unknown (a locked refusal moved it):
        the client's own moves restate M20/M21, which re-reads the arm's position."""
        return self._state.parser is not None

    @property
    def wants_settings(self) -> bool:
        """True while the soft limits ``$20``/``$130..$146`` or, on a 2021 arm, the base offset
        ``$41..$43`` or ``$35`` are unknown (a ``$$`` listing handed to :meth:`adopt_settings`
        gives them)."""
        if not self._soft_read:
            return True
        return self._condition.firmware == "2021" and (
            self._state.base_offset is None or self._state.linear_g1 is None
        )

    def wanted_queries(self) -> tuple[str, ...]:
        """The ``$`` queries whose answers (:meth:`adopt_query`) the prediction still needs:
        ``$N`` (stored startup lines), ``$#`` (stored work offsets) and ``$G`` (which of them
        is in effect)."""
        return self._work.wanted(self._state.startup_lines is not None)

    def adopt_query(self, query: str, output: Sequence[str] | None) -> None:
        """The answer to a :meth:`wanted_queries` query (its lines before ``ok``; None: the
        firmware refused it, and what it gives stays unknown)."""
        lines = None if query != "$N" or output is None else parse_startup_lines(output)
        if lines is not None:
            self._state = replace(self._state, startup_lines=lines)
        self._work.adopt(query, output)
        self.epoch += 1

    def modal_state(self) -> ModalState:
        """The modal words :mod:`~mirobot_async._core.validation` needs, as predicted (a new
        object)."""
        return ModalState.of(self._state.modes, self._chain)

    def needs_firmware(self, parsed: ParsedLine) -> bool:
        """True when the firmware (the kinematic model) or, for a line with axis words, what the
        firmware stores (settings, startup lines, work offsets: read at rest) must be known
        before checking it."""
        if parsed.kind == "dollar":
            return False
        if self._condition.firmware is None:
            return True
        if not parsed.axis_words:
            return False
        return self.wants_settings or bool(self.wanted_queries())

    def _work_offset(self, parsed: ParsedLine | None) -> Offset | None:
        """The work offset in effect for ``parsed`` (``G54..G59`` + ``G92``), or None."""
        return self._work.offset(parsed)

    def _machine(self, parsed: ParsedLine | None = None) -> MachineState:
        """The predicted state with what the firmware profile decides filled in."""
        firmware = self._condition.firmware
        state = replace(self._state, work_offset=self._work_offset(parsed))
        if firmware == "classic":  # no base offset, no gate moves, M20 G1 in joint space
            return replace(state, base_offset=(0.0, 0.0, 0.0), gate_lift=None, firmware=firmware)
        return replace(state, firmware=firmware)

    def _predict(self, parsed: ParsedLine, state: MachineState, what: str | None) -> MachineState:
        """The state after ``parsed``; raises MirobotUsageError when the envelope refuses it."""
        from mirobot_async._safety.prediction import Prediction, predict

        result = predict(self.envelope, parsed, state, what=what)
        if not isinstance(result, Prediction):
            raise result.error()
        self._moves = result.moves
        return result.state

    def verdict(self, parsed: ParsedLine, what: str | None) -> LineCheck | NeedPosition | None:
        """The envelope's verdict on ``parsed`` from the predicted state, or
        :data:`NEED_POSITION`; raises :class:`MirobotUsageError` ("refused by the safety
        envelope ...; nothing was sent") for a line it refuses."""
        state = self._machine(parsed)
        chained = self._chain.problem(parsed, state.modes, self._condition.firmware)
        if chained is not None:  # the prediction would not be what the firmware does
            self._stats.envelope_refusals += 1
            shown = parsed.source.strip() or parsed.text
            raise MotionChainError(shown, f"refused by the safety envelope: {chained}")
        try:
            if state.joints is None and not parsed.is_homing:
                # Lines that do not move need no position; the others wait for one.
                try:
                    after = self._predict(parsed, state, what)
                except MirobotUsageError:
                    return NEED_POSITION
                return _line_check(after, False) if not self._moves else NEED_POSITION
            after = self._predict(parsed, state, what)
            check = _line_check(after, self._moves)
            self._verdicts = (check, after)
            return check
        except MirobotUsageError as err:
            self._stats.envelope_refusals += 1
            raise EnvelopeRefusedError(
                f"refused by the safety envelope: {err}; nothing was sent"
            ) from None

    def preview(self, lines: Sequence[ParsedLine]) -> list[LineCheck] | NeedPosition:
        """The verdicts on ``lines`` as if they were written one after another from the
        predicted state (nothing is tracked), or :data:`NEED_POSITION`. A refused line raises
        :class:`PathRefused` naming its index."""
        from mirobot_async._safety.prediction import Prediction, predict

        state = self._machine()
        if state.joints is None:
            return NEED_POSITION
        checks: list[LineCheck] = []
        for index, parsed in enumerate(lines):
            state = replace(state, work_offset=self._work_offset(parsed))
            result = predict(self.envelope, parsed, state, what=None)
            if not isinstance(result, Prediction):
                self._stats.envelope_refusals += 1
                raise PathRefused(
                    index, f"refused by the safety envelope: {result.error()}; nothing was sent"
                )
            state = result.state
            checks.append(_line_check(state, result.moves))
        return checks

    def adopt_status(self, report: StatusReport) -> None:
        """A status at rest with nothing in flight: where the arm is (unless predicted)."""
        if report.state in _QUIET:
            self._chain = self._chain.at_rest()
        state = self._state
        if state.joints is not None or report.state not in _QUIET:
            return
        modes = state.modes
        if modes.cartesian is None and report.motion_mode is not None:
            modes = replace(modes, cartesian=report.motion_mode == 1)
        self._state = replace(
            state, modes=modes, joints=report.joints, pose=report.pose, rail=report.rail
        )

    def adopt_settings(self, settings: Mapping[int, float]) -> None:
        """A ``$$`` listing: the soft limits, the 2021 base offset ``$41..$43``, gate lift
        ``$49`` and ``$35``."""
        soft = soft_limits_from_settings(settings)
        if soft is not None:
            self._soft_read = True
            self._state = replace(self._state, soft_limits=soft)
        if 35 in settings:
            self._state = replace(self._state, linear_g1=settings[35] != 0)
        offset = base_offset_from_settings(settings)
        if offset is not None:
            self._state = replace(self._state, base_offset=offset)
        if 49 in settings:
            self._state = replace(self._state, gate_lift=float(settings[49]))

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
        """Update the predicted state for a line just written."""
        before = self._state
        after: MachineState | None = None
        firmware = self._condition.firmware
        restarts = self._chain.problem(parsed, before.modes, firmware) is not None
        self._chain = self._chain.after(parsed, before.modes, firmware)
        fate = line_fate(parsed, before.modes, firmware)
        if fate.accepted is False:  # unchecked: the firmware will refuse it; nothing moves
            self._state = _after_refusal(before, fate.modes)
            self._last_line_id = line_id
            return Tracked(
                line_id, None, before, False, True, self.epoch, self._work.coordinate,
                parsed=parsed, refusal_expected=True,
            )  # fmt: skip
        if restarts:  # unchecked: the firmware restarts it from where the arm is (unknown)
            pass
        elif checked and verdict is not None:
            if self._verdicts is not None and self._verdicts[0] is verdict:
                after, self._moves = self._verdicts[1], verdict.moves
            else:
                after = self._follow(parsed, what)
        elif not checked:  # sent with check_envelope=False: follow it if the envelope can
            after = self._follow_unchecked(parsed, command, before, what, warn_unchecked)
        if after is not None:
            moved = self._moves
            self._state = after
        else:
            modes = update_modes(parsed, before.modes, firmware)
            self._state = replace(
                before, modes=modes, joints=None, pose=None, rail=None, parser=PARSER_UNKNOWN
            )
            self._forget_stored(parsed)
            moved = True
        coordinate = self._work.coordinate
        self._track_coordinates(parsed)
        self._last_line_id = line_id
        check = None if after is None else _line_check(after, moved)
        changed = self._state.modes != before.modes
        return Tracked(
            line_id, check, before, moved, changed, self.epoch, coordinate, parsed=parsed
        )

    def _track_coordinates(self, parsed: ParsedLine) -> None:
        """The work coordinate system in effect (``G54`` after homing, program end)."""
        if parsed.is_homing:  # the parser is re-initialised, then the startup lines run
            self._work.reinitialised(self._state.startup_lines, ran=True)
        self._work.follow(parsed)

    def _forget_stored(self, parsed: ParsedLine) -> None:
        """An unchecked line that may change what the firmware stores: read it again."""
        dollar = parsed.dollar
        if parsed.changes_base_offset:
            self._state = replace(self._state, base_offset=None)
        if parsed.changes_setting(49):
            self._state = replace(self._state, gate_lift=None)
        if dollar is not None and dollar.kind in ("restore", "unknown"):
            self._soft_read = False
            self._state = replace(self._state, linear_g1=None, soft_limits=None)
        if dollar is not None and dollar.kind in ("startup", "restore", "unknown"):
            self._state = replace(self._state, startup_lines=None)
        self._work.forget_after(parsed)

    def _follow(self, parsed: ParsedLine, what: str | None) -> MachineState | None:
        try:
            return self._predict(parsed, self._machine(), what)
        except MirobotUsageError:
            return None

    def _follow_unchecked(
        self,
        parsed: ParsedLine,
        command: str,
        before: MachineState,
        what: str | None,
        warn_unchecked: bool,
    ) -> MachineState | None:
        problem: str | None = None
        after: MachineState | None = None
        try:
            after = self._predict(parsed, self._machine(), what)
        except MirobotUsageError as err:
            problem = str(err)
        name = what or repr(command)
        if problem is not None and before.joints is not None:
            _log.warning(
                "%s was sent WITHOUT the safety envelope check (check_envelope=False); "
                "the envelope would have refused it: %s",
                name,
                problem,
            )
        elif problem is not None:  # the position is unknown: the envelope cannot follow
            (_log.warning if warn_unchecked else _log.debug)(
                "%s was sent WITHOUT the safety envelope check (check_envelope=False); "
                "the arm's position is unknown until a status is read: %s",
                name,
                problem,
            )
        else:
            (_log.warning if warn_unchecked else _log.debug)(
                "%s was sent WITHOUT the safety envelope check (check_envelope=False)", name
            )
        return after

    def line_failed(
        self,
        tracked: Tracked,
        *,
        rejected: bool,
        reason: RefusalReason | None = None,
        error: str | None = None,
    ) -> None:
        """A line was rejected (error: nothing of it ran but, on classic, its M20/M21) or its
        motion refused (modes ran); a rejection that was predicted was followed already.

        A refused move leaves the arm where it was, but not always the parser (oracle): locked,
        it moves the parser to the refused target (and so does an unreachable Cartesian
        target, for the commanded pose); a soft limit leaves it."""
        if rejected and tracked.refusal_expected:
            return
        if not tracked.moved and not (rejected and tracked.modes_changed):
            return
        before = tracked.state_before
        assert before is not None  # (the envelope's guard always predicts it)
        last = tracked.line_id == self._last_line_id and tracked.epoch == self.epoch
        if last and rejected:  # nothing was written after it: undo it
            modes = before.modes
            if tracked.parsed is not None:
                firmware = self._condition.firmware
                modes = modes_after_refusal(tracked.parsed, modes, firmware, error)
            self._state = before if modes == before.modes else _after_refusal(before, modes)
            self._work.coordinate = tracked.coordinate
        elif last:
            from mirobot_async._safety.prediction import state_after_refusal

            state = replace(self._state, joints=before.joints, pose=before.pose, rail=before.rail)
            self._state = state_after_refusal(state, before, tracked.check, reason)
        else:
            self._forget(MotionModes.unknown() if rejected else None)
            if not rejected:
                self._state = replace(self._state, parser=PARSER_UNKNOWN)
        self.epoch += 1

    def forget(self, why: str) -> None:
        """The arm may be elsewhere than predicted: ``why`` is ``"alarm"`` (modes kept),
        ``"reset"`` (power-on modes: GRBL re-initialises the parser, G21 included) or ``"lost"``
        (a lost reply: modes unknown)."""
        if why == "reset":
            # GRBL re-initialises the parser (G54, no G92), then the stored startup lines run:
            # on classic unless the reset ends in Alarm; on 2021 (Alarm after a reset) they may
            # not, so the modes they change are unknown.
            ran = None if self._condition.firmware != "classic" or self._condition.alarm else True
            lines = self._state.startup_lines
            self._work.reinitialised(lines, ran=ran is not False)
            self._forget(reset_modes(lines, ran=ran))
            self._state = replace(self._state, parser=None)
            self._chain = Chaining()
            return
        modes = {"lost": MotionModes.unknown()}.get(why)
        if why == "lost":
            self._chain = self._chain.moved_anything()
        self._forget(modes)
        self._state = replace(self._state, parser=PARSER_UNKNOWN)

    def _forget(self, modes: MotionModes | None) -> None:
        state = replace(self._state, joints=None, pose=None, rail=None)
        if modes is not None:
            state = replace(state, modes=modes)
        self._state = state
        self.epoch += 1

    def warn_stream_unchecked(self) -> None:
        """``stream(check_envelope=False)`` started."""
        _log.warning(
            "stream(check_envelope=False): its lines are sent WITHOUT the safety envelope "
            "check (each line the envelope would have refused is named below)"
        )


def _after_refusal(before: MachineState, modes: MotionModes) -> MachineState:
    """``before`` after a line the firmware refused that left ``modes``: the arm and the parser
    stay, but a classic M20/M21 that still acted re-read the arm's position and pose."""
    if modes.cartesian == before.modes.cartesian:
        return replace(before, modes=modes)
    return replace(before, modes=modes, pose=None, parser=None)


def _line_check(state: MachineState, moves: bool) -> LineCheck:
    return LineCheck(state.modes, moves, state.joints, state.pose, state.rail, state.base_offset)


def make_guard(
    envelope: Envelope | None, condition: RobotCondition, stats: ClientStats
) -> EnvelopeGuard | NullGuard:
    """The guard for ``envelope`` (a :class:`NullGuard` without one)."""
    if envelope is None:
        return NullGuard(condition)
    return EnvelopeGuard(envelope, condition, stats)
