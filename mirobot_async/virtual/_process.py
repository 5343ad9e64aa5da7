"""The virtual Mirobot as a process: :class:`EmulatorProcess` and :func:`start_emulator` (asyncio).

The process is ``python -m mirobot_emulator`` (the ``mirobot-emulator`` command), started in its
own session (a terminal's Ctrl-C reaches only the program that started it) on a fresh
pseudo-terminal, or on a loopback TCP port (``listen="tcp"``: ``socket://...``; the default where
there are no ptys, or everywhere with ``MIROBOT_TEST_LINK=tcp``). It is stopped with SIGTERM, then
SIGKILL if it does not exit within a few seconds.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import signal
from collections.abc import AsyncIterator, Sequence
from typing import Any

from mirobot_async.errors import MirobotTimeoutError, MirobotUsageError
from mirobot_async.virtual._control import (
    CONTROL_TIMEOUT,
    DEFAULT_FIRMWARE,
    DEFAULT_TIME_SCALE,
    STARTUP_TIMEOUT,
    STOP_TIMEOUT,
    EmulatorError,
    control_reply,
    control_result,
    control_text,
    emulator_command,
    renew_text,
    renewed_command,
    renewed_url,
)

__all__ = ["EmulatorProcess", "start_emulator"]

_log = logging.getLogger("mirobot_async.virtual")


class EmulatorProcess:
    """A running emulator subprocess, driven from asyncio. Create with :meth:`start`.

    Use it as an async context manager (``async with await EmulatorProcess.start() as emu``) or
    call :meth:`stop` yourself; either way no process is left behind.
    """

    def __init__(
        self, process: asyncio.subprocess.Process, url: str, command: Sequence[str]
    ) -> None:
        self._process = process
        self.url = url
        """The emulator's port (a pty path or ``socket://HOST:PORT``) for ``Mirobot.connect``."""
        self.command = tuple(command)
        self._replies: asyncio.Queue[str | None] = asyncio.Queue()
        self._control_lock = asyncio.Lock()
        self._reader = asyncio.get_running_loop().create_task(
            self._read_stdout(), name=f"mirobot-emulator-stdout-{process.pid}"
        )

    @classmethod
    async def start(
        cls,
        firmware: str = DEFAULT_FIRMWARE,
        time_scale: float = DEFAULT_TIME_SCALE,
        *,
        extra_args: Sequence[str] = (),
        startup_timeout: float = STARTUP_TIMEOUT,
        listen: str | None = None,
    ) -> EmulatorProcess:
        """Start an emulator and wait for its port URL (at most ``startup_timeout`` seconds).

        ``listen``: ``"pty"``, ``"tcp"`` (a free loopback port) or ``"HOST:PORT"``; ``None``:
        ``$MIROBOT_TEST_LINK``, else a pty where ptys exist. Raises :class:`EmulatorError` if it
        exits or prints nothing in time (the process is then killed). Cancellation kills the
        process too.
        """
        command = emulator_command(firmware, time_scale, extra_args, listen)
        process = await asyncio.create_subprocess_exec(
            *command,
            stdin=asyncio.subprocess.PIPE,
            stdout=asyncio.subprocess.PIPE,
            start_new_session=True,  # a terminal's Ctrl-C reaches only the program that owns it
        )
        try:
            assert process.stdout is not None
            try:
                async with asyncio.timeout(startup_timeout):
                    first = await process.stdout.readline()
            except TimeoutError as err:
                raise EmulatorError(
                    f"the emulator printed no port path within {startup_timeout:g} s"
                ) from err
            url = first.decode("utf-8", "replace").strip()
            if not url:
                raise EmulatorError(
                    f"the emulator exited before printing its port path: {' '.join(command)}"
                )
        except BaseException:
            await _reap(process, kill_first=True)
            raise
        _log.debug("emulator %d serving %s", process.pid, url)
        return cls(process, url, command)

    @property
    def pid(self) -> int:
        """The emulator's process id."""
        return self._process.pid

    @property
    def returncode(self) -> int | None:
        """The exit status once the process has exited, else ``None``."""
        return self._process.returncode

    async def _read_stdout(self) -> None:
        stdout = self._process.stdout
        assert stdout is not None
        try:
            while line := await stdout.readline():
                reply = control_reply(line)
                if reply is not None:
                    self._replies.put_nowait(reply)
        except (OSError, ValueError):  # pragma: no cover - pipe torn down
            pass
        finally:
            self._replies.put_nowait(None)

    async def control(self, command: str, *, timeout: float = CONTROL_TIMEOUT) -> str:
        """Send one control command (``drop-ok``, ``corrupt-status``, ``ignore-status``,
        ``stall S``, ``hard-limit``, ``reset``, ``close``, ``time-scale X``, ``split-bytes on|off``,
        ``delay MS``, ``stats``, ``motion-ends``) and return the emulator's ``ack ...`` line, which
        means the fault is armed or done (``stats`` answers with the emulator's counters in that
        line, ``motion-ends`` with the ``time.monotonic()`` instants at which motion last ended).

        Raises :class:`EmulatorError` if the emulator refuses the command or has exited, and
        :class:`MirobotTimeoutError` after ``timeout`` seconds without an answer. Commands are
        answered in order; concurrent calls are serialised. Cancellation is safe (a late answer
        is skipped by the next call only if it has no reply waiting: prefer not to cancel).
        """
        text = control_text(command)
        async with self._control_lock:
            stdin = self._process.stdin
            if stdin is None or self._process.returncode is not None or stdin.is_closing():
                raise EmulatorError(f"cannot send {text!r}: the emulator is not running")
            stdin.write(text.encode("utf-8") + b"\n")
            try:
                async with asyncio.timeout(timeout):
                    await stdin.drain()
                    reply = await self._replies.get()
            except TimeoutError as err:
                raise MirobotTimeoutError(f"the emulator's answer to {text!r}", timeout) from err
            except (ConnectionError, OSError) as err:
                raise EmulatorError(f"cannot send {text!r}: {err}") from err
            if reply is None:
                self._replies.put_nowait(None)  # keep reporting the end to later calls
            return control_result(text, reply)

    async def renew(
        self,
        firmware: str = DEFAULT_FIRMWARE,
        time_scale: float = DEFAULT_TIME_SCALE,
        *,
        extra_args: Sequence[str] = (),
        timeout: float = CONTROL_TIMEOUT,
    ) -> str:
        """Make the running emulator what a new one started with these settings would be: a new
        port (its URL is returned and becomes :attr:`url`), a fresh power-on, only the faults of
        ``extra_args`` armed, counters at zero; milliseconds instead of a process start.

        ``extra_args`` cannot name ``--listen`` or ``--link``. Raises :class:`EmulatorError` if
        the emulator refuses or has exited, :class:`MirobotTimeoutError` after ``timeout`` s
        (as :meth:`control`).
        """
        text = renew_text(firmware, time_scale, extra_args)
        url = renewed_url(await self.control(text, timeout=timeout))
        self.url = url
        self.command = tuple(renewed_command(self.command, firmware, time_scale, extra_args))
        return url

    def kill(self) -> None:
        """SIGKILL the emulator now (its port disappears, like a pulled cable); does not wait."""
        if self._process.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                self._process.kill()

    async def stop(self, timeout: float = STOP_TIMEOUT) -> int:
        """Stop the emulator: SIGTERM, wait up to ``timeout`` s, then SIGKILL. Idempotent.

        Returns the exit status. Waits for the process and its pipes to be fully released, so no
        process or file descriptor is left behind (also when cancelled: the clean-up finishes).
        """
        task = asyncio.ensure_future(self._stop(timeout))
        try:
            return await asyncio.shield(task)
        except asyncio.CancelledError:
            await asyncio.wait({task})
            raise

    async def _stop(self, timeout: float) -> int:
        process = self._process
        if process.stdin is not None and not process.stdin.is_closing():
            process.stdin.close()
        if process.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                process.send_signal(signal.SIGTERM)
        returncode = await _reap(process, timeout=timeout)
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(timeout):
                await asyncio.wait({self._reader})  # the reader's own failure is not ours
        await _cancel_and_wait(self._reader)  # still running: stdout held open by a grandchild
        if process.stdin is not None:
            with contextlib.suppress(Exception):
                await process.stdin.wait_closed()
        return returncode

    async def __aenter__(self) -> EmulatorProcess:
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.stop()


