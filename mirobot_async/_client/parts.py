r"""The parts of one client connection, wired together: the base of the :class:`Mirobot` facade.

:class:`ClientParts` builds the one-way chain of the client's parts (see ARCHITECTURE.md)::

    deadline -> wire -> condition -> poller -> guard -> scheduler -> completion / streaming
                                                               \-> router (events in)

and offers the facade's command mixins (:mod:`~mirobot_async._client.status_commands`,
:mod:`~mirobot_async._client.motion_commands`, :mod:`~mirobot_async._client.tool_commands`,
:mod:`~mirobot_async._client.setting_commands`) what they
share: sending one line and awaiting its reply, the firmware profile, the timing knobs.
"""

from __future__ import annotations

import asyncio
from os import PathLike
from typing import TYPE_CHECKING, Final

from mirobot_async._client.completion import MotionCompletion
from mirobot_async._client.condition import Firmware, HomingCycle, RobotCondition
from mirobot_async._client.deadline import deadline_after
from mirobot_async._client.guard import make_guard
from mirobot_async._client.poller import StatusPoller
from mirobot_async._client.router import EventRouter
from mirobot_async._client.scheduler import PLAIN, LineScheduler, SendRules
from mirobot_async._client.transport import Implementation
from mirobot_async._client.wire import ClientStats, Wire
from mirobot_async._core import gcode
from mirobot_async._core.line import ParsedLine
from mirobot_async._core.outgoing import OutgoingLine
from mirobot_async._core.replies import parse_setting_line
from mirobot_async.errors import (
    MirobotAlarmError,
    MirobotCommandError,
    MirobotConnectionError,
    MirobotUsageError,
)

if TYPE_CHECKING:  # imported when an envelope is used (it needs numpy)
    from mirobot_async._safety.envelope import Envelope

__all__ = [
    "CONNECT_TIMEOUT",
    "DEFAULT_TIMEOUT",
    "HOME_TIMEOUT",
    "MOVE_TIMEOUT",
    "RESET_TIMEOUT",
    "STATUS_TIMEOUT",
    "ClientParts",
    "default_reply_timeout",
]

# ---- documented defaults (seconds) --------------------------------------------------------

DEFAULT_TIMEOUT: Final = 30.0
"""Default ``timeout`` of calls that send one line and await its reply (``send``, ``set_*``...)."""
STATUS_TIMEOUT: Final = 2.0
"""Default ``timeout`` of :meth:`Mirobot.status`, and of the status requests of liveness checks."""
MOVE_TIMEOUT: Final = 120.0
"""Default ``timeout`` of moves (including ``wait=True`` completion) and of ``wait_idle``."""
HOME_TIMEOUT: Final = 180.0
"""Default ``timeout`` of :meth:`Mirobot.home` (a real ``$HH`` takes well over a minute)."""
RESET_TIMEOUT: Final = 10.0
"""Default ``timeout`` of :meth:`Mirobot.reset` (the banner after ``%``)."""
CONNECT_TIMEOUT: Final = 5.0
"""Default ``timeout`` of :meth:`Mirobot.connect` (opening the port and the first status)."""

_AT_REST: Final = SendRules(idle=True)
"""The ``$`` queries of the firmware profile: written with the arm at rest (``Not idle``)."""


def default_reply_timeout(parsed: ParsedLine) -> float:
    """The default ``timeout`` of a one-line call sending ``parsed`` (``send()``, the pump and
    valve commands): :data:`HOME_TIMEOUT` for a homing line (the reply comes when the switch
    search ends: 8-30 s); :data:`MOVE_TIMEOUT` plus its dwell for a line the firmware answers
    only once the queued motion has ended (``G4``, the PWM lines ``M3``/``M4``/``M5``, ``M2``/
    ``M30``; oracle: ``M3 S1000`` behind a 30-degree move at F1000 is answered 1.6 s later),
    as a ``wait=True`` move waits for the same; else :data:`DEFAULT_TIMEOUT`."""
    if parsed.is_homing:
        return HOME_TIMEOUT
    if parsed.dwell_seconds is not None:
        return MOVE_TIMEOUT + max(0.0, parsed.dwell_seconds)
    if parsed.program_end or any(code in (3, 4, 5) for code in parsed.m_codes):
        return MOVE_TIMEOUT
    return DEFAULT_TIMEOUT


