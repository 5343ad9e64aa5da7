"""A program with an emulator process (``start_emulator``) leaves no emulator behind when it is
killed (SIGKILL, SIGHUP: no cleanup of its own runs): every emulator ``start_emulator`` starts
gets ``--exit-on-stdin-eof`` and exits when its parent's end of the pipe closes. (The CLI's
embedded arm runs in the command's own process: tests/integration/test_cli.py.)"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from waiting import wait_for


def _children(pid: int) -> list[int]:
    found: list[int] = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            found += [int(word) for word in (task / "children").read_text().split()]
        except (FileNotFoundError, ProcessLookupError):
            continue
    return found


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except (FileNotFoundError, ProcessLookupError):
        return ""


def _gone(pid: int) -> bool:
    """True once ``pid`` has exited (a zombie left for its new parent counts as gone)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return True
    return state in ("Z", "X")


pytestmark = pytest.mark.skipif(
    not Path("/proc/self/task").exists(), reason="needs /proc (Linux) to find the child"
)


def default_signal_actions() -> None:
    """In the child before it runs: SIGINT and SIGHUP back to their default actions."""
    for sig in (signal.SIGINT, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)


USER_PROGRAM = """
import asyncio
from mirobot_async import Mirobot
from mirobot_async.testing import start_emulator

async def main():
    async with start_emulator(time_scale=0) as url, Mirobot.connect(url) as arm:
        async for _ in arm.statuses(0.05):  # until it is killed
            pass

asyncio.run(main())
"""


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGHUP])
def test_a_killed_program_leaves_no_emulator(sig: signal.Signals) -> None:
    cli = subprocess.Popen(
        [sys.executable, "-c", USER_PROGRAM],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        # the signal's default action, as for a command run from a terminal (a runner started
        # with nohup, or in the background, would leave SIGHUP/SIGINT ignored in its children)
        preexec_fn=default_signal_actions,
    )
    emulator = 0
    try:

        def emulator_child() -> int:
            for child in _children(cli.pid):
                if "mirobot_emulator" in _cmdline(child):
                    return child
            return 0

        emulator = wait_for(emulator_child, 60, "embedded emulator")
        os.kill(cli.pid, sig)
        cli.wait(30)
        wait_for(lambda: _gone(emulator), 30, "exit of the orphaned emulator")
    finally:
        if cli.poll() is None:
            cli.kill()
            cli.wait()
        if emulator and not _gone(emulator):
            os.kill(emulator, signal.SIGKILL)
