"""The client's side of the safety envelope: line checks and position prediction.

:class:`EnvelopeGuard` checks each line against the :class:`~mirobot_async.envelope.Envelope`
right before it is written, starting from the machine state predicted from every line written
before it (:class:`~mirobot_async.prediction.MachineState`: modal words including the units,
position, the 2021 base offset ``$41..$43`` and gate lift ``$49``), and keeps that prediction up
to date. The check is default-deny (:func:`~mirobot_async.prediction.predict`): a line passes
only when its exact effect is predicted. What is unknown at connect stays unknown until a line
states it (``G21``, ``M20``...), a status at rest shows it (the position) or a settings listing
gives it (the base offset). :class:`NullGuard` is the same interface when there is no envelope:
every line passes and nothing is tracked. No I/O here: the line scheduler learns the position (a
status at rest) when :meth:`EnvelopeGuard.verdict` asks for it.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Final, Protocol

from mirobot_async.condition import RobotCondition
from mirobot_async.errors import MirobotUsageError, MotionChainError
from mirobot_async.line import ParsedLine
from mirobot_async.modal import Chaining, LineCheck, MotionModes, update_modes
from mirobot_async.replies import State, StatusReport
from mirobot_async.validation import ModalState
from mirobot_async.wire import ClientStats

if TYPE_CHECKING:  # imported when an envelope is used (it needs numpy)
    from mirobot_async.envelope import Envelope
    from mirobot_async.prediction import MachineState

__all__ = [
    "NEED_POSITION",
    "EnvelopeGuard",
    "Guard",
    "NeedPosition",
    "NullGuard",
    "PathRefused",
    "Tracked",
    "make_guard",
]

_log = logging.getLogger("mirobot_async.client")

_QUIET: Final = frozenset({State.IDLE, State.ALARM, State.CHECK})


class PathRefused(MirobotUsageError):
    """:meth:`EnvelopeGuard.preview` refused the line at :attr:`index`."""

    def __init__(self, index: int, message: str) -> None:
        super().__init__(message)
        self.index = index


class NeedPosition:
    """The line moves the arm and no position is predicted: learn one first."""

    def __repr__(self) -> str:
        return "NEED_POSITION"


NEED_POSITION: Final = NeedPosition()


@dataclass(frozen=True, slots=True)
class Tracked:
    """What the prediction assumed when a line was written (to undo it if the line fails)."""

    line_id: int
    check: LineCheck | None  # the envelope's verdict on the line (its target), if it had one
    state_before: MachineState  # the predicted machine state before the line
    moved: bool
    modes_changed: bool


class Guard(Protocol):
    """What the scheduler and the facade use (:class:`EnvelopeGuard` or :class:`NullGuard`)."""

    epoch: int
    chain: Chaining

    @property
    def envelope(self) -> Envelope | None: ...

    @property
    def modes(self) -> MotionModes: ...

    @property
    def wants_settings(self) -> bool: ...

    def modal_state(self) -> ModalState: ...

    def needs_firmware(self, parsed: ParsedLine) -> bool: ...

    def verdict(self, parsed: ParsedLine, what: str | None) -> LineCheck | NeedPosition | None: ...

    def preview(self, lines: Sequence[ParsedLine]) -> list[LineCheck] | NeedPosition: ...

    def adopt_status(self, report: StatusReport) -> None: ...

    def adopt_settings(self, settings: Mapping[int, float]) -> None: ...

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
    ) -> Tracked | None: ...

    def line_failed(self, tracked: Tracked, *, rejected: bool) -> None: ...

    def forget(self, why: str) -> None: ...

    def warn_stream_unchecked(self) -> None: ...


class NullGuard:
    """No envelope: every line passes, no position is predicted; only the modal words
    (``M20``/``M21``, ``G90``/``G91``) are followed, for the validation of raw lines."""

    epoch = 0

    def __init__(self) -> None:
        self._modes = MotionModes.unknown()
        self.chain = Chaining()
        """Which joints may still move, which the parser took from a mode word (every line)."""

    @property
    def envelope(self) -> Envelope | None:
        """``None``: there is no envelope."""
        return None

    @property
    def modes(self) -> MotionModes:
        """The modal words stated by the lines written since connect (``None``: unknown)."""
        return self._modes

    @property
    def wants_settings(self) -> bool:
        """Never: no settings are needed."""
        return False

    def modal_state(self) -> ModalState:
        """The modal words stated by the lines written since connect (unknown before)."""
        modes = self._modes
        return ModalState(modes.cartesian, modes.relative, modes.motion, self.chain)

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
        if report.state in _QUIET:
            self.chain = self.chain.at_rest()

    def adopt_settings(self, settings: Mapping[int, float]) -> None:
        """Nothing to predict."""

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
        """Follow the line's modal words and chaining; nothing else is tracked."""
        self.chain = self.chain.after(parsed, self._modes)
        if parsed.kind == "dollar" or parsed.codes:
            self._modes = update_modes(parsed, self._modes)
        return None

    def line_failed(self, tracked: Tracked, *, rejected: bool) -> None:
        """Nothing to undo."""

    def forget(self, why: str) -> None:
        """A reset restores the power-on modes; a lost reply makes them unknown."""
        if why == "reset":
            self._modes = MotionModes()
            self.chain = Chaining()
        elif why == "lost":
            self._modes = MotionModes.unknown()
            self.chain = self.chain.moved_anything()

    def warn_stream_unchecked(self) -> None:
        """No envelope, nothing to warn about."""


