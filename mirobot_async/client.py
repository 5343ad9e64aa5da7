"""The asyncio client for the WLKATA Mirobot: :class:`Mirobot`.

::

    async with Mirobot.connect("/dev/ttyUSB0") as arm:
        await arm.home()
        await arm.move_joints(j1=30, j2=10, speed=1500)
        print(await arm.status())

How it works
------------
Bytes from the serial link (:mod:`mirobot_async.transport`) go into the sans-IO state machine
(:mod:`mirobot_async.protocol`), whose events resolve asyncio futures. Every line a call sends is
**registered with the state machine before it is written**, with no ``await`` in between, so its
reply slot exists before the robot can answer. Lines are written in call order (one FIFO lock)
and only when they fit in the robot's 128-byte receive buffer (GRBL character counting), so the
planner never starves and no byte is ever lost to an overflow. ``$`` commands (settings, homing,
``$X``, ``$$``) are sent only when nothing else is in flight and nothing else is sent until they
are answered (GRBL's send-response rule for commands that are unsafe to stream).

Status: at most one ``?`` is outstanding; every caller that wants a status (``status()``,
``statuses()``, ``wait=True`` moves, liveness checks) shares it. A corrupted status line is
dropped, counted (:attr:`Mirobot.stats`) and asked again at once; a ``?`` that the robot ignores
is asked again after :attr:`Mirobot.status_retry_interval`.

Timeouts and liveness
---------------------
Every awaiting call takes ``timeout=`` (seconds, ``None`` = no limit) with a documented default
and raises :class:`~mirobot_async.errors.MirobotTimeoutError` naming what it waited for. No fixed
acknowledgement timeout is safe (``$H`` and ``G4`` are acknowledged when done, motion lines wait
while the planner is full), so liveness is judged from status replies: a call whose reply has not
come for :attr:`Mirobot.liveness_interval` seconds polls the status. No status reply within
``status_timeout`` -> ``MirobotTimeoutError("a status reply ...")``. A busy robot (``Run``,
``Home``, ``Hold``) is given until the call's own timeout. A quiet robot (``Idle``, ``Alarm``)
that leaves the oldest line unanswered although it was sent more than
:attr:`Mirobot.reply_grace` seconds before that status request has lost the reply: the line is
given up (``MirobotTimeoutError`` naming it) and the following replies keep their lines.

Cancellation
------------
Cancelling a call never desynchronises the link: a line already written keeps its slot in the
state machine, its reply is consumed and discarded when it comes, and other tasks' replies are
unaffected. A call cancelled before its line was written sends nothing.

Errors
------
``ok`` with a "dropped" text (locked axes, soft limit, unreachable pose, angle out of limit) ->
:class:`~mirobot_async.errors.MotionRefusedError`; an error line ->
:class:`~mirobot_async.errors.MirobotCommandError` (``Alarm lock`` ->
:class:`~mirobot_async.errors.MirobotAlarmError`). After ``ALARM: ...`` motion calls (and
``wait=True`` moves in progress) fail with ``MirobotAlarmError`` (before sending anything) until
the alarm is cleared by :meth:`Mirobot.unlock`, :meth:`Mirobot.home`,
:meth:`Mirobot.clear_alarm` (or a raw ``$X``/``$H``/``M50``) or :meth:`Mirobot.reset`. After
``ALARM: Hard limit`` the firmware processes nothing but ``%`` (not even ``?``): every pending
call fails with ``MirobotAlarmError`` and the client sends nothing at all until
:meth:`Mirobot.reset` (every call raises ``MirobotAlarmError`` at once). A reset banner fails
pending lines with :class:`~mirobot_async.errors.MirobotResetError`; nothing is resent. End of
file or an I/O error fails every pending call with
:class:`~mirobot_async.errors.MirobotLinkLostError`, and
every later call raises it too. Input is never drained or discarded to "resynchronise".

Safety envelope
---------------
``Mirobot.connect(url, envelope=Envelope(...))`` (:mod:`mirobot_async.envelope`) checks **every
line** before it is written, at the moment it would be written (under the send lock, so the
checks follow the order of the lines on the wire): structured moves (``move_joints``,
``move_pose``), raw :meth:`Mirobot.send` lines and every :meth:`Mirobot.stream` line are parsed
with :meth:`Envelope.check_line <mirobot_async.envelope.Envelope.check_line>` against the modal
state (:class:`~mirobot_async.envelope.MotionModes`, tracked over every line written) and the
predicted position. A violating line raises :class:`~mirobot_async.errors.MirobotUsageError`
naming the bound, and nothing of it is written (no line; at most a ``?`` to learn the position).

*Position policy.* The client predicts where the arm will be once every line written so far has
run: each checked line's target is the start of the next one, so pipelined lines (``wait=False``
moves, streams) chain, and relative moves are checked from there. It starts from the connect
probe's status (if the arm was at rest). The prediction is dropped when the arm may be elsewhere:
after a reset banner, an alarm, homing, a refused or rejected motion line (unless it was the last
line written: then the position before it is restored), a lost reply, and after a line sent with
``check_envelope=False`` that the envelope could not follow. A line that needs the position
while none is predicted waits until every line in flight is answered and a fresh status shows
the robot at rest (``Idle``/``Alarm``), and starts from that status (only ``?`` is written
meanwhile). If the prediction is dropped while a checked line waits for room in the buffer, the
line is checked again before it is written.

*Modes.* Unknown at connect (``MotionModes.unknown()``; ``M20``/``M21`` is taken from the first
status that shows ``Motion_MODE``), power-on defaults after a reset banner or homing, updated by
every line written (checked or not). Structured moves state all their modes; a raw line that
relies on an unknown mode is refused until a line states it.

*Firmware.* The envelope's kinematic model must be the arm's: when the firmware is (or, with an
envelope, is detected at connect with ``$$`` to be) ``classic`` and the envelope has the default
``dh=DH_2021``, the client uses it with ``dh=DH_CLASSIC`` (:attr:`Mirobot.envelope` shows the
one in use). Any other ``dh`` is used as given.

*Opt-out.* ``send(line, check_envelope=False)`` logs a WARNING naming the line (and, if the
envelope would have refused it, why); ``stream(lines, check_envelope=False)`` logs a WARNING when
it starts and one for each line the envelope would have refused. Limitation: lines written
after a line that the robot then refuses were checked assuming it ran (pipelining); a stream
stops at such a refusal. The stream's per-line WARNINGs need the position: after a line the
envelope could not follow, the following unchecked lines are only logged at DEBUG.

Wire log: the ``mirobot_async.wire`` logger (a child of ``mirobot_async``) logs every line sent
(``-> ...``) and received (``<- ...``) at DEBUG.
"""

from __future__ import annotations

import asyncio
import contextlib
import inspect
import logging
import math
import re
from collections import deque
from collections.abc import (
    AsyncGenerator,
    AsyncIterable,
    AsyncIterator,
    Callable,
    Generator,
    Iterable,
)
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Final, Literal

from mirobot_async import gcode
from mirobot_async.errors import (
    MirobotAlarmError,
    MirobotCommandError,
    MirobotConnectionError,
    MirobotError,
    MirobotLinkLostError,
    MirobotResetError,
    MirobotTimeoutError,
    MirobotUsageError,
    MotionRefusedError,
)
from mirobot_async.protocol import (
    AlarmRaised,
    BannerReceived,
    ConnectionClosed,
    Event,
    LineAcknowledged,
    LineRejected,
    MirobotConnection,
    PendingLine,
    ProtocolViolation,
    ResetDetected,
    StatusCorrupted,
    StatusReceived,
    UnsolicitedText,
)
from mirobot_async.replies import ReplyKind, State, StatusReport
from mirobot_async.transport import Implementation, SerialLink

if TYPE_CHECKING:  # imported when an envelope is used (it needs numpy)
    from mirobot_async.envelope import Envelope, LineCheck, MotionModes

__all__ = [
    "CONNECT_TIMEOUT",
    "DEFAULT_TIMEOUT",
    "HOME_TIMEOUT",
    "MOVE_TIMEOUT",
    "RESET_TIMEOUT",
    "STATUS_TIMEOUT",
    "ClientStats",
    "LineResult",
    "Mirobot",
    "Stream",
    "StreamResult",
]

_log = logging.getLogger("mirobot_async.client")
_wire = logging.getLogger("mirobot_async.wire")

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

# Completion tolerances for wait=True: the firmware prints 3 decimals and quantises angles to
# motor steps, so a reached target reads back within a few thousandths.
JOINT_TOLERANCE: Final = 0.01  # degrees (joints) and mm (rail)
POSITION_TOLERANCE: Final = 0.1  # mm (pose x, y, z)
ORIENTATION_TOLERANCE: Final = 0.1  # degrees (pose rx, ry, rz)

_BUSY: Final = frozenset({State.RUN, State.HOME, State.HOLD, State.DOOR})
_QUIET: Final = frozenset({State.IDLE, State.ALARM, State.CHECK})
# Alarms after which the firmware processes nothing but "%" (PROTOCOL.md 6.1; GRBL's critical
# alarms print "[Reset to continue]").
_RESET_ONLY_ALARMS: Final = ("hard limit", "soft limit")
_STATUS_ASKS_KEPT: Final = 8  # send times of unanswered "?" remembered (see Mirobot._on_status)
# Alarms printed by a reset that interrupts motion or homing; the banner follows.
_RESET_ALARMS: Final = ("abort during cycle", "homing fail")
# Raw lines whose success clears a remembered alarm: $X, $H, $HH, $H0..$H7, $HE, M50.
_UNLOCKING_RE: Final = re.compile(rb"^(?:\$X|\$H[H0-7E]?|M0*50)$")
_HOMING_RE: Final = re.compile(rb"^\$H[H0-7E]?$")
_DWELL_RE: Final = re.compile(rb"G0*4(?![0-9.])")
_P_WORD_RE: Final = re.compile(rb"P([+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+))")
_FORBIDDEN_RE: Final = re.compile(r"[\r\n?!~%]")
_VERSION_RE: Final = re.compile(r"Robot\s+(\d{8})(\S*)")
_SETTING_LINE_RE: Final = re.compile(r"^\$(\d+)\s*=\s*([+-]?(?:\d+\.?\d*|\.\d+))")

Firmware = Literal["2021", "classic"]


# ---- public data --------------------------------------------------------------------------------


@dataclass(slots=True)
class ClientStats:
    """Counters of one connection (for monitoring and tests); they only ever increase."""

    lines_sent: int = 0
    lines_acknowledged: int = 0  # "ok" (including refused motions)
    lines_rejected: int = 0  # error lines
    lines_refused: int = 0  # "ok" but the motion was dropped
    replies_discarded: int = 0  # replies to lines whose caller had given up (cancelled)
    replies_lost: int = 0  # lines given up because their reply never came
    status_requests: int = 0  # "?" written
    status_reports: int = 0  # well-formed status lines received
    status_corrupted: int = 0  # unparsable status lines (dropped, asked again)
    status_retries: int = 0  # "?" asked again because no reply came in time
    alarms: int = 0
    resets: int = 0  # banners seen (power-on, reset(), spontaneous)
    protocol_violations: int = 0  # stray "ok", overlong lines...
    bytes_sent: int = 0  # every byte written (lines and realtime bytes such as "?")
    bytes_received: int = 0
    envelope_refusals: int = 0  # lines refused by the safety envelope (nothing written)


