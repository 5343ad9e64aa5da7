"""The asyncio client for the WLKATA Mirobot: :class:`Mirobot`.

::

    async with Mirobot.connect("/dev/ttyUSB0") as arm:
        await arm.home()
        await arm.move_joints(j1=30, j2=10, speed=1500)
        print(await arm.status())

How it works
------------
Bytes from the serial link (:mod:`mirobot_async._client.transport`) go into the sans-IO state
machine (:mod:`mirobot_async._core.protocol`), whose events resolve asyncio futures. Every line a
call sends is
**registered with the state machine before it is written**, with no ``await`` in between, so its
reply slot exists before the robot can answer. Lines are written in call order (one FIFO lock)
and only when they fit in the robot's receive buffer (127 bytes) (GRBL character counting), so the
planner never starves and no byte is ever lost to an overflow. ``$`` commands (settings, homing,
``$X``, ``$$``) are sent only when nothing else is in flight and nothing else is sent until they
are answered (GRBL's send-response rule for commands that are unsafe to stream).

Status: every caller that wants a status (``status()``, ``statuses()``, ``wait=True`` moves,
liveness checks) shares the ``?`` in flight. A corrupted status line is dropped, counted
(:attr:`Mirobot.stats`) and asked again at once; a ``?`` that the robot ignores is asked again
after :attr:`Mirobot.status_retry_interval`, and is forgotten once a later line is answered (see
:mod:`mirobot_async._client.poller`), so ignored requests never slow later calls down.

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
Two silences are expected: during the homing search the firmware answers nothing, not even
``?``, so no ``?`` is asked until the homing bound (:attr:`Mirobot.homing_bounds`, from the
homing settings) has passed; and lines behind a ``G4`` dwell keep their slots while the robot
reports ``Idle`` for the dwell. After homing, nothing is written until the arm is back at zero.
Every rule, with the robot behaviour it relies on: ARCHITECTURE.md, "Timeouts and liveness".

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
``Mirobot.connect(url, envelope=Envelope(...))`` (:mod:`mirobot_async._safety.envelope`) checks
**every line** before it is written, at the moment it would be written (under the send lock, so the
checks follow the order of the lines on the wire): structured moves (``move_joints``,
``move_pose``), raw :meth:`Mirobot.send` lines and every :meth:`Mirobot.stream` line are parsed
with :func:`~mirobot_async._safety.prediction.predict` against the
modal state (:class:`~mirobot_async._safety.envelope.MotionModes`, tracked over every line written)
and the predicted position. A violating line raises :class:`~mirobot_async.errors.MirobotUsageError`
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
envelope, is detected at connect to be) ``classic`` and the envelope has the default
``dh=DH_2021``, the client uses it with ``dh=DH_CLASSIC`` (:attr:`Mirobot.envelope` shows the
one in use). Any other ``dh`` is used as given. The profile comes from a banner, else from a
``$$`` that is written only when nothing is in flight and a status shows the arm at rest (the
firmware refuses ``$$`` while the arm moves), so detecting it never fails a call.

*Opt-out.* ``send(line, check_envelope=False)`` logs a WARNING naming the line (and, if the
envelope would have refused it, why); ``stream(lines, check_envelope=False)`` logs a WARNING when
it starts and one for each line the envelope would have refused. Limitation: lines written
after a line that the robot then refuses were checked assuming it ran (pipelining); a stream
stops at such a refusal. The stream's per-line WARNINGs need the position: after a line the
envelope could not follow, the following unchecked lines are only logged at DEBUG.

Layout: this module is the facade (public commands and the event router); the jobs live in
:mod:`~mirobot_async._client.deadline`, :mod:`~mirobot_async._client.wire` (transport, state
machine, stats), :mod:`~mirobot_async._client.condition` (alarm, resets, firmware),
:mod:`~mirobot_async._client.poller` (status), :mod:`~mirobot_async._client.guard` (envelope),
:mod:`~mirobot_async._client.scheduler` (lines), :mod:`~mirobot_async._client.completion` (motion)
and :mod:`~mirobot_async._client.streaming` (streams).

Wire log: the ``mirobot_async.wire`` logger (a child of ``mirobot_async``) logs every line sent
(``-> ...``) and received (``<- ...``) at DEBUG.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import AsyncIterable, Callable, Generator, Iterable
from os import PathLike
from typing import TYPE_CHECKING, Any

from mirobot_async._client.condition import Firmware
from mirobot_async._client.deadline import check_timeout, deadline_after
from mirobot_async._client.motion_commands import MotionCommands
from mirobot_async._client.parts import (
    CONNECT_TIMEOUT,
    DEFAULT_TIMEOUT,
    HOME_TIMEOUT,
    MOVE_TIMEOUT,
    RESET_TIMEOUT,
    STATUS_TIMEOUT,
    default_reply_timeout,
)
from mirobot_async._client.path_commands import PathCommands, PathError
from mirobot_async._client.router import url_text
from mirobot_async._client.scheduler import SendRules
from mirobot_async._client.setting_commands import SettingCommands
from mirobot_async._client.status_commands import StatusCommands
from mirobot_async._client.streaming import LineResult, Stream, StreamResult
from mirobot_async._client.tool_commands import ToolCommands
from mirobot_async._client.transport import Implementation
from mirobot_async._client.wire import ClientStats, Transport, TransportOpener, serial_opener
from mirobot_async._core.outgoing import OutgoingLine, encode_line
from mirobot_async._core.replies import StatusReport
from mirobot_async.errors import MirobotConnectionError, MirobotTimeoutError, MirobotUsageError

if TYPE_CHECKING:  # imported when an envelope is used (it needs numpy), and the view
    from mirobot_async._safety.envelope import Envelope
    from mirobot_async._view.watch import ArmView

__all__ = [
    "CONNECT_TIMEOUT",
    "DEFAULT_TIMEOUT",
    "HOME_TIMEOUT",
    "MOVE_TIMEOUT",
    "RESET_TIMEOUT",
    "STATUS_TIMEOUT",
    "ClientStats",
    "Connector",
    "LineResult",
    "Mirobot",
    "PathError",
    "Stream",
    "StreamResult",
    "Transport",
    "TransportOpener",
]

_log = logging.getLogger("mirobot_async.client")


class Connector:
    """What :meth:`Mirobot.connect` returns: ``await`` it (then close the arm) or use it with
    ``async with`` (closed at the end of the block)."""

    def __init__(self, arm: Mirobot, *args: Any) -> None:
        self._arm = arm
        self._args = args  # those of Mirobot._open

    def __await__(self) -> Generator[Any, None, Mirobot]:
        return self._arm._open(*self._args).__await__()

    async def __aenter__(self) -> Mirobot:
        return await self._arm._open(*self._args)

    async def __aexit__(self, *exc_info: object) -> None:
        await self._arm.close()


class Mirobot(MotionCommands, PathCommands, StatusCommands, ToolCommands, SettingCommands):
    """An asyncio connection to one Mirobot. Open it with :meth:`connect`.

    All methods may be called concurrently from many tasks; lines go out in call order and each
    call gets its own reply. Every awaiting method takes ``timeout=`` (seconds, ``None`` for no
    limit; defaults are the module's ``*_TIMEOUT`` constants) and raises
    :class:`MirobotTimeoutError` naming what it waited for. Unless its docstring says otherwise a
    method that sends a line behaves like :meth:`send` for errors and cancellation: a cancelled
    call's line keeps its slot and its reply is consumed and discarded. Timing knobs
    (:attr:`liveness_interval`, :attr:`reply_grace`, :attr:`status_retry_interval`,
    :attr:`status_min_gap`) may be lowered by tests.
    """

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
        open_transport: TransportOpener | None = None,
        record: str | PathLike[str] | None = None,
    ) -> Connector:
        """Open ``url`` (device, pty path, ``socket://host:port``, ``loop://``) at 115200 8N1.

        Use as ``async with Mirobot.connect(url) as arm:`` (closed at the end of the block) or
        ``arm = await Mirobot.connect(url)`` (then call :meth:`close`).

        ``firmware`` (``"2021"`` / ``"classic"`` / ``"2024"``) is learnt from the reset banner the
        arm prints when the port opens or, failing that, from ``$$`` or ``$I``; pass it to
        skip detection. ``envelope`` is a workspace safety envelope
        (:class:`mirobot_async.Envelope`): every line that moves the arm is checked against it
        before anything is written (see the module docstring, "Safety envelope"); with an
        envelope an unknown profile is read at connect (``$$``, once the arm is at rest), so
        that a classic arm gets ``DH_CLASSIC``.
        ``implementation`` picks pyserial-asyncio-fast (``"fast"``, default) or the original
        pyserial-asyncio. ``status_timeout`` bounds the status requests of liveness checks.

        ``exclusive`` (default) locks the device so that a second program (or client) opening
        it fails at once with :class:`MirobotConnectionError` instead of stealing replies.
        ``open_transport`` replaces the serial port with another
        :class:`~mirobot_async._client.wire.TransportOpener` (a wrapper that watches the bytes, a
        multiplexed bus); ``implementation`` and ``exclusive`` are then not used.

        With ``probe`` (default) a status request proves that a Mirobot answers (and waits for a
        banner being printed, e.g. by an arm that resets when the port opens).
        Raises :class:`MirobotConnectionError` at once when the port cannot be opened (missing
        path, busy port) or when nothing answers the probe within ``timeout`` seconds.
        Cancellation closes the port.

        An arm behind a multi-robot controller on an RS485 bus is reached with
        :func:`mirobot_async.bus.connect` (``bus.connect(url, address=N)``).

        ``record`` (a file name): a tape of the connection is appended to it as it goes (JSON
        Lines, ``docs/tapes.md``): every byte written and line received, with their instants,
        after a header naming the link kind (no host or path), the banner and the firmware
        family. The file is closed with the connection (also when the connect fails).
        """
        arm = cls(
            firmware=firmware,
            envelope=envelope,
            implementation=implementation,
            status_timeout=status_timeout,
        )
        arm._exclusive = exclusive
        opener = open_transport or serial_opener(implementation, exclusive)
        return Connector(arm, url, timeout, probe, opener, record)

    async def _open(
        self, url: str, timeout: float | None, probe: bool, opener: TransportOpener, record: Any
    ) -> Mirobot:
        if self._opened:
            raise MirobotUsageError("this Mirobot was already connected; create a new one")
        check_timeout(timeout)
        self._record_to(record)
        self._opened = True
        loop = self._loop = asyncio.get_running_loop()
        self._poller.start(loop)
        self._lines.start(loop)
        self._router.start(loop)
        self.url = url
        await self._wire.open(
            url,
            opener,
            on_data=self._router.on_data,
            on_lost=self._router.on_lost,
            timeout=CONNECT_TIMEOUT if timeout is None else timeout,
        )
        self._condition.connected = True
        gap = getattr(self._wire.transport, "status_min_gap", None)
        if isinstance(gap, int | float):  # a link that is no serial line (an in-process arm)
            self._poller.min_gap = float(gap)
        try:
            if probe:
                await self._probe(timeout)
        except BaseException as err:
            await self.close()
            refusal = self._wire.refusal  # a network server accepted, then said it is busy
            if refusal is not None and isinstance(err, MirobotConnectionError):
                raise refusal from err
            raise
        self._wire.begin_tap()  # a tape's header: the banner and family are known now
        _log.debug("connected to %s", url)
        return self

    async def _probe(self, timeout: float | None) -> None:
        deadline = deadline_after(self._running_loop(), timeout)
        try:
            async with asyncio.timeout_at(deadline):
                report, _ = await self._poller.fetch(fresh=False, timeout=None)
                while self._wire.conn.in_banner:
                    await self._wire.next_progress()
        except TimeoutError as err:
            raise MirobotConnectionError(
                f"{url_text(self.url)} opened, but no Mirobot answered a status request within "
                f"{timeout:g} s (an arm that is homing answers none until its switch search ends)"
            ) from err
        if self._guard.envelope is not None and self._condition.firmware is None:
            try:  # the envelope's kinematic model: waits for the arm to be at rest
                await self._require_firmware(deadline, timeout)
            except MirobotTimeoutError as err:
                raise MirobotConnectionError(
                    f"{url_text(self.url)} opened, but the firmware profile (for the safety "
                    f"envelope) could not be read within {timeout:g} s: {err}"
                ) from err
            report = self._poller.last_status or report
        if not self._wire.conn.pending_count:
            # The probe's status, asked with nothing in flight: where the arm is at rest.
            self._guard.adopt_status(self._poller.last_status or report)

    async def close(self) -> None:
        """Close the link; idempotent, never hangs.

        Pending calls fail with :class:`MirobotLinkLostError` ("closed"), as does every later
        call. Unsent output is discarded; the robot keeps running what it already received.
        """
        self._condition.closing = True
        self._router.set_fatal("the connection was closed")
        await self._wire.close()

    async def __aenter__(self) -> Mirobot:
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.close()

    # ---- public state ----

    @property
    def closed(self) -> bool:
        """True once the link was closed or lost."""
        return self._condition.fatal is not None

    @property
    def firmware(self) -> Firmware | None:
        """The firmware family: ``"classic"``, ``"2021"``, ``"2024"``, or ``None`` while not
        known (see :meth:`detect_firmware`; :attr:`firmware_evidence` says how it was learnt)."""
        return self._condition.firmware

    @property
    def firmware_evidence(self) -> str | None:
        """What decided :attr:`firmware`, once per connection: the banner, ``$$``, ``$I`` or
        ``firmware=`` (e.g. ``"$$ lists $44, $45 (only the 2024 family has them)"``)."""
        return self._condition.firmware_evidence

    @property
    def firmware_version(self) -> str | None:
        """The version printed in the last banner seen (``20191228_2``, ``Mirobot,20240820``...),
        if any."""
        return self._condition.firmware_version

    @property
    def banner(self) -> tuple[str, ...] | None:
        """The lines of the last reset banner seen (power-on, :meth:`reset`, spontaneous)."""
        return self._condition.banner

    @property
    def last_status(self) -> StatusReport | None:
        """The most recent well-formed status report received (no I/O)."""
        return self._poller.last_status

    @property
    def alarm(self) -> str | None:
        """The text of the alarm motion calls are failing with, or ``None``."""
        return self._condition.alarm

    @property
    def needs_reset(self) -> bool:
        """True after an alarm that only a reset clears (``Hard limit``): nothing is sent."""
        return self._condition.reset_only is not None

    @property
    def corrupted_status_count(self) -> int:
        """Unparsable status lines received so far (dropped and asked again)."""
        return self.stats.status_corrupted

    @property
    def pending_count(self) -> int:
        """Lines written and not answered yet (including those of cancelled callers)."""
        return self._wire.conn.pending_count

    @property
    def envelope(self) -> Envelope | None:
        """The workspace safety envelope every move is checked against, or ``None``.

        This is the envelope in use: the one given, with ``dh=DH_CLASSIC`` on a classic arm if
        it had the default ``DH_2021`` (see the module docstring).
        """
        return self._guard.envelope

    @property
    def bytes_in_flight(self) -> int:
        """Bytes of lines written and not answered yet (GRBL character counting, <= 128)."""
        return self._wire.conn.bytes_in_flight

    @property
    def status_requests_outstanding(self) -> int:
        """``?`` written and neither answered nor taken as ignored yet (usually 0 or 1)."""
        return self._poller.outstanding

    @property
    def status_waiter_count(self) -> int:
        """Calls currently waiting for a status report (they share the outstanding ``?``)."""
        return self._poller.waiter_count

    @property
    def reply_slot_count(self) -> int:
        """Lines the client awaits a reply for (equals :attr:`pending_count` between events)."""
        return len(self._lines.slots)

    async def send(
        self,
        line: str | bytes,
        *,
        check_envelope: bool = True,
        validate: bool = True,
        timeout: float | None = DEFAULT_TIMEOUT,
    ) -> tuple[str, ...]:
        """Send one raw line and return what the firmware printed for it (without the ``ok``).

        The line is first judged as ``mirobot check`` judges it
        (:func:`mirobot_async._core.validation.check_line`: PWM and joint ranges, line length,
        unknown words, numbers the firmware reads otherwise, ``G20``...), with the modal state
        the client knows (predicted with an envelope, else unknown: mode-dependent ranges only
        when the line states its modes): a problem raises
        :class:`~mirobot_async._core.validation.InvalidLineError` (a :class:`MirobotUsageError`) and
        nothing is written. ``validate=False`` sends it anyway and logs a WARNING naming it.

        With a safety envelope the line is parsed and checked before it is written (a move that
        leaves the envelope, or that the envelope cannot judge, raises
        :class:`MirobotUsageError` and nothing is written); ``check_envelope=False`` sends it
        unchecked and logs a WARNING naming it.

        Raises :class:`MotionRefusedError` for "ok but dropped" motions,
        :class:`MirobotCommandError` for an error reply (:class:`MirobotAlarmError` for
        ``Alarm lock``), :class:`MirobotUsageError` for a line that is not one ASCII line or
        contains a realtime byte (nothing is sent), :class:`MirobotTimeoutError` when no reply
        comes within ``timeout`` seconds (default :data:`DEFAULT_TIMEOUT`) or the reply was lost.
        A ``timeout`` of :data:`DEFAULT_TIMEOUT` is raised for the lines the firmware answers
        late (:func:`~mirobot_async._client.parts.default_reply_timeout`): :data:`HOME_TIMEOUT` for
        a homing line, :data:`MOVE_TIMEOUT` (plus the dwell) for ``G4`` and the PWM lines
        ``M3``/``M4``/``M5``, which are answered once the queued motion has ended. While the
        arm homes the firmware answers nothing, not even ``?``: the call waits, and a link that
        stays silent longer than homing can take fails naming homing.
        ``$`` commands wait until nothing else is in flight. Cancellation keeps the link in step:
        the reply is consumed and discarded.
        """
        data = encode_line(line, self._wire.rx_buffer_size)
        outgoing = OutgoingLine.of(data, f"send({data.decode('ascii')!r})")
        if timeout == DEFAULT_TIMEOUT:
            timeout = default_reply_timeout(outgoing.parsed)
        deadline = deadline_after(self._running_loop(), timeout)
        if not validate:
            _log.warning("%s is sent WITHOUT validation (validate=False)", outgoing.what)
        rules = SendRules(check_envelope=check_envelope, validate=validate)
        return await self._command(outgoing, deadline=deadline, timeout=timeout, rules=rules)

    def stream(
        self,
        lines: Iterable[str | bytes] | AsyncIterable[str | bytes],
        *,
        on_progress: Callable[[LineResult], object] | None = None,
        continue_on_error: bool = False,
        check_envelope: bool = True,
        validate: bool = True,
        timeout: float | None = None,
        wait: bool = False,
    ) -> Stream:
        """Stream G-code lines with GRBL character counting (the planner never starves).

        ``lines`` is an iterable or async iterable of lines (``str``, ``bytes`` or
        ``bytearray``; blank lines are skipped; comments are sent, the firmware ignores them).
        Await the returned :class:`Stream` for a :class:`StreamResult` (``on_progress(LineResult)``
        is called for each line in order; it may be a coroutine function), or iterate it for the
        :class:`LineResult` of each line.

        Stops sending at the first failed line (an error, a refusal, a bad line: one that is not
        one ASCII line, or an item of another type, gets a :class:`MirobotUsageError` and is
        not written) unless ``continue_on_error``; always stops on a reset, an alarm or a lost
        reply. Lines already in the robot's buffer still run and are reported.

        With a safety envelope every line is checked just before it is written, starting where
        the lines before it leave the arm; a line that leaves the envelope (or that it cannot
        judge) is not written and the stream stops there, even with ``continue_on_error``: its
        :class:`LineResult` carries the :class:`MirobotUsageError` (``result.stopped`` is
        True). ``check_envelope=False`` sends every line unchecked and logs a WARNING when the
        stream starts and for each line the envelope would have refused.

        Every line is validated as :meth:`send` does, right before it would be written (with
        the modal state left by the lines before it): an invalid line is not written, its
        :class:`LineResult` carries the
        :class:`~mirobot_async._core.validation.InvalidLineError`, and the stream stops there unless
        ``continue_on_error``. ``validate=False`` logs one WARNING when the stream starts.

        A line that would end elsewhere streamed than sent after the arm stopped (its
        ``M20``/``M21`` makes the firmware restart from where the moving arm is, see
        :class:`~mirobot_async._core.modal.Chaining`) is a
        :class:`~mirobot_async.errors.MotionChainError` naming the line and the fix; it stops
        the stream even with ``continue_on_error``. A ``list`` or ``tuple`` of lines is judged
        whole first: then nothing at all is written (``result.sent == 0``).

        With ``wait`` the stream ends only when the arm has finished the motion: ``G4 P0`` is
        written right after the last line, and the firmware answers it once its planner is
        empty, so the stream returns about one USB latency after the arm stops (a status poll
        needs a whole report, ~16.5 ms of the robot's wire, and one in flight when it stops).
        The dwell is not part of the result; it is not written after a failed line (unless
        ``continue_on_error``) or a stop, and its error (an alarm, a reset) is raised.

        ``$`` lines are sent only when nothing else is in flight. ``timeout`` bounds the whole
        stream (``None``: no limit; each reply is liveness-checked). A lost link raises
        :class:`MirobotLinkLostError`. Cancelling stops sending; lines in flight are consumed and
        discarded.
        """
        parts = (self._lines, self._condition, self._guard)
        if not validate:
            _log.warning("stream(validate=False): its lines are sent WITHOUT validation")
        return Stream(
            parts, lines, on_progress, continue_on_error, timeout, check_envelope, validate, wait
        )

    def view(
        self,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        open_browser: bool = True,
        allow_remote: bool = False,
        wait_for_page: float | None = None,
    ) -> ArmView:
        """The arm in 3D in a browser while a block runs: ``async with arm.view() as view:``.

        The page follows this connection: the arm as its status reports it, the path predicted
        for every line this script writes, a marker and an entry for each line refused (by the
        firmware, or by the client before it was written), each alarm and reset. It only
        watches: closing it never stops the script, and the block's end tells it how the script
        ended. Its URL (with a secret; also printed on stderr) is ``view.url``, opened in a
        browser unless ``open_browser=False``; it is served on ``host``:``port`` (a free port by
        default; an address other than loopback only with ``allow_remote=True``).
        ``wait_for_page`` (seconds): entering also waits until a page is connected (a short
        script would end before anyone watched); after that long it goes on without one.

        Entering waits, once, for the arm at rest when its firmware (or, off classic, its base
        offset) is not known yet (one ``$$``, at most 30 s: :class:`MirobotTimeoutError`).
        Needs the ``view`` extra: without it :class:`MirobotUsageError` says what to install.
        """
        import importlib.util

        missing = [m for m in ("viser", "yourdfpy") if importlib.util.find_spec(m) is None]
        if missing:
            raise MirobotUsageError(
                f"the 3D view (arm.view(), --view) needs the view extra ({', '.join(missing)} "
                "not installed): "
                "pip install 'mirobot-async[view]' (in a clone: pip install -e '.[view]')"
            )
        from mirobot_async._view.watch import ArmView

        return ArmView(
            self,
            self._lines.observers,
            host=host,
            port=port,
            open_browser=open_browser,
            allow_remote=allow_remote,
            wait_for_page=wait_for_page,
        )
