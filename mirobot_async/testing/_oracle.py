"""The vendor's firmware as the arm of a test: :class:`SyncOracleProcess` (the ``oracle`` link).

The firmware oracle is the WLKATA Mirobot's own firmware (classic, ``20191228_2``) running
unmodified in an AVR simulator, kept outside this project (GPLv3: it is only ever started as a
separate process and talked to over its pty, a black box). ``$MIROBOT_ORACLE_SOURCE`` names its
folder (the one holding ``run.sh``); ``run.sh`` finds the build (``$MIROBOT_ORACLE_DIR``).

A :class:`SyncOracleProcess` is a new firmware process powered on (its boot banner read to its
last line, so nothing sent afterwards is lost), handed out where an emulator would be: same
``url``, ``pid``, :meth:`kill` and :meth:`stop`. It has no fault-injection channel:
:meth:`control` and :meth:`renew` raise :class:`OracleUnsupportedError`, which the pytest
plugin turns into a skip (the test needs the emulator). It starts in about 0.1 s, so it is
never pooled: every borrower gets a fresh power-on.
"""

from __future__ import annotations

import contextlib
import os
import selectors
import signal
import subprocess
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from mirobot_async.testing._control import (
    CONTROL_TIMEOUT,
    DEFAULT_FIRMWARE,
    DEFAULT_TIME_SCALE,
    STOP_TIMEOUT,
    EmulatorError,
    OracleUnsupportedError,
)
from mirobot_async.testing._sync import SyncEmulatorProcess

__all__ = ["ORACLE_FIRMWARE", "ORACLE_SOURCE_ENV", "SyncOracleProcess", "oracle_command"]

ORACLE_SOURCE_ENV = "MIROBOT_ORACLE_SOURCE"
"""Environment variable naming the firmware oracle's folder (the one holding ``run.sh``)."""
ORACLE_FIRMWARE = "classic"
"""The one profile the oracle runs: the vendor's classic firmware."""
BANNER_END = b"Using reset pos!\r\n"
"""The last line of the firmware's power-on banner: bytes sent before it are lost."""
ORACLE_STARTUP_TIMEOUT = 20.0
"""Seconds for the pty path and the banner (about 0.1 s on an idle machine)."""


def oracle_command(time_scale: float) -> list[str]:
    """The argument vector of a firmware oracle at ``time_scale`` (0: as fast as the host can,
    about 5-7x real time; 1: real time). Raises :class:`EmulatorError` when
    ``$MIROBOT_ORACLE_SOURCE`` names no folder with ``run.sh``."""
    source = os.environ.get(ORACLE_SOURCE_ENV, "")
    run = Path(source) / "run.sh"
    if not source or not run.is_file():
        raise EmulatorError(
            f"the firmware oracle is not here: set {ORACLE_SOURCE_ENV} to its folder (with "
            f"run.sh; now {source!r}) and build it with its build.sh"
        )
    scale = float(time_scale)
    return [str(run), "-s", "0" if scale == 0 else repr(scale)]


def beyond_the_wire(extra_args: Sequence[str]) -> list[str]:
    """The emulator options in ``extra_args`` other than those that only make its link like the
    arm's: ``--baud 115200`` (the simulated UART runs at it) and ``--usb-latency-ms N`` (the
    oracle's pty has no USB adapter to delay it)."""
    rest: list[str] = []
    words = list(extra_args)
    while words:
        word = words.pop(0)
        name, equals, value = word.partition("=")
        if name in ("--baud", "--usb-latency-ms"):
            value = value if equals else (words.pop(0) if words else "")
            if name == "--usb-latency-ms" or value == "115200":
                continue
            rest += [name, value]
            continue
        rest.append(word)
    return rest


def check_oracle_settings(firmware: str, time_scale: float, extra_args: Sequence[str]) -> None:
    """:class:`OracleUnsupportedError` unless the oracle can be what these emulator settings
    ask for (the classic profile, no emulator options but those of the arm's own link)."""
    if firmware != ORACLE_FIRMWARE:
        raise OracleUnsupportedError(
            f"the firmware oracle is the {ORACLE_FIRMWARE} firmware, not {firmware!r}"
        )
    options = beyond_the_wire(extra_args)
    if options:
        raise OracleUnsupportedError(
            f"the firmware oracle has no emulator options ({' '.join(options)})"
        )
    if not float(time_scale) >= 0:
        raise OracleUnsupportedError(f"time_scale={time_scale!r} must be >= 0")


