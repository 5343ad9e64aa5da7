"""The client's side of the safety envelope: line checks and position prediction.

:class:`EnvelopeGuard` checks each line against the :class:`~mirobot_async.envelope.Envelope`
right before it is written, starting from the position and modal state predicted from every
line written before it, and keeps that prediction up to date (see the client's module docstring,
"Safety envelope", for the policy). :class:`NullGuard` is the same interface when there is no
envelope: every line passes and nothing is tracked. No I/O here: the line scheduler learns the
position (a status at rest) when :meth:`EnvelopeGuard.verdict` asks for it.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Final, Protocol

from mirobot_async.condition import RobotCondition
from mirobot_async.errors import MirobotUsageError
from mirobot_async.replies import State, StatusReport
from mirobot_async.wire import ClientStats

if TYPE_CHECKING:  # imported when an envelope is used (it needs numpy)
    from mirobot_async.envelope import Envelope, LineCheck, MotionModes

__all__ = [
    "NEED_POSITION",
    "EnvelopeGuard",
    "Guard",
    "NeedPosition",
    "NullGuard",
    "Tracked",
    "make_guard",
]

_log = logging.getLogger("mirobot_async.client")

_HOMING_RE: Final = re.compile(rb"^\$H[H0-7E]?$")
_QUIET: Final = frozenset({State.IDLE, State.ALARM, State.CHECK})


class NeedPosition:
    """The line moves the arm and no position is predicted: learn one first."""

    def __repr__(self) -> str:
        return "NEED_POSITION"


NEED_POSITION: Final = NeedPosition()


@dataclass(frozen=True, slots=True)
class _Position:
    """Where the arm is (or will be once every line written has run)."""

    joints: tuple[float, ...]
    pose: tuple[float, ...]
    rail: float | None


@dataclass(frozen=True, slots=True)
class Tracked:
    """What the prediction assumed when a line was written (to undo it if the line fails)."""

    line_id: int
    check: LineCheck | None  # the envelope's verdict on the line (its target), if it had one
    modes_before: MotionModes
    position_before: _Position | None
    moved: bool
    modes_changed: bool


class Guard(Protocol):
    """What the scheduler and the facade use (:class:`EnvelopeGuard` or :class:`NullGuard`)."""

    epoch: int

    @property
    def envelope(self) -> Envelope | None: ...

    def needs_firmware(self, data: bytes) -> bool: ...

    def verdict(self, data: bytes, what: str | None) -> LineCheck | NeedPosition | None: ...

    def adopt_status(self, report: StatusReport) -> None: ...

    def track_written(
        self,
        line_id: int,
        command: str,
        data: bytes,
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
    """No envelope: every line passes, nothing is predicted."""

    epoch = 0

    @property
    def envelope(self) -> Envelope | None:
        """``None``: there is no envelope."""
        return None

    def needs_firmware(self, data: bytes) -> bool:
        """Never: no kinematic model is needed."""
        return False

    def verdict(self, data: bytes, what: str | None) -> LineCheck | NeedPosition | None:
        """Nothing to check."""
        return None

    def adopt_status(self, report: StatusReport) -> None:
        """Nothing to predict."""

    def track_written(
        self,
        line_id: int,
        command: str,
        data: bytes,
        verdict: LineCheck | None,
        *,
        checked: bool,
        what: str | None,
        warn_unchecked: bool,
    ) -> Tracked | None:
        """Nothing to track."""
        return None

    def line_failed(self, tracked: Tracked, *, rejected: bool) -> None:
        """Nothing to undo."""

    def forget(self, why: str) -> None:
        """Nothing to forget."""

    def warn_stream_unchecked(self) -> None:
        """No envelope, nothing to warn about."""


class EnvelopeGuard:
    """Checks lines against ``envelope`` and predicts where they leave the arm."""

    def __init__(self, envelope: Envelope, condition: RobotCondition, stats: ClientStats) -> None:
        from mirobot_async.envelope import MotionModes

        self._envelope = envelope
        self._classic: Envelope | None = None  # the envelope with dh=DH_CLASSIC
        self._condition = condition
        self._stats = stats
        self._modes: MotionModes = MotionModes.unknown()
        self._position: _Position | None = None
        self.epoch = 0  # bumped when the prediction or the modes are invalidated
        self._last_line_id: int | None = None

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

    def needs_firmware(self, data: bytes) -> bool:
        """True when the firmware (the kinematic model) must be known before checking ``data``."""
        return self._condition.firmware is None and not data.startswith(b"$")

    def _check(self, data: bytes, position: _Position | None, what: str | None) -> LineCheck:
        return self.envelope.check_line(
            data,
            None if position is None else position.joints,
            None if position is None else position.pose,
            self._modes,
            current_rail=None if position is None else position.rail,
            what=what,
        )

    def verdict(self, data: bytes, what: str | None) -> LineCheck | NeedPosition | None:
        """The envelope's verdict on ``data`` from the predicted position, or
        :data:`NEED_POSITION`; raises :class:`MirobotUsageError` ("refused by the safety
        envelope ...; nothing was sent") for a line it refuses."""
        try:
            if self._position is None and not _HOMING_RE.match(data):
                # Lines that do not move need no position; the others wait for one.
                try:
                    verdict = self._check(data, None, what)
                except MirobotUsageError:
                    return NEED_POSITION
                return verdict if not verdict.moves else NEED_POSITION
            return self._check(data, self._position, what)
        except MirobotUsageError as err:
            self._stats.envelope_refusals += 1
            raise MirobotUsageError(
                f"refused by the safety envelope: {err}; nothing was sent"
            ) from None

    def adopt_status(self, report: StatusReport) -> None:
        """A status at rest with nothing in flight: where the arm is (unless predicted)."""
        if self._position is not None or report.state not in _QUIET:
            return
        self._position = _Position(report.joints, report.pose, report.rail)
        if self._modes.cartesian is None and report.motion_mode is not None:
            self._modes = replace(self._modes, cartesian=report.motion_mode == 1)

    def track_written(
        self,
        line_id: int,
        command: str,
        data: bytes,
        verdict: LineCheck | None,
        *,
        checked: bool,
        what: str | None,
        warn_unchecked: bool,
    ) -> Tracked | None:
        """Update the predicted position and modes for a line just written."""
        modes_before, position_before = self._modes, self._position
        if not checked:  # sent with check_envelope=False: follow it if the envelope can
            verdict = self._follow_unchecked(data, command, position_before, what, warn_unchecked)
        if verdict is not None:
            self._modes = verdict.modes
            moved = verdict.moves
            if moved:
                joints, pose = verdict.joints, verdict.pose
                self._position = (
                    None
                    if joints is None or pose is None
                    else _Position(joints, pose, verdict.rail)
                )
        else:
            from mirobot_async.envelope import update_modes

            self._modes = update_modes(data, modes_before)
            self._position = None
            moved = True
        self._last_line_id = line_id
        return Tracked(
            line_id, verdict, modes_before, position_before, moved, self._modes != modes_before
        )

    def _follow_unchecked(
        self,
        data: bytes,
        command: str,
        position: _Position | None,
        what: str | None,
        warn_unchecked: bool,
    ) -> LineCheck | None:
        problem: str | None = None
        verdict: LineCheck | None = None
        try:
            verdict = self._check(data, position, what)
        except MirobotUsageError as err:
            problem = str(err)
        name = what or repr(command)
        if problem is not None and position is not None:
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
        return verdict

    def line_failed(self, tracked: Tracked, *, rejected: bool) -> None:
        """A line was rejected (error: nothing of it ran) or its motion refused (modes ran)."""
        if not tracked.moved and not (rejected and tracked.modes_changed):
            return
        if tracked.line_id == self._last_line_id:  # nothing was written after it: undo it
            if rejected:
                self._modes = tracked.modes_before
            self._position = tracked.position_before
            self.epoch += 1
        else:
            from mirobot_async.envelope import MotionModes

            self._forget(MotionModes.unknown() if rejected else None)

    def forget(self, why: str) -> None:
        """The arm may be elsewhere than predicted: ``why`` is ``"alarm"`` (modes kept),
        ``"reset"`` (power-on modes) or ``"lost"`` (a lost reply: modes unknown)."""
        from mirobot_async.envelope import MotionModes

        modes = {"reset": MotionModes(), "lost": MotionModes.unknown()}.get(why)
        self._forget(modes)

    def _forget(self, modes: MotionModes | None) -> None:
        self._position = None
        if modes is not None:
            self._modes = modes
        self.epoch += 1

    def warn_stream_unchecked(self) -> None:
        """``stream(check_envelope=False)`` started."""
        _log.warning(
            "stream(check_envelope=False): its lines are sent WITHOUT the safety envelope "
            "check (each line the envelope would have refused is named below)"
        )


def make_guard(
    envelope: Envelope | None, condition: RobotCondition, stats: ClientStats
) -> EnvelopeGuard | NullGuard:
    """The guard for ``envelope`` (a :class:`NullGuard` without one)."""
    if envelope is None:
        return NullGuard()
    return EnvelopeGuard(envelope, condition, stats)