@dataclass(frozen=True, slots=True)
class LineResult:
    """The outcome of one streamed line: ``number`` is its 1-based position in the input."""

    number: int
    line: str
    output: tuple[str, ...] = ()
    error: MirobotError | None = None

    @property
    def ok(self) -> bool:
        """True when the line was acknowledged and not refused."""
        return self.error is None


@dataclass(slots=True)
class StreamResult:
    """The outcome of :meth:`Mirobot.stream`.

    ``sent`` lines were written, ``acknowledged`` of them were answered ``ok`` (and not refused);
    ``errors`` lists the failed lines in order; ``stopped`` is True when the stream ended before
    its input did (first error without ``continue_on_error``, a reset, an alarm, a timeout).
    """

    sent: int = 0
    acknowledged: int = 0
    errors: list[LineResult] = field(default_factory=list)
    stopped: bool = False

    @property
    def ok(self) -> bool:
        """True when every input line was acknowledged without error."""
        return not self.errors and not self.stopped

    def raise_for_errors(self) -> None:
        """Raise the first line's error, if any."""
        for result in self.errors:
            if result.error is not None:
                raise result.error


# ---- internals ---------------------------------------------------------------------------------

_Outcome = LineAcknowledged | LineRejected | BaseException


@dataclass(frozen=True, slots=True)
class _Position:
    """Where the arm is (or will be once every line written has run), for the envelope."""

    joints: tuple[float, ...]
    pose: tuple[float, ...]
    rail: float | None


@dataclass(frozen=True, slots=True)
class _Tracked:
    """What the envelope's bookkeeping assumed when a line was written (to undo a failed line)."""

    modes_before: MotionModes
    position_before: _Position | None
    moved: bool
    modes_changed: bool


@dataclass(slots=True, eq=False)
class _Slot:
    """A line written to the robot and owed a reply; ``fut`` is cancelled if the caller leaves."""

    pending: PendingLine
    command: str
    fut: asyncio.Future[_Outcome]
    sent_at: float
    check: LineCheck | None = None  # the envelope's verdict on the line (its target)
    tracked: _Tracked | None = None
    # Called synchronously when the reply (or failure) is settled, before anything else runs.
    watch: Callable[[_Slot], None] | None = None


class _StreamStopped(Exception):
    """Raised by :meth:`Mirobot._submit` when a stream's ``should_stop`` says so: not written."""


@dataclass(slots=True, eq=False)
class _StatusWaiter:
    """Wants a status reply to a ``?`` written at or after ``not_before``."""

    fut: asyncio.Future[tuple[StatusReport, float] | BaseException]
    not_before: float