async def _cancel_and_wait(*tasks: asyncio.Task[Any]) -> None:
    """Cancel ``tasks`` and wait until they are done, logging their failures.

    A task's own failure is logged, never raised (it must not replace the caller's result or
    exception); a cancellation of the calling task while waiting propagates (``gather`` raises
    :class:`asyncio.CancelledError` only then: the tasks' own cancellations are results).
    """
    for task in tasks:
        task.cancel()
    results = await asyncio.gather(*tasks, return_exceptions=True)
    for task, result in zip(tasks, results, strict=True):
        if isinstance(result, Exception):  # not CancelledError (a BaseException)
            _log.warning("%s failed: %r", task.get_name(), result, exc_info=result)


async def _reap(
    process: asyncio.subprocess.Process, *, timeout: float = STOP_TIMEOUT, kill_first: bool = False
) -> int:
    """Wait for ``process`` to exit (killing it after ``timeout``); return its status."""
    if kill_first and process.returncode is None:
        with contextlib.suppress(ProcessLookupError):
            process.kill()
    if process.stdin is not None and not process.stdin.is_closing():
        process.stdin.close()
    try:
        async with asyncio.timeout(timeout):
            return await process.wait()
    except TimeoutError:
        _log.warning("emulator %d did not exit after SIGTERM; killing it", process.pid)
        with contextlib.suppress(ProcessLookupError):
            process.kill()
        return await process.wait()