class ClientParts:
    """The parts of one connection and what the command mixins share (not used alone)."""

    def __init__(
        self,
        *,
        firmware: Firmware | None = None,
        envelope: Envelope | None = None,
        implementation: Implementation = "fast",
        status_timeout: float = STATUS_TIMEOUT,
    ) -> None:
        if firmware not in (None, *gcode.FIRMWARE_PROFILES):
            raise MirobotUsageError(
                f"firmware={firmware!r} must be '2021', 'classic', '2024' or None"
            )
        if implementation not in ("fast", "original"):
            raise MirobotUsageError(
                f"implementation={implementation!r} must be 'fast' or 'original'"
            )
        if not status_timeout > 0:
            raise MirobotUsageError(f"status_timeout={status_timeout!r} must be > 0")
        if envelope is not None:
            from mirobot_async._safety.envelope import Envelope

            if not isinstance(envelope, Envelope):
                raise MirobotUsageError(
                    f"envelope={envelope!r} must be a mirobot_async.Envelope or None"
                )
        self._implementation: Implementation = implementation
        self._exclusive = True
        self.url: str | None = None
        self.stats = ClientStats()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._opened = False
        self._wire = Wire(self.stats)
        self._condition = RobotCondition(firmware)
        self._poller = StatusPoller(self._wire, self._condition)
        self._guard = make_guard(envelope, self._condition, self.stats)
        self._lines = LineScheduler(
            self._wire, self._condition, self._poller, self._guard, self._require_firmware
        )
        self._completion = MotionCompletion(self._poller, self._condition)
        self._router = EventRouter(
            self._wire, self._condition, self._poller, self._guard, self._lines, lambda: self.url
        )
        self.status_timeout = status_timeout

    def _record_to(self, record: str | PathLike[str] | None) -> None:
        """``connect(record=FILE)``: a tape of this connection, appended to ``FILE``."""
        if record is not None:  # imported only when recording
            from mirobot_async._tapes.recorder import record_arm

            self._wire.tap = record_arm(record, self._condition)

    # ---- timing knobs ----

    @property
    def status_timeout(self) -> float:
        """Bound of the status requests of liveness checks and completion polls (seconds)."""
        return self._lines.status_timeout

    @status_timeout.setter
    def status_timeout(self, value: float) -> None:
        self._lines.status_timeout = self._completion.status_timeout = value

    @property
    def homing(self) -> HomingCycle | None:
        """The homing line in flight (``$H``...: the robot answers no ``?`` until its switch
        search ends, at most ``homing.bound`` seconds after ``homing.started``), or ``None``."""
        return self._condition.homing

    @property
    def homing_bounds(self) -> dict[str, float]:
        """Seconds a homing line may go unanswered at the default homing rates: ``"$H"`` (also
        ``$H0``..``$H7``) and ``"$HH"`` (also ``$HE``); slower ``$24``/``$25`` stretch them. Past
        it a silent robot is taken for a dead link (see ARCHITECTURE.md, "Timeouts and
        liveness"). A mutable mapping: tests may lower it."""
        return self._condition.homing_bounds

    @property
    def liveness_interval(self) -> float:
        """Seconds without a reply after which a waiting call checks the robot with a ``?``."""
        return self._lines.liveness_interval

    @liveness_interval.setter
    def liveness_interval(self, value: float) -> None:
        self._lines.liveness_interval = value

    @property
    def reply_grace(self) -> float:
        """A line unanswered although a quiet robot answered a ``?`` sent this long after it
        is lost."""
        return self._lines.reply_grace

    @reply_grace.setter
    def reply_grace(self, value: float) -> None:
        self._lines.reply_grace = value

    @property
    def status_retry_interval(self) -> float:
        """Seconds after which an unanswered ``?`` is sent again (the robot may ignore one)."""
        return self._poller.retry_interval

    @status_retry_interval.setter
    def status_retry_interval(self, value: float) -> None:
        self._poller.retry_interval = value

    @property
    def status_min_gap(self) -> float:
        """Minimum seconds between two ``?`` (back-to-back polling for completion)."""
        return self._poller.min_gap

    @status_min_gap.setter
    def status_min_gap(self, value: float) -> None:
        self._poller.min_gap = value

    def _running_loop(self) -> asyncio.AbstractEventLoop:
        """The connection's loop (:class:`MirobotConnectionError` before ``connect``)."""
        if self._loop is None:
            raise MirobotConnectionError("not connected: use Mirobot.connect(url)")
        return self._loop

    # ---- one line ----

    async def _command(
        self,
        data: bytes | OutgoingLine,
        *,
        deadline: float | None,
        timeout: float | None,
        rules: SendRules = PLAIN,
    ) -> tuple[str, ...]:
        """Send one line and return its output; raise what its reply means (``rules``: see
        :meth:`LineScheduler.submit`). ``data`` is the caller's :class:`OutgoingLine` (its one
        parse), or the bytes of one made here."""
        line = data if isinstance(data, OutgoingLine) else OutgoingLine.of(data)
        slot = await self._lines.submit(line, deadline=deadline, timeout=timeout, rules=rules)
        return await self._lines.await_slot(slot, deadline, timeout)

    async def _command_within(self, data: bytes, timeout: float | None) -> tuple[str, ...]:
        """:meth:`_command` with a deadline ``timeout`` seconds from now (the one-line calls)."""
        deadline = deadline_after(self._running_loop(), timeout)
        return await self._command(data, deadline=deadline, timeout=timeout)

    # ---- the firmware profile ----

    async def _require_firmware(self, deadline: float | None, timeout: float | None) -> Firmware:
        """The firmware profile: known from a banner, else from ``$$`` sent when the robot is at
        rest (the firmware refuses ``$$`` while it moves: ``Not idle``)."""
        if self._condition.firmware is None or self._guard.wants_settings:
            await self._settings(deadline, timeout, idle=True)
        for query in self._guard.wanted_queries():  # what the firmware stores ($N, $#, $G)
            output: tuple[str, ...] | None
            try:
                output = await self._command(
                    query.encode("ascii"), deadline=deadline, timeout=timeout, rules=_AT_REST
                )
            except MirobotAlarmError:
                raise
            except MirobotCommandError:  # the firmware does not know it: it stays unknown
                output = None
            self._guard.adopt_query(query, output)
        if self._condition.firmware is None:  # pragma: no cover - _settings always decides
            raise MirobotConnectionError("could not determine the firmware profile")
        return self._condition.firmware

    async def detect_firmware(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> Firmware:
        """The firmware profile, from the last banner or else from ``$$`` (sent once, when the
        robot is at rest: it waits for the arm to stop moving).

        Raises :class:`MirobotTimeoutError` after ``timeout`` seconds. Cancellation is safe.
        """
        return await self._require_firmware(deadline_after(self._running_loop(), timeout), timeout)

    # ---- settings ----

    async def _settings(
        self, deadline: float | None, timeout: float | None, *, idle: bool = False
    ) -> dict[int, float]:
        output = await self._command(
            gcode.settings_dump(),
            deadline=deadline,
            timeout=timeout,
            rules=_AT_REST if idle else PLAIN,
        )
        values: dict[int, float] = {}
        for line in output:
            setting = parse_setting_line(line)
            if setting is not None:
                values[setting[0]] = setting[1]
        self._condition.learn_firmware_from_settings(values)
        self._guard.adopt_settings(values)
        return values