class EnvelopeGuard:
    """Checks lines against ``envelope`` and predicts where they leave the arm."""

    def __init__(self, envelope: Envelope, condition: RobotCondition, stats: ClientStats) -> None:
        from mirobot_async.prediction import MachineState

        self._envelope = envelope
        self._classic: Envelope | None = None  # the envelope with dh=DH_CLASSIC
        self._condition = condition
        self._stats = stats
        # Everything unknown at connect: the modes (units too), the position, the base offset.
        self._state: MachineState = MachineState(MotionModes.unknown())
        self._base_offset: tuple[float, float, float] | None = None  # learned from $$ (2021)
        self._gate_lift: float | None = None
        self.epoch = 0  # bumped when the prediction or the modes are invalidated
        self._last_line_id: int | None = None
        self._moves = False  # whether the last prediction moves the arm
        self._verdicts: tuple[LineCheck, MachineState] | None = None  # the last verdict's state
        self.chain = Chaining()
        """Which joints may still move, which the parser took from a mode word (every line)."""

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
    def wants_settings(self) -> bool:
        """True on a 2021 arm while the base offset ``$41..$43`` is unknown (a ``$$`` listing
        handed to :meth:`adopt_settings` gives it)."""
        return self._condition.firmware == "2021" and self._base_offset is None

    def modal_state(self) -> ModalState:
        """The modal words :mod:`~mirobot_async.validation` needs, as predicted (a new object)."""
        modes = self._state.modes
        return ModalState(modes.cartesian, modes.relative, modes.motion, self.chain)

    def needs_firmware(self, parsed: ParsedLine) -> bool:
        """True when the firmware (the kinematic model) or, for an absolute Cartesian line on a
        2021 arm, its base offset (a ``$$`` listing at rest) must be known before checking it."""
        if parsed.kind == "dollar":
            return False
        if self._condition.firmware is None:
            return True
        if not self.wants_settings or self._state.base_offset is not None:
            return False
        modes = self._state.modes
        cartesian = parsed.coordinate_mode == 20 or (
            parsed.coordinate_mode is None and modes.cartesian is not False
        )
        relative = parsed.distance == 91 or (parsed.distance is None and modes.relative is True)
        axes = parsed.axis_words
        return cartesian and not relative and any(k in axes for k in "XYZ")

    def _machine(self) -> MachineState:
        """The predicted state with what the firmware profile decides filled in."""
        firmware = self._condition.firmware
        state = self._state
        if firmware == "classic":  # no base offset, no gate moves
            return replace(state, base_offset=(0.0, 0.0, 0.0), gate_lift=None, firmware=firmware)
        if state.base_offset is None and self._base_offset is not None:
            state = replace(state, base_offset=self._base_offset)
        if state.gate_lift is None and self._gate_lift is not None:
            state = replace(state, gate_lift=self._gate_lift)
        return replace(state, firmware=firmware)

    def _predict(self, parsed: ParsedLine, state: MachineState, what: str | None) -> MachineState:
        """The state after ``parsed``; raises MirobotUsageError when the envelope refuses it."""
        from mirobot_async.prediction import Prediction, predict

        result = predict(self.envelope, parsed, state, what=what)
        if not isinstance(result, Prediction):
            raise result.error()
        self._moves = result.moves
        return result.state

    def verdict(self, parsed: ParsedLine, what: str | None) -> LineCheck | NeedPosition | None:
        """The envelope's verdict on ``parsed`` from the predicted state, or
        :data:`NEED_POSITION`; raises :class:`MirobotUsageError` ("refused by the safety
        envelope ...; nothing was sent") for a line it refuses."""
        state = self._machine()
        chained = self.chain.problem(parsed, state.modes, self._condition.firmware)
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
            raise MirobotUsageError(
                f"refused by the safety envelope: {err}; nothing was sent"
            ) from None

    def preview(self, lines: Sequence[ParsedLine]) -> list[LineCheck] | NeedPosition:
        """The verdicts on ``lines`` as if they were written one after another from the
        predicted state (nothing is tracked), or :data:`NEED_POSITION`. A refused line raises
        :class:`PathRefused` naming its index."""
        from mirobot_async.prediction import Prediction, predict

        state = self._machine()
        if state.joints is None:
            return NEED_POSITION
        checks: list[LineCheck] = []
        for index, parsed in enumerate(lines):
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
            self.chain = self.chain.at_rest()
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
        """A ``$$`` listing: the 2021 base offset ``$41..$43`` and gate lift ``$49``."""
        if all(n in settings for n in (41, 42, 43)):
            offset = (float(settings[41]), float(settings[42]), float(settings[43]))
            self._base_offset = offset
            self._state = replace(self._state, base_offset=offset)
        if 49 in settings:
            self._gate_lift = float(settings[49])
            self._state = replace(self._state, gate_lift=self._gate_lift)

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
        restarts = self.chain.problem(parsed, before.modes, firmware) is not None
        self.chain = self.chain.after(parsed, before.modes, firmware)
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
            modes = update_modes(parsed, before.modes)
            self._state = replace(before, modes=modes, joints=None, pose=None, rail=None)
            if _may_change_offset(parsed):
                self._state = replace(self._state, base_offset=None, gate_lift=None)
                self._base_offset = self._gate_lift = None
            moved = True
        self._last_line_id = line_id
        check = None if after is None else _line_check(after, moved)
        return Tracked(line_id, check, before, moved, self._state.modes != before.modes)

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

    def line_failed(self, tracked: Tracked, *, rejected: bool) -> None:
        """A line was rejected (error: nothing of it ran) or its motion refused (modes ran)."""
        if not tracked.moved and not (rejected and tracked.modes_changed):
            return
        before = tracked.state_before
        if tracked.line_id == self._last_line_id:  # nothing was written after it: undo it
            if rejected:
                self._state = before
            else:
                self._state = replace(
                    self._state, joints=before.joints, pose=before.pose, rail=before.rail
                )
            self.epoch += 1
        else:
            self._forget(MotionModes.unknown() if rejected else None)

    def forget(self, why: str) -> None:
        """The arm may be elsewhere than predicted: ``why`` is ``"alarm"`` (modes kept),
        ``"reset"`` (power-on modes: GRBL re-initialises the parser, G21 included) or ``"lost"``
        (a lost reply: modes unknown)."""
        modes = {"reset": MotionModes(), "lost": MotionModes.unknown()}.get(why)
        if why == "reset":
            self.chain = Chaining()
        elif why == "lost":
            self.chain = self.chain.moved_anything()
        self._forget(modes)

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


def _line_check(state: MachineState, moves: bool) -> LineCheck:
    return LineCheck(state.modes, moves, state.joints, state.pose, state.rail, state.base_offset)


def _may_change_offset(parsed: ParsedLine) -> bool:
    """An unchecked ``$`` line that may change the base offset or the gate lift."""
    dollar = parsed.dollar
    if dollar is None:
        return False
    if dollar.kind in ("restore", "unknown"):
        return True
    return dollar.kind == "setting" and dollar.number in (41, 42, 43, 49)


def make_guard(
    envelope: Envelope | None, condition: RobotCondition, stats: ClientStats
) -> EnvelopeGuard | NullGuard:
    """The guard for ``envelope`` (a :class:`NullGuard` without one)."""
    if envelope is None:
        return NullGuard()
    return EnvelopeGuard(envelope, condition, stats)
