"""What the user-flow tests of this directory share: an arm at its own speed, lent by the
session's pool (the plugin's ``mirobot_emulator_pool``), and the CLI as a child process.

``ARMS``: the emulator at ``--time-scale 1`` in both profiles.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import waiting

from mirobot_async.testing import EmulatorPool

ARMS = ("2021", "classic")
ROOT = Path(__file__).resolve().parents[2]


@contextlib.contextmanager
def arm_at_real_speed(pool: EmulatorPool, arm: str) -> Iterator[str]:
    """The port of an emulator of profile ``arm`` running at real speed, powered on."""
    with pool.lend(arm, 1.0) as emulator:
        yield emulator.url


class Spawned:
    """``python -m mirobot_async ARGS`` in its own process group (as a terminal runs it: a
    Ctrl-C there reaches the group), its output read as it comes by two threads."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "mirobot_async", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
            text=True,
            cwd=ROOT,
            start_new_session=True,
        )
        self._out: list[str] = []
        self._err: list[str] = []
        self._readers = [
            threading.Thread(target=self._read, args=(pipe, into), daemon=True)
            for pipe, into in ((self.proc.stdout, self._out), (self.proc.stderr, self._err))
        ]
        for reader in self._readers:
            reader.start()

    @staticmethod
    def _read(pipe: object, into: list[str]) -> None:
        for line in pipe:  # type: ignore[attr-defined]
            into.append(line)

    @property
    def stdout(self) -> str:
        return "".join(self._out)

    @property
    def stderr(self) -> str:
        return "".join(self._err)

    def wait_for(self, text: str, timeout: float, *, count: int = 1) -> None:
        """Return once ``text`` has appeared ``count`` times on stderr (``AssertionError`` after
        ``timeout`` s, or when the command ends first)."""

        def seen_or_ended() -> bool:
            return self.stderr.count(text) >= count or self.proc.poll() is not None

        try:
            waiting.wait_for(seen_or_ended, timeout, f"{text!r} x{count}", every=0.01)
        except AssertionError as error:
            raise AssertionError(f"{error}: {self.stderr}") from None
        if self.stderr.count(text) < count:  # ended: read what it wrote last
            for reader in self._readers:
                reader.join(5)
            if self.stderr.count(text) < count:
                raise AssertionError(
                    f"ended ({self.proc.returncode}) before {text!r}: {self.stderr}"
                )

    def interrupt(self) -> None:
        """Ctrl-C in the terminal: SIGINT to the command's process group."""
        os.killpg(self.proc.pid, signal.SIGINT)

    def finish(self, timeout: float) -> int:
        """Wait for the command to exit (killed after ``timeout`` s); its exit status."""
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise
        for reader in self._readers:
            reader.join(5)
        return self.proc.returncode

    def kill(self) -> None:
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
        for reader in self._readers:
            reader.join(5)


@contextlib.contextmanager
def spawned(*args: str) -> Iterator[Spawned]:
    """:class:`Spawned`, killed with its group if it is still running when the block ends."""
    command = Spawned(*args)
    try:
        yield command
    finally:
        command.kill()
        for pipe in (command.proc.stdout, command.proc.stderr):
            if pipe is not None:
                pipe.close()