@contextlib.asynccontextmanager
async def start_emulator(
    firmware: str = DEFAULT_FIRMWARE,
    time_scale: float = DEFAULT_TIME_SCALE,
    *,
    extra_args: Sequence[str] = (),
    startup_timeout: float = STARTUP_TIMEOUT,
    listen: str | None = None,
    in_process: bool = False,
) -> AsyncIterator[str]:
    """Run a virtual Mirobot for the duration of the block; yields its port URL.

    ``firmware`` is ``"2021"``, ``"classic"`` or ``"2024"``; ``time_scale`` is simulated seconds
    per wall second (0: motion completes at once, 1: real time, 100: a 10 s homing takes 0.1 s);
    ``extra_args`` go to the ``mirobot-emulator`` command line (``--baud``, ``--fault``...);
    ``listen`` is ``"pty"``, ``"tcp"`` or ``"HOST:PORT"`` (``None``: ``$MIROBOT_TEST_LINK``, else a
    pty where ptys exist).
    Startup waits at most ``startup_timeout`` s (:class:`EmulatorError`); on exit the process is
    stopped and reaped even if the block was cancelled. Use :class:`EmulatorProcess` for a
    handle with the fault-injection channel.

    ``in_process=True`` runs the firmware model inside this process instead (an
    :class:`~mirobot_async.virtual.InProcessArm` and its ``virtual://N`` URL for
    ``Mirobot.connect``): no subprocess and no pty, a test costs milliseconds; ``extra_args``
    and ``listen`` are then refused (the process's options: pacing, faults, links).
    """
    if in_process:
        if extra_args or listen is not None:
            raise MirobotUsageError(
                "start_emulator(in_process=True) takes no extra_args or listen: those are "
                "options of the emulator process"
            )
        from mirobot_async.virtual._in_process import InProcessArm

        with InProcessArm(firmware, time_scale) as arm:
            yield arm.url
        return
    emulator = await EmulatorProcess.start(
        firmware,
        time_scale,
        extra_args=extra_args,
        startup_timeout=startup_timeout,
        listen=listen,
    )
    try:
        yield emulator.url
    finally:
        await emulator.stop()