class SyncOracleProcess(SyncEmulatorProcess):
    """A firmware oracle process, powered on and past its banner, in place of an emulator.

    ``url`` is its pty; :meth:`kill` pulls the cable (SIGKILL), :meth:`stop` stops it (SIGTERM,
    then SIGKILL after ``timeout`` s). Never reusable. :meth:`control` and :meth:`renew` raise
    :class:`OracleUnsupportedError`.
    """

    def __init__(
        self,
        firmware: str = ORACLE_FIRMWARE,
        time_scale: float = DEFAULT_TIME_SCALE,
        *,
        extra_args: Sequence[str] = (),
        startup_timeout: float = ORACLE_STARTUP_TIMEOUT,
        listen: str | None = None,
    ) -> None:
        # Not SyncEmulatorProcess.__init__: no control channel to drain.
        check_oracle_settings(firmware, time_scale, extra_args)
        del listen  # always its own pty
        self.command = tuple(oracle_command(time_scale))
        self._cut = False
        self._stderr = tempfile.TemporaryFile()  # noqa: SIM115 - closed by stop()
        self._process = subprocess.Popen(
            self.command,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=self._stderr,
            start_new_session=True,  # a terminal's Ctrl-C reaches only the program that owns it
        )
        try:
            self.url = self._power_on(startup_timeout)
        except BaseException:
            self._process.kill()
            self._finish(STOP_TIMEOUT)
            self._close_pipes()
            raise

    def _power_on(self, timeout: float) -> str:
        """Read the pty path, open the pty (the MCU powers on) and read the banner to its last
        line, then close it: the firmware keeps running, and the next opener is the client."""
        deadline = time.monotonic() + timeout
        stdout = self._process.stdout
        assert stdout is not None
        with selectors.DefaultSelector() as selector:
            selector.register(stdout, selectors.EVENT_READ)
            if not selector.select(timeout):
                raise EmulatorError(self._failure(f"printed no pty path within {timeout:g} s"))
        path = stdout.readline().decode("utf-8", "replace").strip()
        if not path.startswith("/"):
            raise EmulatorError(self._failure(f"printed no pty path ({path!r})"))
        import termios
        import tty

        fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            tty.setraw(fd, termios.TCSANOW)
            banner = bytearray()
            with selectors.DefaultSelector() as selector:
                selector.register(fd, selectors.EVENT_READ)
                while BANNER_END not in banner:
                    left = deadline - time.monotonic()
                    if left <= 0:
                        raise EmulatorError(
                            self._failure(f"no power-on banner within {timeout:g} s: {banner!r}")
                        )
                    if selector.select(min(left, 0.1)):
                        with contextlib.suppress(BlockingIOError):
                            banner += os.read(fd, 4096)
        finally:
            os.close(fd)
        return path

    def _failure(self, what: str) -> str:
        self._stderr.seek(0)
        said = self._stderr.read().decode("utf-8", "replace").strip()[-2000:]
        return f"the firmware oracle ({' '.join(self.command)}) {what}" + (
            f"; it said: {said}" if said else ""
        )

    def control(self, command: str, *, timeout: float = CONTROL_TIMEOUT) -> str:
        """Always :class:`OracleUnsupportedError`: the real firmware has no fault channel."""
        raise OracleUnsupportedError(
            f"needs the emulator's control channel ({command.split()[0] if command else ''!r}); "
            "the firmware oracle has none"
        )

    def renew(
        self,
        firmware: str = DEFAULT_FIRMWARE,
        time_scale: float = DEFAULT_TIME_SCALE,
        *,
        extra_args: Sequence[str] = (),
        timeout: float = CONTROL_TIMEOUT,
    ) -> str:
        """Always :class:`OracleUnsupportedError` (a new oracle process is the way to renew)."""
        raise OracleUnsupportedError("needs the emulator's renew; the firmware oracle has none")

    @property
    def reusable(self) -> bool:
        """Never: an oracle is a new process for every borrower (it starts in about 0.1 s)."""
        return False

    def stop(self, timeout: float = STOP_TIMEOUT) -> int:
        """SIGTERM, wait up to ``timeout`` s, SIGKILL. Idempotent."""
        self._cut = True
        if self._process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self._process.send_signal(signal.SIGTERM)
        returncode = self._finish(timeout)
        self._close_pipes()
        return returncode

    def _close_pipes(self) -> None:
        if self._process.stdout is not None:
            self._process.stdout.close()
        self._stderr.close()