def _angle_diff(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@dataclass(frozen=True, slots=True)
class _Target:
    """Where a motion should end (``None`` entries are not checked)."""

    joints: tuple[float | None, ...] = (None,) * 6
    rail: float | None = None
    pose: tuple[float | None, ...] = (None,) * 6

    def reached(self, report: StatusReport) -> bool:
        for want, have in zip(self.joints, report.joints, strict=True):
            if want is not None and abs(want - have) > JOINT_TOLERANCE:
                return False
        if (
            self.rail is not None
            and report.rail is not None
            and abs(self.rail - report.rail) > JOINT_TOLERANCE
        ):
            return False
        for index, (want, have) in enumerate(zip(self.pose, report.pose, strict=True)):
            if want is None:
                continue
            if index < 3:
                if abs(want - have) > POSITION_TOLERANCE:
                    return False
            elif _angle_diff(want, have) > ORIENTATION_TOLERANCE:
                return False
        return True


def _dwell_seconds(line: bytes) -> float:
    """Seconds of a ``G4 P<s>`` dwell in ``line`` (0 when it is not a dwell)."""
    compact = line.upper().replace(b" ", b"").replace(b"\t", b"")
    if _DWELL_RE.search(compact) is None:
        return 0.0
    match = _P_WORD_RE.search(compact)
    if match is None:
        return 0.0
    try:
        return max(0.0, float(match.group(1)))
    except ValueError:  # pragma: no cover - the regex only matches numbers
        return 0.0


def _firmware_from_banner(lines: Iterable[str]) -> tuple[Firmware | None, str | None]:
    for line in lines:
        match = _VERSION_RE.search(line)
        if match is not None:
            date = match.group(1)
            version = date + match.group(2)
            return ("classic" if date < "20210000" else "2021"), version
    return None, None


def _check_timeout(timeout: float | None) -> None:
    """Raise :class:`MirobotUsageError` unless ``timeout`` is ``None`` or a number >= 0.

    Every public awaiting call checks its ``timeout`` before it writes anything.
    """
    if timeout is None:
        return
    if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not timeout >= 0:
        raise MirobotUsageError(f"timeout={timeout!r} must be a number >= 0 or None")


def _deadline(loop: asyncio.AbstractEventLoop, timeout: float | None) -> float | None:
    _check_timeout(timeout)
    if timeout is None:
        return None
    return loop.time() + timeout


class _Connector:
    """What :meth:`Mirobot.connect` returns: ``await`` it or use it with ``async with``."""

    def __init__(self, arm: Mirobot, url: str, timeout: float | None, probe: bool) -> None:
        self._arm = arm
        self._url = url
        self._timeout = timeout
        self._probe = probe

    def __await__(self) -> Generator[Any, None, Mirobot]:
        return self._arm._open(self._url, self._timeout, self._probe).__await__()

    async def __aenter__(self) -> Mirobot:
        return await self._arm._open(self._url, self._timeout, self._probe)

    async def __aexit__(self, *exc_info: object) -> None:
        await self._arm.close()


class Stream:
    """A pipelined stream of lines, returned by :meth:`Mirobot.stream`. Use it once, either way:

    * ``result = await arm.stream(lines)`` -> :class:`StreamResult` (``on_progress`` is called
      with each :class:`LineResult` in order); a ``Stream`` is awaitable but not a coroutine:
      to run it in a task use :meth:`run`, ``asyncio.create_task(arm.stream(lines).run())``;
    * ``async for result in arm.stream(lines): ...`` -> each :class:`LineResult` in order as it
      is acknowledged (close the iteration early with ``contextlib.aclosing`` to stop sending at
      once).
    """

    def __init__(
        self,
        arm: Mirobot,
        lines: Iterable[str | bytes] | AsyncIterable[str | bytes],
        on_progress: Callable[[LineResult], object] | None,
        continue_on_error: bool,
        timeout: float | None,
        check_envelope: bool = True,
    ) -> None:
        self._arm = arm
        self._lines = lines
        self._on_progress = on_progress
        self._continue = continue_on_error
        self._timeout = timeout
        self._check_envelope = check_envelope
        self._used = False
        self.result = StreamResult()
        """Filled in as the stream runs (also in the iterator form)."""

    def _take(self) -> AsyncGenerator[LineResult, None]:
        if self._used:
            raise MirobotUsageError("a Stream can be awaited or iterated only once")
        self._used = True
        return self._arm._stream_lines(
            self._lines, self._continue, self._timeout, self.result, self._check_envelope
        )

    def __aiter__(self) -> AsyncIterator[LineResult]:
        return self._take()

    def __await__(self) -> Generator[Any, None, StreamResult]:
        return self.run().__await__()

    async def run(self) -> StreamResult:
        """Run the stream to its end and return its :class:`StreamResult` (as ``await``).

        A coroutine, so it can be given to ``asyncio.create_task()`` or ``asyncio.gather()``.
        """
        results = self._take()
        async with contextlib.aclosing(results):
            async for line_result in results:
                if self._on_progress is not None:
                    maybe = self._on_progress(line_result)
                    if inspect.isawaitable(maybe):
                        await maybe
        return self.result


# ---- the client ---------------------------------------------------------------------------------


class Mirobot:
    """An asyncio connection to one Mirobot. Open it with :meth:`connect`.

    All methods may be called concurrently from many tasks; lines go out in call order and each
    call gets its own reply. Every awaiting method takes ``timeout=`` (seconds, ``None`` for no
    limit; defaults are the module's ``*_TIMEOUT`` constants) and raises
    :class:`MirobotTimeoutError` naming what it waited for. Unless its docstring says otherwise a
    method that sends a line behaves like :meth:`send` for errors and cancellation: a cancelled
    call's line keeps its slot and its reply is consumed and discarded. Timing knobs are instance
    attributes (class defaults below) that tests may lower.
    """

    liveness_interval: float = 1.0
    """Seconds without a reply after which a waiting call checks the robot with a status request."""
    reply_grace: float = 0.5
    """A line unanswered although a quiet robot answered a ``?`` sent this long after it: lost."""
    status_retry_interval: float = 0.25
    """Seconds after which an unanswered ``?`` is sent again (the robot may ignore one)."""
    status_min_gap: float = 0.002
    """Minimum seconds between two ``?`` (back-to-back polling for completion)."""

    def __init__(
        self,
        *,
        firmware: Firmware | None = None,
        envelope: Envelope | None = None,
        implementation: Implementation = "fast",
        status_timeout: float = STATUS_TIMEOUT,
    ) -> None:
        if firmware not in (None, "2021", "classic"):
            raise MirobotUsageError(f"firmware={firmware!r} must be '2021', 'classic' or None")
        if implementation not in ("fast", "original"):
            raise MirobotUsageError(
                f"implementation={implementation!r} must be 'fast' or 'original'"
            )
        if not status_timeout > 0:
            raise MirobotUsageError(f"status_timeout={status_timeout!r} must be > 0")
        if envelope is not None:
            from mirobot_async.envelope import Envelope, MotionModes

            if not isinstance(envelope, Envelope):
                raise MirobotUsageError(
                    f"envelope={envelope!r} must be a mirobot_async.Envelope or None"
                )
        self._firmware: Firmware | None = firmware
        self.firmware_version: str | None = None
        """The version printed in the last banner seen (``20191228_2``...), if any."""
        # safety envelope (see "Safety envelope" above); all None / unused without one
        self._envelope: Envelope | None = envelope
        self._envelope_classic: Envelope | None = None  # the envelope with dh=DH_CLASSIC
        self._modes: MotionModes | None = None if envelope is None else MotionModes.unknown()
        self._position: _Position | None = None  # predicted after every line written
        self._position_epoch = 0  # bumped when the prediction or the modes are invalidated
        self._last_line_id: int | None = None
        self._implementation: Implementation = implementation
        self._exclusive = True
        self.status_timeout = status_timeout
        self.url: str | None = None
        self.stats = ClientStats()
        self._conn = MirobotConnection()
        self._link: SerialLink | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._closing = False
        self._fatal: str | None = None
        self._opened = False
        # lines
        self._slots: dict[int, _Slot] = {}
        self._send_lock = asyncio.Lock()
        self._progress = asyncio.Event()
        self._barrier: int | None = None  # id of an in-flight "$" line (send-response)
        self._dwell_until = -math.inf
        # alarms and resets
        self._alarm: str | None = None
        self._alarm_epoch = 0
        self._needs_reset: str | None = None
        self._reset_epoch = 0
        self._resetting = 0  # reset() calls awaiting their banner: no line is written meanwhile
        self._banner_started = -math.inf
        self._banner_waiters: list[tuple[float, asyncio.Future[tuple[str, ...] | BaseException]]]
        self._banner_waiters = []
        self.banner: tuple[str, ...] | None = None
        """The lines of the last reset banner seen (power-on, :meth:`reset`, spontaneous)."""
        # status
        self._status_waiters: list[_StatusWaiter] = []
        # When each unanswered "?" was written, oldest first: a status line (even a corrupted
        # one) answers the oldest. Bounded: a "?" the robot ignored is dropped eventually.
        self._status_asks: deque[float] = deque(maxlen=_STATUS_ASKS_KEPT)
        self._status_last_ask = -math.inf
        self._status_timer: asyncio.TimerHandle | None = None
        self._last_status: StatusReport | None = None
        self._rx_log = bytearray()

    # ---- lifecycle ----

    @classmethod
    def connect(
        cls,
        url: str,
        *,
        firmware: Firmware | None = None,
        timeout: float | None = CONNECT_TIMEOUT,
        envelope: Envelope | None = None,
        implementation: Implementation = "fast",
        status_timeout: float = STATUS_TIMEOUT,
        probe: bool = True,
        exclusive: bool = True,
    ) -> _Connector:
        """Open ``url`` (device, pty path, ``socket://host:port``, ``loop://``) at 115200 8N1.

        Use as ``async with Mirobot.connect(url) as arm:`` (closed at the end of the block) or
        ``arm = await Mirobot.connect(url)`` (then call :meth:`close`).

        ``firmware`` (``"2021"`` / ``"classic"``) is detected from a reset banner or, when a call
        needs it (rail limits, settings checks), from ``$$``; pass it to skip detection.
        ``envelope`` is a workspace safety envelope (:class:`mirobot_async.Envelope`): every line
        that moves the arm is checked against it before anything is written (see the module
        docstring, "Safety envelope"); with an envelope and an unknown ``firmware`` the profile
        is detected at connect (``$$``), so that a classic arm gets ``DH_CLASSIC``.
        ``implementation`` picks pyserial-asyncio-fast (``"fast"``, default) or the original
        pyserial-asyncio. ``status_timeout`` bounds the status requests of liveness checks.

        ``exclusive`` (default) locks the device so that a second program (or client) opening
        it fails at once with :class:`MirobotConnectionError` instead of stealing replies.

        With ``probe`` (default) a status request proves that a Mirobot answers (and waits for a
        banner being printed, e.g. by an arm that resets when the port opens).
        Raises :class:`MirobotConnectionError` at once when the port cannot be opened (missing
        path, busy port) or when nothing answers the probe within ``timeout`` seconds.
        Cancellation closes the port.
        """
        arm = cls(
            firmware=firmware,
            envelope=envelope,
            implementation=implementation,
            status_timeout=status_timeout,
        )
        arm._exclusive = exclusive
        return _Connector(arm, url, timeout, probe)

    async def _open(self, url: str, timeout: float | None, probe: bool) -> Mirobot:
        if self._opened:
            raise MirobotUsageError("this Mirobot was already connected; create a new one")
        _check_timeout(timeout)
        self._opened = True
        self._loop = asyncio.get_running_loop()
        self.url = url
        self._link = await SerialLink.open(
            url,
            on_data=self._on_data,
            on_lost=self._on_lost,
            implementation=self._implementation,
            exclusive=self._exclusive,
            timeout=CONNECT_TIMEOUT if timeout is None else timeout,
        )
        try:
            if probe:
                await self._probe(timeout)
                if self._envelope is not None:
                    await self._prepare_envelope(timeout)
        except BaseException:
            await self.close()
            raise
        _log.debug("connected to %s", url)
        return self

    async def _probe(self, timeout: float | None) -> None:
        loop = self._running_loop()
        deadline = _deadline(loop, timeout)
        try:
            async with asyncio.timeout_at(deadline):
                await self._fetch_status(fresh=True, timeout=None)
                while self._conn.in_banner:
                    await self._progress.wait()
        except TimeoutError as err:
            raise MirobotConnectionError(
                f"{_url_text(self.url)} opened, but no Mirobot answered a status request within "
                f"{timeout:g} s"
            ) from err

    async def _prepare_envelope(self, timeout: float | None) -> None:
        """At connect: the firmware (the envelope's kinematic model) and the arm's position."""
        loop = self._running_loop()
        deadline = _deadline(loop, timeout)
        if self._firmware is None:
            await self._require_firmware(deadline, timeout)
        report = self._last_status
        if (
            report is not None
            and report.state in _QUIET
            and not self._conn.pending_count
            and self._position is None
        ):
            # The probe's status, asked with nothing in flight: where the arm is at rest.
            self._position = _Position(report.joints, report.pose, report.rail)
            if self._modes is not None and report.motion_mode is not None:
                self._modes = replace(self._modes, cartesian=report.motion_mode == 1)

    async def close(self) -> None:
        """Close the link; idempotent, never hangs.

        Pending calls fail with :class:`MirobotLinkLostError` ("closed"), as does every later
        call. Unsent output is discarded; the robot keeps running what it already received.
        """
        self._closing = True
        self._set_fatal("the connection was closed")
        if self._link is not None:
            await self._link.close()

    async def __aenter__(self) -> Mirobot:
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.close()

    @property
    def closed(self) -> bool:
        """True once the link was closed or lost."""
        return self._fatal is not None

    # ---- public state ----

    @property
    def firmware(self) -> Firmware | None:
        """``"2021"``, ``"classic"``, or ``None`` while not known (see :meth:`detect_firmware`)."""
        return self._firmware

    @property
    def last_status(self) -> StatusReport | None:
        """The most recent well-formed status report received (no I/O)."""
        return self._last_status

    @property
    def alarm(self) -> str | None:
        """The text of the alarm motion calls are failing with, or ``None``."""
        return self._alarm

    @property
    def needs_reset(self) -> bool:
        """True after an alarm that only a reset clears (``Hard limit``): nothing is sent."""
        return self._needs_reset is not None

    @property
    def corrupted_status_count(self) -> int:
        """Unparsable status lines received so far (dropped and asked again)."""
        return self.stats.status_corrupted

    @property
    def pending_count(self) -> int:
        """Lines written and not answered yet (including those of cancelled callers)."""
        return self._conn.pending_count

    @property
    def envelope(self) -> Envelope | None:
        """The workspace safety envelope every move is checked against, or ``None``.

        This is the envelope in use: the one given, with ``dh=DH_CLASSIC`` on a classic arm if
        it had the default ``DH_2021`` (see the module docstring).
        """
        return self._active_envelope()

    @property
    def bytes_in_flight(self) -> int:
        """Bytes of lines written and not answered yet (GRBL character counting, <= 128)."""
        return self._conn.bytes_in_flight

    @property
    def status_requests_outstanding(self) -> int:
        """``?`` written and not answered yet (as counted by the protocol state machine).

        Usually 0 or 1; more while an unanswered ``?`` is asked again after
        :attr:`status_retry_interval` (a ``?`` the robot ignored is never answered).
        """
        return self._conn.status_requests_outstanding

    @property
    def status_waiter_count(self) -> int:
        """Calls currently waiting for a status report (they share the outstanding ``?``)."""
        return sum(not waiter.fut.done() for waiter in self._status_waiters)

    @property
    def reply_slot_count(self) -> int:
        """Lines the client awaits a reply for (equals :attr:`pending_count` between events)."""
        return len(self._slots)

    # ---- received data ----

    def _running_loop(self) -> asyncio.AbstractEventLoop:
        if self._loop is None:
            raise MirobotConnectionError("not connected: use Mirobot.connect(url)")
        return self._loop

    def _on_data(self, data: bytes) -> None:
        self.stats.bytes_received += len(data)
        if _wire.isEnabledFor(logging.DEBUG):
            self._log_received(data)
        if self._fatal is not None:
            return
        try:
            self._conn.receive_data(data)
            for event in self._conn.events():
                self._dispatch(event)
        except Exception as exc:  # a bug here must not kill the transport silently
            _log.exception("internal error while handling received data")
            self._set_fatal(f"internal error while handling received data: {exc!r}")

    def _log_received(self, data: bytes) -> None:
        buf = self._rx_log
        buf += data
        *lines, rest = re.split(rb"\r\n|\r|\n", bytes(buf))
        buf[:] = rest[-1024:]
        for line in lines:
            if line.strip():
                _wire.debug("<- %s", line.decode("ascii", "replace"))

    def _on_lost(self, exc: BaseException | None) -> None:
        if self._closing:
            return
        detail = f": {exc}" if exc is not None else " (end of file)"
        self._set_fatal(f"the link to {_url_text(self.url)} was lost{detail}")

    def _dispatch(self, event: Event) -> None:
        if isinstance(event, LineAcknowledged | LineRejected):
            self._on_reply(event)
        elif isinstance(event, StatusReceived):
            self._on_status(event.report)
        elif isinstance(event, StatusCorrupted):
            self._on_status_corrupted(event)
        elif isinstance(event, AlarmRaised):
            self._on_alarm(event.text)
        elif isinstance(event, ResetDetected):
            self._on_reset(event)
        elif isinstance(event, BannerReceived):
            self._on_banner(event)
        elif isinstance(event, UnsolicitedText):
            _log.info("robot says: %s", event.text)
            if event.kind is ReplyKind.FEEDBACK and "reset to continue" in event.text.lower():
                self._needs_reset = self._needs_reset or (self._alarm or event.text)
        elif isinstance(event, ProtocolViolation):
            self.stats.protocol_violations += 1
            _log.warning("protocol violation: %s: %r", event.description, event.data)
        elif isinstance(event, ConnectionClosed):
            self._on_lost(None)

    def _on_reply(self, event: LineAcknowledged | LineRejected) -> None:
        stats = self.stats
        if isinstance(event, LineAcknowledged):
            stats.lines_acknowledged += 1
            if event.refusal is not None:
                stats.lines_refused += 1
        else:
            stats.lines_rejected += 1
        slot = self._slots.pop(event.line.id, None)
        if self._barrier == event.line.id:
            self._barrier = None
        if slot is not None and slot.tracked is not None:
            if isinstance(event, LineRejected):
                self._untrack_failed_line(slot, slot.tracked, rejected=True)
            elif event.refusal is not None:
                self._untrack_failed_line(slot, slot.tracked, rejected=False)
        if slot is not None:
            if slot.fut.done():
                stats.replies_discarded += 1
                _log.debug("discarding the reply to %r (its caller left)", slot.command)
            else:
                self._settle(slot, event)
        self._notify()

    @staticmethod
    def _settle(slot: _Slot, outcome: _Outcome) -> None:
        """Give ``slot`` its outcome and tell its watcher at once (no loop iteration between)."""
        slot.fut.set_result(outcome)
        if slot.watch is not None:
            slot.watch(slot)

    def _on_alarm(self, text: str) -> None:
        self.stats.alarms += 1
        self._alarm = text
        self._alarm_epoch += 1
        self._forget_position()  # an alarm may stop the arm anywhere
        _log.warning("robot alarm: %s", text)
        if text.strip().lower() not in _RESET_ONLY_ALARMS:
            # The firmware still answers lines (Alarm lock) or a banner follows (abort during
            # cycle, homing fail): pending lines get their replies or MirobotResetError.
            self._notify()
            return
        # Hard limit: the firmware processes nothing but "%", not even "?". Fail every pending
        # line and status request now; their slots stay, so late replies are still matched.
        self._needs_reset = text
        for slot in self._slots.values():
            if not slot.fut.done():
                self._settle(
                    slot, MirobotAlarmError(slot.command, text, output=("ALARM: " + text,))
                )
        for waiter in self._status_waiters:
            if not waiter.fut.done():
                waiter.fut.set_result(MirobotAlarmError(None, text))
        self._status_waiters.clear()
        self._notify()

    def _on_reset(self, event: ResetDetected) -> None:
        loop = self._running_loop()
        self.stats.resets += 1
        self._reset_epoch += 1
        self._banner_started = loop.time()
        self._barrier = None
        self._dwell_until = -math.inf
        if self._envelope is not None:  # power-on modes; the arm stopped wherever it was
            from mirobot_async.envelope import MotionModes

            self._forget_position(MotionModes())
        if event.failed:
            # Every caller still waiting gets MirobotResetError: say it loudly only if some
            # line has nobody left to tell.
            unseen = any(
                (slot := self._slots.get(p.id)) is None or slot.fut.done() for p in event.failed
            )
            (_log.warning if unseen else _log.info)(
                "the robot reset: %d pending line(s) were not run", len(event.failed)
            )
        for pending in event.failed:
            slot = self._slots.pop(pending.id, None)
            if slot is not None and not slot.fut.done():
                self._settle(slot, MirobotResetError(slot.command))
        # A "?" in flight may or may not be answered after a reset: its send time is kept until
        # the banner ends (see _on_banner); the retry timer asks again if no reply comes.
        self._notify()

    def _on_banner(self, event: BannerReceived) -> None:
        self.banner = event.lines
        firmware, version = _firmware_from_banner(event.lines)
        if version is not None:
            self.firmware_version = version
        if firmware is not None:
            if self._firmware is not None and self._firmware != firmware:
                _log.warning(
                    "firmware=%r was given but the banner says %r", self._firmware, firmware
                )
            else:
                self._firmware = firmware
        keep = []
        for asked_at, fut in self._banner_waiters:
            if fut.done():
                continue
            if asked_at <= self._banner_started:
                fut.set_result(event.lines)
            else:
                keep.append((asked_at, fut))
        self._banner_waiters = keep
        # A "?" written before or during the reset may never be answered: forget them all (a
        # late reply is then credited to none, so it satisfies no waiter asking for a fresh one).
        self._status_asks.clear()
        self._notify()
        self._pump_status()

    def _notify(self) -> None:
        """Wake every task waiting for progress (a reply, a reset, an alarm...)."""
        self._progress.set()
        self._progress = asyncio.Event()

    def _set_fatal(self, message: str) -> None:
        """The link is unusable: fail everything pending, once, and every later call."""
        if self._fatal is not None:
            return
        self._fatal = message
        # The waiting calls raise MirobotLinkLostError with this message (and so does every later
        # call): log it loudly only when no call is waiting to show it.
        told = (
            any(not slot.fut.done() for slot in self._slots.values())
            or any(not waiter.fut.done() for waiter in self._status_waiters)
            or any(not fut.done() for _, fut in self._banner_waiters)
        )
        (_log.debug if self._closing else _log.info if told else _log.warning)("%s", message)
        for slot in self._slots.values():
            if not slot.fut.done():
                self._settle(slot, MirobotLinkLostError(f"{message}; no reply to {slot.command!r}"))
        self._slots.clear()
        for waiter in self._status_waiters:
            if not waiter.fut.done():
                waiter.fut.set_result(MirobotLinkLostError(f"{message}; no status reply"))
        self._status_waiters.clear()
        for _, fut in self._banner_waiters:
            if not fut.done():
                fut.set_result(MirobotLinkLostError(f"{message}; no banner"))
        self._banner_waiters.clear()
        if self._status_timer is not None:
            self._status_timer.cancel()
            self._status_timer = None
        self._notify()
        if self._link is not None:
            self._link.abort()

    def _raise_if_closed(self) -> None:
        if self._fatal is not None:
            raise MirobotLinkLostError(self._fatal)
        if self._link is None:
            raise MirobotConnectionError("not connected: use Mirobot.connect(url)")

    def _check_sendable(self, command: str | None, *, motion: bool) -> None:
        self._raise_if_closed()
        if self._needs_reset is not None:
            raise MirobotAlarmError(
                command,
                f"{self._needs_reset} (nothing, not even a status request, is sent until reset())",
            )
        if motion and self._alarm is not None:
            raise MirobotAlarmError(command, self._alarm)

    # ---- status polling (one "?" outstanding, shared) ----

    def _on_status(self, report: StatusReport) -> None:
        self.stats.status_reports += 1
        self._last_status = report
        # Credited to the oldest "?" unanswered (a report nobody asked for: to none), so that
        # a waiter never gets a report older than itself.
        asked_at = self._status_asks.popleft() if self._status_asks else -math.inf
        keep: list[_StatusWaiter] = []
        for waiter in self._status_waiters:
            if waiter.fut.done():
                continue
            if waiter.not_before <= asked_at:
                waiter.fut.set_result((report, asked_at))
            else:
                keep.append(waiter)
        self._status_waiters = keep
        self._pump_status()

    def _on_status_corrupted(self, event: StatusCorrupted) -> None:
        self.stats.status_corrupted += 1
        _log.warning("dropped a corrupted status line (%s)", event.reason)
        if self._status_asks:  # the oldest "?" was answered, unreadably: ask again
            self._status_asks.popleft()
        self._pump_status()

    def _pump_status(self) -> None:
        """Write a ``?`` if someone waits for a status and none is outstanding (or it is late)."""
        if self._fatal is not None or self._link is None or self._needs_reset is not None:
            return
        if not any(not w.fut.done() for w in self._status_waiters):
            self._status_waiters.clear()
            if self._status_timer is not None:
                self._status_timer.cancel()
                self._status_timer = None
            return
        loop = self._running_loop()
        now = loop.time()
        if self._status_asks:
            due = self._status_last_ask + self.status_retry_interval
            if now < due:
                self._arm_status_timer(due)
                return
            self.stats.status_retries += 1
            _log.debug("no status reply after %.3f s; asking again", now - self._status_last_ask)
        else:
            due = self._status_last_ask + self.status_min_gap
            if now < due:
                self._arm_status_timer(due)
                return
        data = self._conn.request_status()
        self._link.write(data)
        self.stats.status_requests += 1
        self.stats.bytes_sent += len(data)
        if _wire.isEnabledFor(logging.DEBUG):
            _wire.debug("-> ?")
        self._status_asks.append(now)  # (the oldest is dropped beyond _STATUS_ASKS_KEPT)
        self._status_last_ask = now
        self._arm_status_timer(now + self.status_retry_interval)

    def _arm_status_timer(self, when: float) -> None:
        timer = self._status_timer
        if timer is not None:
            if timer.when() == when:
                return
            timer.cancel()
        self._status_timer = self._running_loop().call_at(when, self._on_status_timer)

    def _on_status_timer(self) -> None:
        self._status_timer = None
        self._pump_status()

    async def _fetch_status(
        self, *, fresh: bool, timeout: float | None, what: str = "a status report"
    ) -> tuple[StatusReport, float]:
        """The next status report (``fresh``: to a ``?`` written after this call started).

        Returns the report and the time its ``?`` was written.
        """
        _check_timeout(timeout)
        self._raise_if_closed()
        if self._needs_reset is not None:
            raise MirobotAlarmError(
                None,
                f"{self._needs_reset} (the robot answers nothing, not even '?', until reset())",
            )
        loop = self._running_loop()
        waiter = _StatusWaiter(loop.create_future(), loop.time() if fresh else -math.inf)
        self._status_waiters.append(waiter)
        self._pump_status()
        try:
            async with asyncio.timeout(timeout):
                result = await waiter.fut
        except TimeoutError as err:
            raise MirobotTimeoutError(what, timeout) from err
        finally:
            if not waiter.fut.done():
                waiter.fut.cancel()
        if isinstance(result, BaseException):
            raise result
        return result

    async def status(self, *, timeout: float | None = STATUS_TIMEOUT) -> StatusReport:
        """Send ``?`` (or join the one in flight) and return the next status report.

        A corrupted reply is dropped (counted in :attr:`corrupted_status_count`) and asked again;
        an ignored ``?`` is asked again after :attr:`status_retry_interval`, all within
        ``timeout`` seconds (default :data:`STATUS_TIMEOUT`), after which
        :class:`MirobotTimeoutError` ("a status report") is raised. Cancellation is safe.
        """
        report, _ = await self._fetch_status(fresh=False, timeout=timeout, what="a status report")
        return report

    async def statuses(
        self, interval: float = 0.1, *, timeout: float | None = STATUS_TIMEOUT
    ) -> AsyncGenerator[StatusReport, None]:
        """Yield a status report about every ``interval`` seconds, forever.

        Several consumers may iterate at once: their requests share the outstanding ``?``, and
        polling never disturbs lines in flight. Each report waits at most ``timeout`` seconds
        (:class:`MirobotTimeoutError`). Stop by breaking out of the loop (or cancelling the task);
        prefer ``async with contextlib.aclosing(arm.statuses()) as reports:`` to release it at
        once (it is an async generator, so ``aclosing`` type-checks).
        """
        if not interval >= 0:
            raise MirobotUsageError(f"interval={interval!r} must be >= 0")
        _check_timeout(timeout)
        loop = self._running_loop()
        next_time = loop.time()
        while True:
            report, _ = await self._fetch_status(fresh=False, timeout=timeout)
            yield report
            now = loop.time()
            next_time = max(next_time + interval, now)
            if next_time > now:
                await asyncio.sleep(next_time - now)

    # ---- sending lines ----

    def _encode_raw(self, line: str | bytes) -> bytes:
        if isinstance(line, bytes | bytearray):
            try:
                text = bytes(line).decode("ascii")
            except UnicodeDecodeError as err:
                raise MirobotUsageError(f"line={line!r} is not ASCII") from err
        elif isinstance(line, str):
            text = line
        else:
            raise MirobotUsageError(f"line={line!r} must be str or bytes")
        if not text.isascii():
            raise MirobotUsageError(f"line={text!r} is not ASCII")
        text = text.strip(" \t")
        if text.endswith("\r\n"):
            text = text[:-2]
        elif text.endswith("\n"):
            text = text[:-1]
        text = text.strip(" \t")
        bad = _FORBIDDEN_RE.search(text)
        if bad is not None:
            char = bad.group()
            if char in "\r\n":
                raise MirobotUsageError(f"line={text!r} contains a line break: send one line")
            hint = {
                "?": "use status()",
                "!": "use hold()",
                "~": "use resume()",
                "%": "use reset()",
            }[char]
            raise MirobotUsageError(
                f"line={text!r} contains the realtime byte {char!r}, which the firmware would "
                f"act on at once ({hint})"
            )
        data = text.encode("ascii")
        if len(data) + 1 > self._conn.rx_buffer_size:
            raise MirobotUsageError(
                f"line={text!r} is {len(data) + 1} bytes with its line end, more than the "
                f"robot's {self._conn.rx_buffer_size}-byte receive buffer"
            )
        return data

    def _ready_to_send(self, exclusive: bool, nbytes: int) -> bool:
        if self._resetting or self._conn.in_banner:
            return False
        if self._barrier is not None:
            if self._barrier in self._slots:
                return False
            self._barrier = None
        if exclusive:
            return self._conn.pending_count == 0
        return self._conn.fits(nbytes)

    async def _wait_progress(self, deadline: float | None) -> None:
        """Wait for any progress; after :attr:`liveness_interval` without any, check liveness."""
        event = self._progress
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(self.liveness_interval):
                await event.wait()
                return
        await self._check_liveness(deadline)

    async def _check_liveness(self, deadline: float | None) -> None:
        """Ask for a status; if the robot is quiet, give up on lines whose reply was lost."""
        loop = self._running_loop()
        timeout = self.status_timeout
        if deadline is not None:
            remaining = deadline - loop.time()
            if remaining <= 0:
                return  # the caller's own deadline decides
            timeout = min(timeout, remaining)
        report, asked_at = await self._fetch_status(
            fresh=True,
            timeout=timeout,
            what="a status reply (checking that the robot is alive while waiting for a reply)",
        )
        if report.state in _QUIET:
            self._expire_lost_replies(asked_at, report.state)

    def _expire_lost_replies(self, asked_at: float, state: State) -> None:
        if self._conn.in_banner or asked_at < self._dwell_until + self.reply_grace:
            return
        expired = False
        while self._conn.pending_count:
            oldest = self._conn.pending_lines[0]
            slot = self._slots.get(oldest.id)
            if slot is not None and asked_at - slot.sent_at < self.reply_grace:
                break
            self._conn.expire_oldest()
            self._slots.pop(oldest.id, None)
            if self._barrier == oldest.id:
                self._barrier = None
            self.stats.replies_lost += 1
            expired = True
            if self._envelope is not None:  # did it run? Unknown: forget position and modes
                from mirobot_async.envelope import MotionModes

                self._forget_position(MotionModes.unknown())
            command = oldest.line.decode("ascii", "replace")
            _log.warning(
                "no reply to %r although the robot is %s and answered a later status request: "
                "giving up on it",
                command,
                state.value,
            )
            if slot is not None and not slot.fut.done():
                elapsed = self._running_loop().time() - slot.sent_at
                self._settle(
                    slot,
                    MirobotTimeoutError(
                        f"the reply to {command!r} (lost: the robot is {state.value} and answered "
                        "a later status request)",
                        round(elapsed, 3),
                        command=command,
                    ),
                )
        if expired:
            self._notify()

    async def _submit(
        self,
        data: bytes,
        command: str,
        *,
        deadline: float | None,
        timeout: float | None,
        motion: bool,
        check_envelope: bool = True,
        what: str | None = None,
        warn_unchecked: bool = True,
        should_stop: Callable[[], bool] | None = None,
        watch: Callable[[_Slot], None] | None = None,
    ) -> _Slot:
        """Wait for this line's turn and for room in the receive buffer, then write it.

        ``should_stop`` (a stream's) is asked right before the write, with no await in between:
        if true, :class:`_StreamStopped` is raised and nothing is written. ``watch`` is set on the
        slot as the line is written (see :attr:`_Slot.watch`).

        With an envelope the line is checked (``check_envelope``) under the send lock, against
        the position and modes predicted from every line written before it, and checked again
        if they were invalidated while it waited; a violation raises MirobotUsageError and
        nothing of the line is written. ``what`` names the call in messages.
        """
        self._check_sendable(command, motion=motion)
        envelope_on = self._envelope is not None
        if envelope_on and self._firmware is None and not data.startswith(b"$"):
            await self._require_firmware(deadline, timeout)  # the envelope's kinematic model
        exclusive = data.startswith(b"$")
        nbytes = len(data) + 1
        epoch = self._reset_epoch
        verdict: LineCheck | None = None
        checked_epoch: int | None = None
        waiting_for = f"room in the robot's receive buffer to send {command!r}"
        try:
            async with asyncio.timeout_at(deadline), self._send_lock:
                while True:
                    self._check_sendable(command, motion=motion)
                    if self._reset_epoch != epoch:
                        raise MirobotResetError(
                            command, "the robot reset while it waited to be sent; not sent"
                        )
                    if should_stop is not None and should_stop():
                        raise _StreamStopped
                    if envelope_on and check_envelope and checked_epoch != self._position_epoch:
                        position_epoch = self._position_epoch
                        waiting_for = (
                            f"the arm to come to rest (its position, for the safety envelope) "
                            f"before sending {command!r}"
                        )
                        verdict = await self._envelope_check(data, command, what, deadline)
                        checked_epoch = position_epoch
                        waiting_for = f"room in the robot's receive buffer to send {command!r}"
                        continue  # re-check everything after the awaits
                    if self._ready_to_send(exclusive, nbytes):
                        if should_stop is not None and should_stop():
                            raise _StreamStopped  # a reply received meanwhile stopped it
                        slot = self._write_line(data, command, exclusive)
                        slot.watch = watch  # no reply can be dispatched before this
                        if envelope_on:
                            self._track_written(
                                slot,
                                data,
                                verdict if check_envelope else None,
                                what,
                                warn_unchecked,
                            )
                        return slot
                    await self._wait_progress(deadline)
        except TimeoutError as err:
            if isinstance(err, MirobotError):
                raise
            raise MirobotTimeoutError(waiting_for, timeout, command=command) from err

    # ---- the safety envelope ----

    def _active_envelope(self) -> Envelope | None:
        """The envelope in use: on a classic arm, the default ``DH_2021`` becomes ``DH_CLASSIC``."""
        envelope = self._envelope
        if envelope is None or self._firmware != "classic":
            return envelope
        from mirobot_async.kinematics import DH_2021, DH_CLASSIC

        if envelope.dh != DH_2021:
            return envelope
        if self._envelope_classic is None:
            self._envelope_classic = replace(envelope, dh=DH_CLASSIC)
        return self._envelope_classic

    def _forget_position(self, modes: MotionModes | None = None) -> None:
        """The arm may be elsewhere than predicted (and the modes may be ``modes``)."""
        if self._envelope is None:
            return
        self._position = None
        if modes is not None:
            self._modes = modes
        self._position_epoch += 1

    def _check_line(
        self,
        envelope: Envelope,
        data: bytes,
        position: _Position | None,
        what: str | None,
    ) -> LineCheck:
        from mirobot_async.envelope import MotionModes

        return envelope.check_line(
            data,
            None if position is None else position.joints,
            None if position is None else position.pose,
            self._modes or MotionModes.unknown(),
            current_rail=None if position is None else position.rail,
            what=what,
        )

    async def _envelope_check(
        self, data: bytes, command: str, what: str | None, deadline: float | None
    ) -> LineCheck:
        """Check ``data`` (called under the send lock); learn the position first if needed."""
        envelope = self._active_envelope()
        assert envelope is not None
        position = self._position
        try:
            if position is None and not _HOMING_RE.match(data):
                # Lines that do not move need no position; the others wait for one.
                try:
                    verdict = self._check_line(envelope, data, None, what)
                except MirobotUsageError:
                    pass
                else:
                    if not verdict.moves:
                        return verdict
                position = await self._learn_position(command, deadline)
            return self._check_line(envelope, data, position, what)
        except MirobotUsageError as err:
            self.stats.envelope_refusals += 1
            raise MirobotUsageError(
                f"refused by the safety envelope: {err}; nothing was sent"
            ) from None

    async def _learn_position(self, command: str, deadline: float | None) -> _Position:
        """Wait until nothing is in flight and a fresh status shows the arm at rest; use it."""
        loop = self._running_loop()
        while True:
            while self._conn.pending_count:
                await self._wait_progress(deadline)
                self._check_sendable(command, motion=False)
            timeout = self.status_timeout
            if deadline is not None:
                timeout = max(0.0, min(timeout, deadline - loop.time()))
            report, _ = await self._fetch_status(
                fresh=True,
                timeout=timeout,
                what=f"a status report (the arm's position for the safety envelope, {command!r})",
            )
            if self._conn.pending_count or self._conn.in_banner or report.state not in _QUIET:
                continue  # still moving (or a banner): poll again
            if self._position is not None:  # restored meanwhile (a failed last line)
                return self._position
            position = _Position(report.joints, report.pose, report.rail)
            self._position = position
            modes = self._modes
            if modes is not None and modes.cartesian is None and report.motion_mode is not None:
                self._modes = replace(modes, cartesian=report.motion_mode == 1)
            return position

    def _track_written(
        self,
        slot: _Slot,
        data: bytes,
        verdict: LineCheck | None,
        what: str | None,
        warn_unchecked: bool,
    ) -> None:
        """Update the predicted position and modes for a line just written."""
        envelope = self._active_envelope()
        assert envelope is not None and self._modes is not None
        modes_before, position_before = self._modes, self._position
        if verdict is None:  # sent with check_envelope=False: follow it if the envelope can
            problem: str | None = None
            try:
                verdict = self._check_line(envelope, data, position_before, what)
            except MirobotUsageError as err:
                problem = str(err)
            name = what or repr(slot.command)
            if problem is not None and position_before is not None:
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
        if verdict is not None:
            slot.check = verdict
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
        slot.tracked = _Tracked(modes_before, position_before, moved, self._modes != modes_before)
        self._last_line_id = slot.pending.id

    def _untrack_failed_line(self, slot: _Slot, tracked: _Tracked, *, rejected: bool) -> None:
        """A line was rejected (error: nothing of it ran) or its motion refused (modes ran)."""
        if not tracked.moved and not (rejected and tracked.modes_changed):
            return
        if slot.pending.id == self._last_line_id:  # nothing was written after it: undo it
            if rejected:
                self._modes = tracked.modes_before
            self._position = tracked.position_before
            self._position_epoch += 1
        else:
            from mirobot_async.envelope import MotionModes

            self._forget_position(MotionModes.unknown() if rejected else None)

    def _write_line(self, data: bytes, command: str, exclusive: bool) -> _Slot:
        """Register ``data`` with the state machine, then write it (synchronous: no gap)."""
        link = self._link
        assert link is not None
        loop = self._running_loop()
        pending = self._conn.send_line(data)
        now = loop.time()
        slot = _Slot(pending, command, loop.create_future(), now)
        self._slots[pending.id] = slot
        if exclusive:
            self._barrier = pending.id
        link.write(pending.wire)
        self.stats.lines_sent += 1
        self.stats.bytes_sent += len(pending.wire)
        if _wire.isEnabledFor(logging.DEBUG):
            _wire.debug("-> %s", command)
        dwell = _dwell_seconds(data) if b"4" in data else 0.0
        if dwell:
            self._dwell_until = max(self._dwell_until, now) + dwell
        return slot

    async def _await_slot(
        self, slot: _Slot, deadline: float | None, timeout: float | None
    ) -> tuple[str, ...]:
        """Wait for the reply of ``slot`` (liveness-checked); raise what it means."""
        loop = self._running_loop()
        fut = slot.fut
        try:
            while not fut.done():
                now = loop.time()
                if deadline is not None and now >= deadline:
                    raise MirobotTimeoutError(
                        f"the reply to {slot.command!r}", timeout, command=slot.command
                    )
                wait = self.liveness_interval
                if deadline is not None:
                    wait = min(wait, deadline - now)
                await asyncio.wait((fut,), timeout=wait)
                if fut.done() or (deadline is not None and loop.time() >= deadline):
                    continue
                try:
                    await self._check_liveness(deadline)
                except MirobotTimeoutError:
                    if fut.done() or (deadline is not None and loop.time() >= deadline):
                        continue
                    raise
        finally:
            if not fut.done():
                fut.cancel()  # the caller left: the reply will be consumed and discarded
        return self._outcome(slot)

    def _outcome(self, slot: _Slot) -> tuple[str, ...]:
        result = slot.fut.result()
        if isinstance(result, BaseException):
            raise result
        if isinstance(result, LineRejected):
            if "alarm lock" in result.text.lower():
                raise MirobotAlarmError(
                    slot.command, result.text, result.code, output=result.output
                )
            raise MirobotCommandError(slot.command, result.text, result.code, output=result.output)
        refusal = result.refusal
        if refusal is not None:
            raise MotionRefusedError(
                slot.command, refusal.text, refusal.reason, axis=refusal.axis, output=result.output
            )
        return result.output

    async def _command_within(self, data: bytes, timeout: float | None) -> tuple[str, ...]:
        """:meth:`_command` with a deadline ``timeout`` seconds from now (the one-line calls)."""
        return await self._command(
            data, deadline=_deadline(self._running_loop(), timeout), timeout=timeout
        )

    async def _command(
        self,
        data: bytes,
        *,
        deadline: float | None,
        timeout: float | None,
        motion: bool = False,
        check_envelope: bool = True,
        what: str | None = None,
    ) -> tuple[str, ...]:
        """Send one line and return its output; raise what its reply means."""
        if data.endswith(b"\n"):
            data = data[:-1]
        command = data.decode("ascii")
        slot = await self._submit(
            data,
            command,
            deadline=deadline,
            timeout=timeout,
            motion=motion,
            check_envelope=check_envelope,
            what=what,
        )
        output = await self._await_slot(slot, deadline, timeout)
        if _UNLOCKING_RE.match(data.upper().replace(b" ", b"")) and self._needs_reset is None:
            self._alarm = None
        return output

    async def send(
        self,
        line: str | bytes,
        *,
        check_envelope: bool = True,
        timeout: float | None = DEFAULT_TIMEOUT,
    ) -> tuple[str, ...]:
        """Send one raw line and return what the firmware printed for it (without the ``ok``).

        With a safety envelope the line is parsed and checked before it is written (a move that
        leaves the envelope, or that the envelope cannot judge, raises
        :class:`MirobotUsageError` and nothing is written); ``check_envelope=False`` sends it
        unchecked and logs a WARNING naming it.

        Raises :class:`MotionRefusedError` for "ok but dropped" motions,
        :class:`MirobotCommandError` for an error reply (:class:`MirobotAlarmError` for
        ``Alarm lock``), :class:`MirobotUsageError` for a line that is not one ASCII line or
        contains a realtime byte (nothing is sent), :class:`MirobotTimeoutError` when no reply
        comes within ``timeout`` seconds (default :data:`DEFAULT_TIMEOUT`) or the reply was lost.
        ``$`` commands wait until nothing else is in flight. Cancellation keeps the link in step:
        the reply is consumed and discarded.
        """
        data = self._encode_raw(line)
        loop = self._running_loop()
        deadline = _deadline(loop, timeout)
        return await self._command(
            data,
            deadline=deadline,
            timeout=timeout,
            check_envelope=check_envelope,
            what=f"send({data.decode('ascii')!r})",
        )

    # ---- streaming ----

    def stream(
        self,
        lines: Iterable[str | bytes] | AsyncIterable[str | bytes],
        *,
        on_progress: Callable[[LineResult], object] | None = None,
        continue_on_error: bool = False,
        check_envelope: bool = True,
        timeout: float | None = None,
    ) -> Stream:
        """Stream G-code lines with GRBL character counting (the planner never starves).

        ``lines`` is an iterable or async iterable of lines (blank lines are skipped; comments
        are sent, the firmware ignores them). Await the returned :class:`Stream` for a
        :class:`StreamResult` (``on_progress(LineResult)`` is called for each line in order; it
        may be a coroutine function), or iterate it for the :class:`LineResult` of each line.

        Stops sending at the first failed line (an error, a refusal, a bad line) unless
        ``continue_on_error``; always stops on a reset, an alarm or a lost reply. Lines already in
        the robot's buffer still run and are reported.

        With a safety envelope every line is checked just before it is written, starting where
        the lines before it leave the arm; a line that leaves the envelope (or that it cannot
        judge) is not written and the stream stops there, even with ``continue_on_error``: its
        :class:`LineResult` carries the :class:`MirobotUsageError` (``result.stopped`` is
        True). ``check_envelope=False`` sends every line unchecked and logs a WARNING when the
        stream starts and for each line the envelope would have refused.

        ``$`` lines are sent only when nothing else is in flight. ``timeout`` bounds the whole
        stream (``None``: no limit; each reply is liveness-checked). A lost link raises
        :class:`MirobotLinkLostError`. Cancelling stops sending; lines in flight are consumed and
        discarded.
        """
        return Stream(self, lines, on_progress, continue_on_error, timeout, check_envelope)

    async def _stream_lines(
        self,
        lines: Iterable[str | bytes] | AsyncIterable[str | bytes],
        continue_on_error: bool,
        timeout: float | None,
        result: StreamResult,
        check_envelope: bool = True,
    ) -> AsyncGenerator[LineResult, None]:
        """Producer task: submit lines as the buffer allows. This generator: await in order."""
        loop = self._running_loop()
        deadline = _deadline(loop, timeout)
        self._check_sendable(None, motion=False)
        if not check_envelope and self._envelope is not None:
            _log.warning(
                "stream(check_envelope=False): its lines are sent WITHOUT the safety envelope "
                "check (each line the envelope would have refused is named below)"
            )
        # (number, line, slot or the error that kept it from being sent); consumed from ``head``.
        queue: list[tuple[int, str, _Slot | MirobotError | None]] = []
        head = 0
        wake = asyncio.Event()
        flags = {"stop": False, "done": False, "exhausted": False}

        def should_stop() -> bool:
            return flags["stop"]

        def watch(slot: _Slot) -> None:
            # Runs as the reply is dispatched, before the producer can wake: a failing line
            # stops the stream at once, so nothing is written after its reply arrived.
            outcome = slot.fut.result()
            if isinstance(outcome, BaseException):
                flags["stop"] = True  # reset, alarm, lost reply, lost link: always fatal
            elif isinstance(outcome, LineRejected):
                if not continue_on_error or "alarm lock" in outcome.text.lower():
                    flags["stop"] = True
            elif outcome.refusal is not None and not continue_on_error:
                flags["stop"] = True

        async def produce() -> None:
            number = 0
            sync_items = iter(lines) if not isinstance(lines, AsyncIterable) else None
            async_items = aiter(lines) if isinstance(lines, AsyncIterable) else None
            try:
                while not flags["stop"]:
                    if async_items is not None:
                        item = await anext(async_items, _END)
                    else:
                        assert sync_items is not None
                        item = next(sync_items, _END)
                    if item is _END:
                        flags["exhausted"] = True
                        break
                    number += 1
                    assert isinstance(item, str | bytes)
                    try:
                        data = self._encode_raw(item)
                    except MirobotUsageError as err:
                        queue.append((number, _text(item), err))
                        wake.set()
                        if continue_on_error:
                            continue
                        break
                    if not data:
                        continue  # a blank line
                    command = data.decode("ascii")
                    try:
                        slot = await self._submit(
                            data,
                            command,
                            deadline=deadline,
                            timeout=timeout,
                            motion=False,
                            check_envelope=check_envelope,
                            what=f"stream line {number} {command!r}",
                            warn_unchecked=False,
                            should_stop=should_stop,
                            watch=watch,
                        )
                    except _StreamStopped:
                        break
                    except (MirobotResetError, MirobotAlarmError, MirobotTimeoutError) as err:
                        queue.append((number, command, err))
                        break
                    except MirobotUsageError as err:  # the safety envelope: stop before it
                        queue.append((number, command, err))
                        flags["stop"] = True
                        break
                    queue.append((number, command, slot))
                    result.sent += 1
                    wake.set()
            finally:
                flags["done"] = True
                wake.set()

        producer = loop.create_task(produce(), name="mirobot-stream-producer")
        try:
            while True:
                if head >= len(queue):
                    if flags["done"]:
                        break
                    wake.clear()
                    if head >= len(queue) and not flags["done"]:
                        await wake.wait()
                    continue
                number, command, item = queue[head]
                queue[head] = (number, command, None)  # drop the reference
                head += 1
                if head >= 4096:
                    del queue[:head]
                    head = 0
                if isinstance(item, MirobotError):
                    line_result = LineResult(number, command, (), item)
                else:
                    assert item is not None
                    try:
                        output = await self._await_slot(item, deadline, timeout)
                    except MirobotLinkLostError:
                        raise
                    except MirobotError as err:
                        line_result = LineResult(number, command, getattr(err, "output", ()), err)
                    else:
                        line_result = LineResult(number, command, output)
                if line_result.error is None:
                    result.acknowledged += 1
                else:
                    result.errors.append(line_result)
                    fatal = isinstance(
                        line_result.error,
                        MirobotResetError | MirobotAlarmError | MirobotTimeoutError,
                    )
                    if fatal or not continue_on_error:
                        flags["stop"] = True
                yield line_result
            if producer.done() and not producer.cancelled():
                error = producer.exception()
                if error is not None:
                    raise error  # a lost link while sending, or a failing input iterator
            result.stopped = flags["stop"] and not flags["exhausted"]
        finally:
            flags["stop"] = True
            if not producer.done():
                producer.cancel()
            await asyncio.wait((producer,))
            if not producer.cancelled():
                producer.exception()  # retrieved (raised above if it mattered)
            # Lines written but not awaited (the consumer left early): abandon their slots, so
            # their replies are consumed and discarded.
            for _, _, leftover in queue[head:]:
                if isinstance(leftover, _Slot) and not leftover.fut.done():
                    leftover.fut.cancel()

    # ---- motion ----

    async def _require_firmware(self, deadline: float | None, timeout: float | None) -> Firmware:
        if self._firmware is None:
            await self._settings(deadline, timeout)
        if self._firmware is None:  # pragma: no cover - _settings always decides
            raise MirobotConnectionError("could not determine the firmware profile")
        return self._firmware

    async def detect_firmware(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> Firmware:
        """The firmware profile, from the last banner or else from ``$$`` (sent once).

        Raises :class:`MirobotTimeoutError` after ``timeout`` seconds. Cancellation is safe.
        """
        loop = self._running_loop()
        return await self._require_firmware(_deadline(loop, timeout), timeout)

    async def _baseline(self, deadline: float | None) -> StatusReport | None:
        """A fresh status to compute a relative target from, if the arm is at rest."""
        if self._conn.pending_count:
            return None
        loop = self._running_loop()
        timeout = self.status_timeout
        if deadline is not None:
            timeout = max(0.0, min(timeout, deadline - loop.time()))
        report, _ = await self._fetch_status(fresh=True, timeout=timeout)
        if report.state not in _QUIET or self._conn.pending_count:
            return None
        return report

    async def _move(
        self,
        data: bytes,
        *,
        target: Callable[[StatusReport | None, LineCheck | None], _Target | None],
        relative: bool,
        wait: bool,
        deadline: float | None,
        timeout: float | None,
        what: str,
    ) -> StatusReport | None:
        """Send a motion line; with ``wait`` await its completion at ``target``.

        ``target(baseline, check)`` gives the goal; for relative moves from ``check`` (the
        envelope's verdict: the absolute target) or else ``baseline`` (a status read before
        sending while the arm was at rest), or ``None`` (completion = Idle after the ``ok``).
        """
        data = data.rstrip(b"\n")
        command = data.decode("ascii").strip()
        self._check_sendable(command, motion=True)
        use_baseline = wait and relative and self._envelope is None
        baseline = await self._baseline(deadline) if use_baseline else None
        epoch, alarm_epoch = self._reset_epoch, self._alarm_epoch
        slot = await self._submit(
            data,
            command,
            deadline=deadline,
            timeout=timeout,
            motion=True,
            what=f"{what} {command!r}",
        )
        await self._await_slot(slot, deadline, timeout)
        if not wait:
            return None
        known = not relative or baseline is not None or slot.check is not None
        goal = target(baseline, slot.check) if known else None
        return await self._wait_motion(
            command,
            goal,
            deadline=deadline,
            timeout=timeout,
            epoch=epoch,
            alarm_epoch=alarm_epoch,
        )

    async def _wait_motion(
        self,
        command: str,
        target: _Target | None,
        *,
        deadline: float | None,
        timeout: float | None,
        epoch: int,
        alarm_epoch: int,
        homing: bool = False,
    ) -> StatusReport:
        """Poll back-to-back until a status asked after the ``ok`` shows the motion done."""
        loop = self._running_loop()
        what = f"the robot to finish {command!r} (Idle at the target)"
        seen_busy = False
        while True:
            now = loop.time()
            if deadline is not None and now >= deadline:
                raise MirobotTimeoutError(what, timeout, command=command)
            status_timeout = self.status_timeout
            if deadline is not None:
                status_timeout = min(status_timeout, deadline - now)
            try:
                report, _ = await self._fetch_status(fresh=True, timeout=status_timeout)
            except MirobotTimeoutError as err:
                if deadline is not None and loop.time() >= deadline:
                    raise MirobotTimeoutError(what, timeout, command=command) from err
                raise
            except MirobotAlarmError as err:
                raise MirobotAlarmError(command, self._alarm or err.text) from err
            if self._reset_epoch != epoch:
                raise MirobotResetError(command, "the robot reset before the motion finished")
            if self._alarm_epoch != alarm_epoch or report.state is State.ALARM:
                alarm = self._alarm or "the robot is in Alarm"
                if alarm.strip().lower() in _RESET_ALARMS:
                    raise MirobotResetError(command, f"the motion was aborted: ALARM: {alarm}")
                raise MirobotAlarmError(command, alarm)
            if report.state in _BUSY:
                seen_busy = True
                continue
            if homing:
                if all(abs(j) <= JOINT_TOLERANCE for j in report.joints):
                    return report
                continue
            if target is None or seen_busy or target.reached(report):
                return report

    async def move_joints(
        self,
        j1: float | None = None,
        j2: float | None = None,
        j3: float | None = None,
        j4: float | None = None,
        j5: float | None = None,
        j6: float | None = None,
        rail: float | None = None,
        *,
        speed: float | None = None,
        relative: bool = False,
        wait: bool = True,
        timeout: float | None = MOVE_TIMEOUT,
    ) -> StatusReport | None:
        """Joint move (degrees; ``rail`` in mm); omitted joints stay where they are.

        ``speed`` in deg/min (``None``: every joint at its max rate, ``G0``). ``relative`` adds
        to the current angles. Absolute targets outside the joint (and rail) ranges raise
        :class:`MirobotUsageError` before anything is sent, and so does a move that leaves the
        safety envelope (target, or the tool point along the joint-space path from the
        predicted position; see the module docstring).

        With ``wait`` (default) returns the status report that shows the move finished: ``ok``
        received and a later status ``Idle`` at the target (within 0.01 deg), or ``Idle`` after
        the arm was seen moving; for relative moves the target is the envelope's predicted one,
        or without an envelope computed from a status read just before sending when the arm is
        at rest (else completion is ``Idle`` after the ``ok``). Without ``wait`` returns
        ``None`` once the line is queued (``ok``).

        Raises :class:`MotionRefusedError` (locked, soft limit...), :class:`MirobotAlarmError`
        (an alarm is remembered or raised meanwhile), :class:`MirobotResetError`,
        :class:`MirobotTimeoutError` after ``timeout`` seconds (default :data:`MOVE_TIMEOUT`).
        Cancelling keeps the link in step (as :meth:`send`) but does not stop the arm (use
        :meth:`hold` or :meth:`reset`).
        """
        values = (j1, j2, j3, j4, j5, j6)
        loop = self._running_loop()
        deadline = _deadline(loop, timeout)
        # Argument errors first (the rail range depends on the firmware: checked below).
        if rail is None or any(v is not None for v in values):
            gcode.move_joints(j1, j2, j3, j4, j5, j6, speed=speed, relative=relative)
        if rail is not None:
            gcode.move_joints(rail=rail, speed=speed, relative=True)  # a finite number
        firmware: str = self._firmware or "2021"
        if rail is not None and self._firmware is None and not relative:
            firmware = await self._require_firmware(deadline, timeout)
        data = gcode.move_joints(
            j1, j2, j3, j4, j5, j6, rail, speed=speed, relative=relative, firmware=firmware
        )

        def target(base: StatusReport | None, check: LineCheck | None) -> _Target:
            if not relative:
                return _Target(joints=values, rail=rail)
            if check is not None and check.joints is not None:
                joints = tuple(
                    None if v is None else q for v, q in zip(values, check.joints, strict=True)
                )
                return _Target(joints=joints, rail=None if rail is None else check.rail)
            assert base is not None
            joints = tuple(
                None if v is None else b + v for v, b in zip(values, base.joints, strict=True)
            )
            new_rail = None if rail is None or base.rail is None else base.rail + rail
            return _Target(joints=joints, rail=new_rail)

        return await self._move(
            data,
            target=target,
            relative=relative,
            wait=wait,
            deadline=deadline,
            timeout=timeout,
            what="move_joints",
        )

    async def move_pose(
        self,
        x: float | None = None,
        y: float | None = None,
        z: float | None = None,
        rx: float | None = None,
        ry: float | None = None,
        rz: float | None = None,
        *,
        speed: float | None = None,
        linear: bool = False,
        relative: bool = False,
        wait: bool = True,
        timeout: float | None = MOVE_TIMEOUT,
    ) -> StatusReport | None:
        """Cartesian move of the tool point (mm) and orientation (roll, pitch, yaw in degrees).

        ``linear=False``: point to point (``G0``); ``linear=True``: straight line (``G1``) at
        ``speed`` mm/min, which is then required. ``relative`` adds to the current pose
        (orientation component-wise, as the firmware does). Omitted coordinates stay. With a
        safety envelope the target (``G0``: and the joint-space path to it) or the sampled
        straight line is checked first: :class:`MirobotUsageError`, nothing sent.

        ``wait`` as in :meth:`move_joints` (the pose must read back within 0.1 mm / 0.1 deg).
        Unreachable targets raise :class:`MotionRefusedError` (``reason`` UNREACHABLE or
        ANGLE_OUT_OF_LIMIT); other errors and ``timeout`` (default :data:`MOVE_TIMEOUT`) as in
        :meth:`move_joints`.
        """
        values = (x, y, z, rx, ry, rz)
        loop = self._running_loop()
        deadline = _deadline(loop, timeout)
        data = gcode.move_pose(x, y, z, rx, ry, rz, speed=speed, linear=linear, relative=relative)

        def target(base: StatusReport | None, check: LineCheck | None) -> _Target:
            if not relative:
                return _Target(pose=values)
            if check is not None and check.pose is not None:
                pose = tuple(
                    None if v is None else p for v, p in zip(values, check.pose, strict=True)
                )
                return _Target(pose=pose)
            assert base is not None
            pose = tuple(
                None if v is None else b + v for v, b in zip(values, base.pose, strict=True)
            )
            return _Target(pose=pose)

        return await self._move(
            data,
            target=target,
            relative=relative,
            wait=wait,
            deadline=deadline,
            timeout=timeout,
            what="move_pose",
        )

    async def home(
        self, sequential: bool = False, *, timeout: float | None = HOME_TIMEOUT
    ) -> StatusReport:
        """Home the arm (``$H``; ``sequential=True``: ``$HH``, one axis after another).

        Returns when a status after the ``ok`` shows ``Idle`` with all joints at zero. Homing
        unlocks the axes and clears a remembered alarm. Raises :class:`MirobotTimeoutError`
        after ``timeout`` seconds (default :data:`HOME_TIMEOUT`), :class:`MirobotAlarmError` if
        homing fails, :class:`MirobotResetError` on a reset. Cancelling does not stop homing.
        """
        data = gcode.home(sequential)
        loop = self._running_loop()
        deadline = _deadline(loop, timeout)
        self._check_sendable("$HH" if sequential else "$H", motion=False)
        epoch, alarm_epoch = self._reset_epoch, self._alarm_epoch
        await self._command(data, deadline=deadline, timeout=timeout)
        return await self._wait_motion(
            data.decode("ascii").strip(),
            None,
            deadline=deadline,
            timeout=timeout,
            epoch=epoch,
            alarm_epoch=alarm_epoch,
            homing=True,
        )

    async def unlock(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Release the axis lock without homing: ``$X`` (leave Alarm), then ``M50`` (unlock).

        Clears a remembered alarm (not a hard limit: that needs :meth:`reset`). Errors and
        cancellation as in :meth:`send`; ``timeout`` (default :data:`DEFAULT_TIMEOUT`) covers both
        lines.
        """
        loop = self._running_loop()
        deadline = _deadline(loop, timeout)
        self._check_sendable("$X", motion=False)
        await self._command(gcode.clear_alarm(), deadline=deadline, timeout=timeout)
        await self._command(gcode.unlock_axes(), deadline=deadline, timeout=timeout)

    async def clear_alarm(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """``$X``: leave Alarm (the power-on axis lock stays: see :meth:`unlock`).

        Clears a remembered alarm (not a hard limit). Errors, ``timeout`` (default
        :data:`DEFAULT_TIMEOUT`) and cancellation as in :meth:`send`.
        """
        loop = self._running_loop()
        await self._command(gcode.clear_alarm(), deadline=_deadline(loop, timeout), timeout=timeout)

    async def wait_idle(self, *, timeout: float | None = MOVE_TIMEOUT) -> StatusReport:
        """Wait until every line sent before this call is answered and the robot is ``Idle``.

        Polls back-to-back, so it returns within milliseconds of the robot becoming idle.
        Raises :class:`MirobotAlarmError` if the robot is (or goes) into Alarm,
        :class:`MirobotTimeoutError` after ``timeout`` seconds (default :data:`MOVE_TIMEOUT`).
        Cancellation is safe.
        """
        loop = self._running_loop()
        deadline = _deadline(loop, timeout)
        # After a hard limit nothing is answered until reset(): fail at once, not after a
        # liveness check (the lost lines' slots stay registered to match late replies).
        self._check_sendable(None, motion=False)
        waiting_for = set(self._slots)
        what = "the robot to be Idle"
        try:
            async with asyncio.timeout_at(deadline):
                while waiting_for & self._slots.keys():
                    await self._wait_progress(deadline)
                    self._check_sendable(None, motion=False)
                while True:
                    report, _ = await self._fetch_status(fresh=True, timeout=None)
                    if report.state is State.ALARM:
                        raise MirobotAlarmError(None, self._alarm or "the robot is in Alarm")
                    if report.state in _QUIET:
                        return report
        except TimeoutError as err:
            if isinstance(err, MirobotError):
                raise
            raise MirobotTimeoutError(what, timeout) from err

    async def hold(self, *, timeout: float | None = STATUS_TIMEOUT) -> StatusReport:
        """Feed hold (``!``): decelerate to a stop; returns the first status no longer ``Run``.

        ``!`` is a realtime byte: it acts at once, ahead of queued lines. Not sent after a hard
        limit (the arm is already stopped; :meth:`reset` first). Raises
        :class:`MirobotTimeoutError` after ``timeout`` seconds (default :data:`STATUS_TIMEOUT`).
        Cancelling only stops waiting: the hold was already sent.
        """
        loop = self._running_loop()
        deadline = _deadline(loop, timeout)
        self._check_sendable("!", motion=False)
        self._write_realtime(self._conn.feed_hold())
        try:
            async with asyncio.timeout_at(deadline):
                while True:
                    report, _ = await self._fetch_status(fresh=True, timeout=None)
                    if report.state is not State.RUN:
                        return report
        except TimeoutError as err:
            if isinstance(err, MirobotError):
                raise
            raise MirobotTimeoutError("the robot to stop (Hold)", timeout, command="!") from err

    async def resume(self, *, timeout: float | None = STATUS_TIMEOUT) -> StatusReport:
        """Cycle start (``~``): resume after :meth:`hold`; returns the next status report.

        Raises :class:`MirobotTimeoutError` after ``timeout`` seconds (default
        :data:`STATUS_TIMEOUT`) without a status. Cancelling only stops waiting for the status.
        """
        _check_timeout(timeout)
        self._check_sendable("~", motion=False)
        self._write_realtime(self._conn.cycle_start())
        report, _ = await self._fetch_status(
            fresh=True, timeout=timeout, what="a status report after resuming"
        )
        return report

    def _write_realtime(self, data: bytes) -> None:
        link = self._link
        assert link is not None
        link.write(data)
        self.stats.bytes_sent += len(data)
        if _wire.isEnabledFor(logging.DEBUG):
            _wire.debug("-> %s", data.decode("ascii"))

    async def reset(self, *, timeout: float | None = RESET_TIMEOUT) -> tuple[str, ...]:
        """Soft reset (``%``): stop at once, clear the robot's buffers, await its banner.

        Sent immediately, ahead of queued lines. Pending lines fail with
        :class:`MirobotResetError` (they are not resent), lines of other calls still waiting for
        their turn fail the same way, and no line is written until the banner has ended. Clears
        the hard-limit lock and remembered alarms (an alarm the reset itself causes, such as
        ``Abort during cycle``, stays). The axes are locked again afterwards: :meth:`home` or
        :meth:`unlock`. Returns the banner lines. Raises :class:`MirobotTimeoutError` when no
        banner comes within ``timeout`` seconds (default :data:`RESET_TIMEOUT`). Cancelling only
        stops waiting: the ``%`` was sent, and lines written before its banner arrives fail with
        :class:`MirobotResetError`.
        """
        _check_timeout(timeout)
        self._raise_if_closed()
        loop = self._running_loop()
        asked_at = loop.time()
        fut: asyncio.Future[tuple[str, ...] | BaseException] = loop.create_future()
        entry = (asked_at, fut)
        self._banner_waiters.append(entry)
        alarm_epoch = self._alarm_epoch
        self._resetting += 1
        try:
            self._write_realtime(self._conn.request_reset())
            async with asyncio.timeout(timeout):
                result = await fut
        except TimeoutError as err:
            raise MirobotTimeoutError("the banner after a reset", timeout, command="%") from err
        finally:
            self._resetting -= 1
            if not fut.done():
                fut.cancel()
            with contextlib.suppress(ValueError):
                self._banner_waiters.remove(entry)
            self._notify()
        if isinstance(result, BaseException):
            raise result
        self._needs_reset = None
        if self._alarm_epoch == alarm_epoch:
            self._alarm = None
        return result

    # ---- outputs ----

    async def set_pump(self, pwm: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """``M3 S<pwm>``: PWM output 1 (pump: 0 off, 500 blow, 1000 suck; servo gripper).

        Errors, ``timeout`` (default :data:`DEFAULT_TIMEOUT`) and cancellation as in :meth:`send`.
        """
        data = gcode.set_pump(pwm)
        await self._command_within(data, timeout)

    async def set_valve(self, pwm: int, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """``M4 E<pwm>``: PWM output 2 (valve, or the V1.1 gripper). As :meth:`set_pump`."""
        data = gcode.set_valve(pwm)
        await self._command_within(data, timeout)

    async def suction_on(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Suction cup: pump sucking (``M3 S1000``). As :meth:`set_pump`."""
        await self.set_pump(gcode.PUMP_SUCK, timeout=timeout)

    async def blow(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Suction cup: pump blowing, to release a part (``M3 S500``). As :meth:`set_pump`."""
        await self.set_pump(gcode.PUMP_BLOW, timeout=timeout)

    async def pump_off(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Pump off (``M3 S0``). As :meth:`set_pump`."""
        await self.set_pump(gcode.PUMP_OFF, timeout=timeout)

    async def gripper_open(
        self, *, legacy: bool = False, timeout: float | None = DEFAULT_TIMEOUT
    ) -> None:
        """Open the servo gripper (``M3 S40``; ``legacy=True``: the V1.1 gripper, ``M4 E65``).

        As :meth:`set_pump`."""
        data = gcode.set_gripper(False, legacy=legacy)
        await self._command_within(data, timeout)

    async def gripper_close(
        self, *, legacy: bool = False, timeout: float | None = DEFAULT_TIMEOUT
    ) -> None:
        """Close the servo gripper (``M3 S60``; ``legacy=True``: ``M4 E40``).

        As :meth:`set_pump`."""
        data = gcode.set_gripper(True, legacy=legacy)
        await self._command_within(data, timeout)

    # ---- settings ----

    async def set_soft_limits(self, on: bool, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """``$20=1|0``: refuse (on) or allow joint targets outside the soft limits.

        Sent when nothing else is in flight; errors, ``timeout`` and cancellation as in
        :meth:`send`.
        """
        data = gcode.set_soft_limits(on)
        await self._command_within(data, timeout)

    async def set_hard_limits(self, on: bool, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """``$21=1|0``: stop with ``ALARM: Hard limit`` when a J1..J3 switch trips (on).

        Sent when nothing else is in flight; errors, ``timeout`` and cancellation as in
        :meth:`send`.
        """
        data = gcode.set_hard_limits(on)
        await self._command_within(data, timeout)

    async def _settings(self, deadline: float | None, timeout: float | None) -> dict[int, float]:
        output = await self._command(gcode.settings_dump(), deadline=deadline, timeout=timeout)
        values: dict[int, float] = {}
        for line in output:
            match = _SETTING_LINE_RE.match(line.strip())
            if match is not None:
                values[int(match.group(1))] = float(match.group(2))
        if self._firmware is None and values:
            self._firmware = "2021" if 29 in values else "classic"
        return values

    async def settings(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> dict[int, float]:
        """``$$``: every setting as ``{number: value}`` (also decides :attr:`firmware`).

        Sent when nothing else is in flight. Errors, ``timeout`` (default :data:`DEFAULT_TIMEOUT`)
        and cancellation as in :meth:`send`.
        """
        return await self._settings(_deadline(self._running_loop(), timeout), timeout)

    async def set_setting(
        self, number: int, value: float, *, timeout: float | None = DEFAULT_TIMEOUT
    ) -> None:
        """Write ``$<number>=<value>`` (checked against the firmware's known settings first).

        Settings live in EEPROM and survive power cycles. Errors and ``timeout`` as in
        :meth:`send` (the firmware profile is detected first if unknown).
        """
        loop = self._running_loop()
        deadline = _deadline(loop, timeout)
        firmware = self._firmware
        if firmware is None:
            gcode.set_setting(number, value)  # argument errors before any I/O
            firmware = await self._require_firmware(deadline, timeout)
        data = gcode.set_setting(number, value, firmware=firmware)
        await self._command(data, deadline=deadline, timeout=timeout)


_END: Final = object()


def _text(item: object) -> str:
    if isinstance(item, bytes | bytearray):
        return bytes(item).decode("ascii", "replace").rstrip("\r\n")
    return str(item).rstrip("\r\n")


def _url_text(url: str | None) -> str:
    """``url`` quoted for messages."""
    return repr(url) if url is not None else "the port"
