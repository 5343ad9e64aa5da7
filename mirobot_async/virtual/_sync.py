"""The emulator driven without asyncio: :class:`SyncEmulatorProcess` and :func:`run_emulator`
(used by the pytest fixtures and by scripts without an event loop)."""

from __future__ import annotations

import contextlib
import logging
import queue
import signal
import subprocess
import threading
from collections.abc import Iterator, Sequence

from mirobot_async.errors import MirobotTimeoutError
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

__all__ = ["SyncEmulatorProcess", "run_emulator"]

_log = logging.getLogger("mirobot_async.virtual")


class SyncEmulatorProcess:
    """A running emulator subprocess driven without asyncio (used by the pytest fixtures).

    ``url``, :meth:`control`, :meth:`kill` and :meth:`stop` as in :class:`EmulatorProcess`, but
    blocking (with timeouts). A daemon thread drains the emulator's stdout (plain blocking
    reads: portable, no ``selectors`` on pipes, which Windows lacks).
    """

    def __init__(
        self,
        firmware: str = DEFAULT_FIRMWARE,
        time_scale: float = DEFAULT_TIME_SCALE,
        *,
        extra_args: Sequence[str] = (),
        startup_timeout: float = STARTUP_TIMEOUT,
        listen: str | None = None,
    ) -> None:
        self.command = tuple(emulator_command(firmware, time_scale, extra_args, listen))
        self._replies: queue.Queue[str | None] = queue.Queue()
        self._first: queue.Queue[bytes] = queue.Queue()
        self._control_lock = threading.Lock()
        self._cut = False  # killed, stopped, or its port closed by a close fault
        self._process = subprocess.Popen(
            self.command,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            start_new_session=True,  # a terminal's Ctrl-C reaches only the program that owns it
        )
        self._thread = threading.Thread(
            target=self._drain, name=f"mirobot-emulator-stdout-{self.pid}", daemon=True
        )
        self._thread.start()
        try:
            self.url = self._first_line(startup_timeout)
        except BaseException:
            self._process.kill()
            self._finish(STOP_TIMEOUT)
            self._thread.join(STOP_TIMEOUT)
            if self._process.stdout is not None:
                self._process.stdout.close()
            raise

    def _first_line(self, timeout: float) -> str:
        try:
            first = self._first.get(timeout=timeout)
        except queue.Empty as err:
            raise EmulatorError(f"the emulator printed no port path within {timeout:g} s") from err
        url = first.decode("utf-8", "replace").strip()
        if not url:
            raise EmulatorError(
                f"the emulator exited before printing its port path: {' '.join(self.command)}"
            )
        return url

    def _drain(self) -> None:
        stdout = self._process.stdout
        assert stdout is not None
        first = True
        try:
            while raw := stdout.readline():
                if first:
                    first = False
                    self._first.put(raw)
                    continue
                reply = control_reply(raw)
                if reply is not None:
                    self._replies.put(reply)
        except (OSError, ValueError):  # pragma: no cover - pipe closed under us
            pass
        finally:
            if first:
                self._first.put(b"")
            self._replies.put(None)

    @property
    def pid(self) -> int:
        """The emulator's process id."""
        return self._process.pid

    @property
    def returncode(self) -> int | None:
        """The exit status once the process has exited, else ``None``."""
        return self._process.poll()

    def control(self, command: str, *, timeout: float = CONTROL_TIMEOUT) -> str:
        """Send a control command; return its ``ack`` line (as :meth:`EmulatorProcess.control`)."""
        text = control_text(command)
        with self._control_lock:
            stdin = self._process.stdin
            if stdin is None or stdin.closed or self._process.poll() is not None:
                raise EmulatorError(f"cannot send {text!r}: the emulator is not running")
            try:
                stdin.write(text.encode("utf-8") + b"\n")
                stdin.flush()
            except OSError as err:
                raise EmulatorError(f"cannot send {text!r}: {err}") from err
            try:
                reply = self._replies.get(timeout=timeout)
            except queue.Empty as err:
                raise MirobotTimeoutError(f"the emulator's answer to {text!r}", timeout) from err
            if reply is None:
                self._replies.put(None)  # keep reporting the end to later calls
            if text.split()[0].lower() == "close":
                self._cut = True  # the port is gone and the process is on its way out
            return control_result(text, reply)

    def renew(
        self,
        firmware: str = DEFAULT_FIRMWARE,
        time_scale: float = DEFAULT_TIME_SCALE,
        *,
        extra_args: Sequence[str] = (),
        timeout: float = CONTROL_TIMEOUT,
    ) -> str:
        """Make the running emulator what a new one started with these settings would be; return
        its new port URL (also in :attr:`url`; :attr:`command` becomes the new settings').

        The emulator drops its port (a connected client, bytes in flight both ways) for a new
        one, powers a fresh firmware model on, arms only the faults of ``extra_args`` and zeroes
        its counters, in milliseconds instead of a process start. ``extra_args`` cannot name
        ``--listen`` or ``--link`` (a new process's business). Raises :class:`EmulatorError` if
        it refuses or has exited, :class:`MirobotTimeoutError` after ``timeout`` s.
        """
        text = renew_text(firmware, time_scale, extra_args)
        url = renewed_url(self.control(text, timeout=timeout))
        self.url = url
        self.command = tuple(renewed_command(self.command, firmware, time_scale, extra_args))
        return url

    @property
    def reusable(self) -> bool:
        """True while the process runs and was neither killed, stopped nor cut by ``close``
        (then :meth:`renew` can make it as good as new)."""
        return not self._cut and self._process.poll() is None

    def kill(self) -> None:
        """SIGKILL the emulator now (like a pulled cable); does not wait."""
        self._cut = True
        if self._process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self._process.kill()

    def stop(self, timeout: float = STOP_TIMEOUT) -> int:
        """SIGTERM, wait up to ``timeout`` s, SIGKILL; close the pipes. Idempotent."""
        self._cut = True
        if self._process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self._process.send_signal(signal.SIGTERM)
        returncode = self._finish(timeout)
        self._thread.join(timeout)
        if self._process.stdout is not None:
            self._process.stdout.close()
        return returncode

    def _finish(self, timeout: float) -> int:
        process = self._process
        if process.stdin is not None and not process.stdin.closed:
            with contextlib.suppress(OSError):
                process.stdin.close()
        try:
            return process.wait(timeout)
        except subprocess.TimeoutExpired:
            _log.warning("emulator %d did not exit after SIGTERM; killing it", process.pid)
            process.kill()
            return process.wait()

    def __enter__(self) -> SyncEmulatorProcess:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()


@contextlib.contextmanager
def run_emulator(
    firmware: str = DEFAULT_FIRMWARE,
    time_scale: float = DEFAULT_TIME_SCALE,
    *,
    extra_args: Sequence[str] = (),
    startup_timeout: float = STARTUP_TIMEOUT,
    listen: str | None = None,
) -> Iterator[SyncEmulatorProcess]:
    """Synchronous twin of :func:`start_emulator`, yielding the :class:`SyncEmulatorProcess`."""
    emulator = SyncEmulatorProcess(
        firmware, time_scale, extra_args=extra_args, startup_timeout=startup_timeout, listen=listen
    )
    try:
        yield emulator
    finally:
        emulator.stop()
