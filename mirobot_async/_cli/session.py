"""A command's time with the arm: opening it (``--port`` or an embedded virtual Mirobot),
preparing it (home / unlock), the pre-flight check, background jobs, and stopping safely when
the command is interrupted (SIGINT or SIGTERM).

Stopping safely: a command that moves the arm runs its moves inside :func:`stop_safely`. When a
signal arrives, :class:`Interrupts` runs the registered urgent action at once, in the signal
handler's loop callback: it starts a task whose first step writes the feed hold ``!`` (or the
soft reset ``%`` with ``--on-interrupt reset``) before anything else happens, then cancels the
command. :func:`stop_safely` waits up to :data:`STOP_WAIT` seconds for the arm to stand still,
says what was still queued, and lets the cancellation end the command (exit status 130).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import contextvars
import logging
import os
import signal
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from typing import TYPE_CHECKING, Final

from mirobot_async._cli.exits import CliError, RobotNotReadyError, note
from mirobot_async._client.ports import AUTO, find_mirobot
from mirobot_async._core.modal import HOMED, MotionModes
from mirobot_async._core.replies import State, StatusReport
from mirobot_async.errors import MirobotError

if TYPE_CHECKING:
    from mirobot_async._client.client import Mirobot
    from mirobot_async._safety.envelope import Envelope

__all__ = [
    "DEFAULT_TIME_SCALE",
    "HOMING_INTERRUPT",
    "LOCKED_MESSAGE",
    "LOCKED_PROBED_MESSAGE",
    "STOP_WAIT",
    "Interrupts",
    "background_jobs",
    "envelope_of",
    "firmware_of",
    "open_robot",
    "preflight",
    "prepare",
    "prepare_mode",
    "refuse_if_locked",
    "sampling",
    "start_modes",
    "stop_safely",
    "time_scale_of",
]

_log = logging.getLogger("mirobot_async.cli")

DEFAULT_TIME_SCALE: Final = 10.0
"""Speed of the embedded virtual Mirobot (simulated seconds per wall second)."""
STOP_WAIT: Final = 2.0
"""Seconds an interrupted command waits for the arm to stand still in ``Hold`` (or for the
banner after ``--on-interrupt reset``) before it gives up and exits anyway."""
STILL_GAP: Final = 0.02
"""Two status reports this far apart (wall seconds) with the same joints: the arm stands still."""
HOMING_INTERRUPT: Final = "reset"
"""How an interrupted homing cycle is stopped: GRBL 0.9 checks only for a soft reset while it
homes (a feed hold would be ignored and the arm would go on homing)."""
LOCKED_MESSAGE: Final = "the arm is locked: run `mirobot home` or pass --home"
LOCKED_PROBED_MESSAGE: Final = (
    "the arm is locked (a zero-length move got 'Locked status of each axis!'): "
    "run `mirobot home` or pass --home"
)
HELD_MESSAGE: Final = (
    "the arm is in Hold with moves still queued: `mirobot reset` clears them "
    "(then `mirobot home`, or pass --home)"
)


def firmware_of(args: argparse.Namespace) -> str:
    """The firmware profile for the embedded emulator and argument checks (default 2021)."""
    return str(args.firmware or "2021")


def time_scale_of(args: argparse.Namespace) -> float | None:
    """The embedded virtual Mirobot's time scale, or None for a real arm (``--port``)."""
    if args.port is not None:
        return None
    return DEFAULT_TIME_SCALE if args.time_scale is None else float(args.time_scale)


def envelope_of(args: argparse.Namespace) -> Envelope | None:
    """The safety envelope of ``--envelope FILE`` (None without it), on the kinematic model of
    ``--firmware`` (default 2021: a classic arm found at connect gets the classic model).
    A bad file is a MirobotUsageError naming it (exit status 2), before the arm is opened.
    A command may set ``args.envelope_object`` (an Envelope) instead, e.g. a default one."""
    given: Envelope | None = getattr(args, "envelope_object", None)
    if given is not None:
        return given
    path = getattr(args, "envelope", None)
    if path is None:
        return None
    from mirobot_async._cli.envelope_file import load_envelope

    return load_envelope(path, firmware=firmware_of(args))


def record_of(args: argparse.Namespace) -> str | None:
    """``--record FILE``: where the session's tape is appended (None: not recorded)."""
    record = getattr(args, "record", None)
    return None if record is None else str(record)


def _check_port(port: str) -> None:
    """Fail early, in plain words, for a device path that does not exist or is locked.

    "Locked" is an exclusive ``flock`` held by another program, as pyserial takes with
    ``exclusive=True``: the port is opened without blocking, tested and closed again.
    URLs (``socket://...``) and non-POSIX names (``COM3``) are left to the transport.
    """
    if "://" in port or not port.startswith("/"):
        return
    if not os.path.exists(port):
        raise CliError(f"{port}: no such port (is the arm plugged in and switched on?)")
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        return
    try:
        fd = os.open(port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError:
        return  # the transport reports it with the OS's words
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        raise CliError(f"{port} is busy: another program is using it") from None
    except OSError:
        return
    finally:
        os.close(fd)  # also releases the lock


HOMING_SILENCE_NOTE: Final = (
    "the arm may be homing: it answers no status request while it searches its switches"
)


async def _connect_port(
    args: argparse.Namespace, watch_silent: bool, envelope: Envelope | None
) -> Mirobot:
    """Connect to ``args.port``; with ``watch_silent`` an arm that answers no status request (it may
    be homing) is connected to anyway, with a note (the caller keeps asking)."""
    from mirobot_async._client.client import Mirobot
    from mirobot_async.errors import MirobotConnectionError

    record = record_of(args)
    try:
        return await Mirobot.connect(
            args.port, firmware=args.firmware, envelope=envelope, record=record
        )
    except MirobotConnectionError as err:
        if not watch_silent or not isinstance(err.__cause__, TimeoutError):
            raise
        note(f"{err}; {HOMING_SILENCE_NOTE}: watching anyway")
    return await Mirobot.connect(  # with --record: a second tape in the file
        args.port, firmware=args.firmware, envelope=envelope, probe=False, record=record
    )


@contextlib.asynccontextmanager
async def open_robot(
    args: argparse.Namespace, *, watch_silent: bool = False
) -> AsyncIterator[Mirobot]:
    """The arm at ``--port``, or an embedded virtual Mirobot for the duration of the block.

    ``watch_silent`` (``monitor``): a port whose arm answers no status request is opened
    anyway (an arm that is homing answers none until its switch search ends)."""
    from mirobot_async._client.client import Mirobot

    envelope = envelope_of(args)
    if args.port is not None:
        if args.time_scale is not None:
            note("note: --time-scale only applies to the embedded virtual Mirobot; ignored")
        if args.port == AUTO:
            args.port = await asyncio.to_thread(find_mirobot)
            note(f"auto: using {args.port}")
        _check_port(args.port)
        arm = await _connect_port(args, watch_silent, envelope)
        try:
            yield arm
        finally:
            await arm.close()
        return

    from mirobot_async.virtual import start_emulator

    firmware = firmware_of(args)
    scale = DEFAULT_TIME_SCALE if args.time_scale is None else float(args.time_scale)
    note(
        f"no --port given; using an embedded virtual Mirobot "
        f"(firmware {firmware}, time-scale {scale:g})"
    )
    # In this process (no subprocess, no pty): a command starts at once, and a Ctrl-C reaches
    # only the command, which then stops the virtual arm as it would a real one.
    async with (
        start_emulator(firmware=firmware, time_scale=scale, in_process=True) as url,
        Mirobot.connect(
            url,
            firmware="2024"
            if firmware == "2024"
            else "classic"
            if firmware == "classic"
            else "2021",
            envelope=envelope,
            record=record_of(args),
        ) as arm,
    ):
        yield arm


@contextlib.asynccontextmanager
async def sampling(arm: Mirobot, interval: float) -> AsyncIterator[AsyncIterator[StatusReport]]:
    """``arm.statuses(interval)``, closed at the end of the block (not left to the GC)."""
    statuses = arm.statuses(interval=interval)
    try:
        yield statuses
    finally:
        await statuses.aclose()


def prepare_mode(args: argparse.Namespace) -> str:
    """What :func:`prepare` does: ``"home"``, ``"unlock"`` or ``"none"`` (``--home`` /
    ``--unlock`` / ``--no-home``; without them nothing on a port, the embedded virtual
    Mirobot's default otherwise)."""
    mode: str | None = args.prepare
    if mode is None:
        mode = "none" if args.port is not None else str(args.embedded_prepare)
    return mode


def start_modes(args: argparse.Namespace) -> MotionModes:
    """The modes a program starts from after :func:`prepare`: homing leaves
    :data:`~mirobot_async._core.modal.HOMED` (feed rate 0: a ``G1`` needs an ``F``), otherwise
    the power-on modes the check assumes."""
    return HOMED if prepare_mode(args) == "home" else MotionModes()


async def prepare(arm: Mirobot, args: argparse.Namespace) -> None:
    """Home or unlock before starting, as ``--home`` / ``--unlock`` / ``--no-home`` say.

    Homing is stopped safely with a soft reset (:data:`HOMING_INTERRUPT`)."""
    mode = prepare_mode(args)
    if args.prepare is None:
        if mode == "home":
            note("homing the virtual Mirobot first (--no-home to skip)")
        elif mode == "unlock":
            note("unlocking the virtual Mirobot first (--as-is to skip)")
    if mode == "home":
        async with stop_safely(arm, HOMING_INTERRUPT):
            await arm.home()
    elif mode == "unlock":
        await arm.unlock()


async def preflight(arm: Mirobot, *, probe_lock: bool = True) -> StatusReport:
    """The arm's status, if it can move: :class:`RobotNotReadyError` (one line, exit 1) when it
    is locked or holds queued moves (Hold), before a line of the command is sent.

    Locked: in Alarm, or (``probe_lock``; the status does not show it: a classic arm after
    power-on, a 2021 arm after ``$X``) as :func:`refuse_if_locked` finds it."""
    report = await arm.status()
    if report.state is State.ALARM:
        raise RobotNotReadyError(LOCKED_MESSAGE)
    if report.state is State.HOLD:
        raise RobotNotReadyError(HELD_MESSAGE)
    if probe_lock:
        await refuse_if_locked(arm)
    return report


async def refuse_if_locked(arm: Mirobot) -> None:
    """:class:`RobotNotReadyError` naming ``mirobot home`` when :meth:`Mirobot.axes_locked`
    finds the axes locked with its zero-length move (it moves nothing and leaves the modes as
    they were): before the command's first motion line."""
    if await arm.axes_locked():
        raise RobotNotReadyError(LOCKED_PROBED_MESSAGE)


@contextlib.asynccontextmanager
async def background_jobs(**jobs: Awaitable[None] | None) -> AsyncIterator[None]:
    """Run ``jobs`` (None: skipped; keyword: what it is, for messages) as tasks for the duration
    of the block, then cancel them.

    A job's failure never replaces the block's outcome: after a block that succeeded it is a
    warning on stderr (e.g. the trace is incomplete), after one that failed it is only logged
    at debug level (most likely the same cause, such as the link lost). A cancellation of the
    calling task while the jobs wind down (a second Ctrl-C) propagates: ``gather`` raises
    :class:`asyncio.CancelledError` only then, the jobs' own cancellations are results.
    """
    tasks = {
        name.replace("_", " "): asyncio.ensure_future(job)
        for name, job in jobs.items()
        if job is not None
    }
    succeeded = False
    try:
        yield
        succeeded = True
    finally:
        for task in tasks.values():
            task.cancel()
        results = await asyncio.gather(*tasks.values(), return_exceptions=True)
        for name, result in zip(tasks, results, strict=True):
            if isinstance(result, Exception):
                _log.debug("%s failed", name, exc_info=result)
                if succeeded:
                    note(f"warning: {name} failed: {type(result).__name__}: {result}")


# --------------------------------------------------------------------------------------------
# Interruptions


_CURRENT: contextvars.ContextVar[Interrupts | None] = contextvars.ContextVar(
    "mirobot_cli_interrupts", default=None
)


class Interrupts:
    """SIGINT and SIGTERM while a command runs in ``task``.

    The first signal runs the registered urgent actions at once (synchronously, from the loop's
    signal callback) and cancels the command; a second signal only cancels again (it cuts the
    wait for the arm short). :attr:`signal` is the first signal received, None if none.
    """

    def __init__(self, task: asyncio.Task[int]) -> None:
        self._task = task
        self._urgent: list[Callable[[], None]] = []
        self.signal: signal.Signals | None = None

    def fire(self, signum: signal.Signals) -> None:
        """React to ``signum`` (installed as the loop's signal handler)."""
        if self.signal is None:
            self.signal = signum
            for action in list(self._urgent):
                try:
                    action()
                except Exception:  # pragma: no cover - a stop action must not stop the others
                    _log.exception("stopping the arm failed")
        self._task.cancel()

    @contextlib.contextmanager
    def installed(self) -> Iterator[None]:
        """Handle SIGINT and SIGTERM for the duration of the block (where the loop can)."""
        loop = asyncio.get_running_loop()
        token = _CURRENT.set(self)
        handled = []
        for signum in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
                loop.add_signal_handler(signum, self.fire, signum)
                handled.append(signum)
        try:
            yield
        finally:
            for signum in handled:
                with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
                    loop.remove_signal_handler(signum)
            _CURRENT.reset(token)

    @contextlib.contextmanager
    def urgent(self, action: Callable[[], None]) -> Iterator[None]:
        """Run ``action`` at once if a signal arrives during the block."""
        self._urgent.append(action)
        try:
            yield
        finally:
            self._urgent.remove(action)


async def _stop_arm(arm: Mirobot, on_interrupt: str) -> str:
    """Feed hold (or soft reset) and wait up to :data:`STOP_WAIT` s; returns what happened.

    The first step writes ``!`` / ``%`` synchronously (:meth:`Mirobot.hold` and
    :meth:`Mirobot.reset` write before their first await). Never raises a MirobotError.
    """
    loop = asyncio.get_running_loop()
    started = loop.time()
    try:
        if on_interrupt == "reset":
            await arm.reset(timeout=STOP_WAIT)
            return (
                "interrupted: soft reset sent (%): the arm stopped and its queue was cleared; "
                "the axes are locked again (`mirobot home`)"
            )
        report = await arm.hold(timeout=STOP_WAIT)
        # Hold is reported as soon as the arm starts to decelerate: wait until it stands still.
        while loop.time() - started < STOP_WAIT:
            await asyncio.sleep(STILL_GAP)
            previous, report = report, await arm.status(timeout=STOP_WAIT)
            if report.joints == previous.joints and report.rail == previous.rail:
                break
        else:
            return f"interrupted: feed hold sent (!); the arm was still moving after {STOP_WAIT} s"
    except MirobotError as err:
        return f"interrupted: the arm may still be moving: {err}"
    waited = (loop.time() - started) * 1000
    return (
        f"interrupted: feed hold sent (!); the arm is {report.state.value} after {waited:.0f} ms"
        + (", standing still" if report.state is State.HOLD else "")
    )


@contextlib.asynccontextmanager
async def stop_safely(
    arm: Mirobot, on_interrupt: str, queued: Callable[[], list[str]] | None = None
) -> AsyncIterator[None]:
    """Moves inside the block are stopped on SIGINT/SIGTERM: ``!`` (``on_interrupt="hold"``)
    or ``%`` (``"reset"``) is written at once, the block is cancelled, the arm is waited for up
    to :data:`STOP_WAIT` s, then ``queued()`` is called (it may end a progress display) and
    what the stop did and the lines it returns (what was still queued) are printed on stderr.

    The cancellation propagates (the command exits 130). Outside :func:`main` (no
    :class:`Interrupts` installed) the block runs unguarded.
    """
    interrupts = _CURRENT.get()
    if interrupts is None:
        yield
        return
    loop = asyncio.get_running_loop()
    stopping: list[asyncio.Task[str]] = []

    def stop_now() -> None:
        stop = _stop_arm(arm, on_interrupt)
        stopping.append(loop.create_task(stop, name="mirobot-stop"))

    with interrupts.urgent(stop_now):
        try:
            yield
        except asyncio.CancelledError:
            if not stopping:
                raise
            outcome = await stopping[0]
            messages = queued() if queued is not None else []
            note(outcome)
            for message in messages:
                note(message)
            if on_interrupt == "hold" and "feed hold sent" in outcome:
                note("queued moves stay in the arm until `mirobot reset` clears them")
            raise
