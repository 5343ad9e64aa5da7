"""``mirobot ports``: probing emulator ptys (a 2021 one that stays quiet on open, a classic one
that resets and prints its banner on open) and a pty that answers garbage, in one command.
The emulators' counters prove the probe sent nothing but ``?`` and ``$$``."""

from __future__ import annotations

import os
import subprocess
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from mirobot_async.testing import EmulatorPool, SyncEmulatorProcess

# the emulator as a process and its links: run on the link lanes (MIROBOT_TEST_LINK=pty|tcp)
pytestmark = [pytest.mark.timeout(60), pytest.mark.emulator_process]


def stats(emulator: SyncEmulatorProcess) -> dict[str, int]:
    words = emulator.control("stats").split()
    return {name: int(value) for name, _, value in (w.partition("=") for w in words if "=" in w)}


Cli = Callable[..., subprocess.CompletedProcess[str]]


@pytest.fixture
def garbage_port() -> Iterator[str]:
    """A pty whose other end answers every byte with a line that is not a Mirobot status."""
    master, slave = os.openpty()
    device = os.ttyname(slave)
    stop = threading.Event()

    def answer() -> None:
        while not stop.is_set():
            try:
                data = os.read(master, 64)
            except OSError:
                return
            if data:
                os.write(master, b"\x00\xffAT+OK <garbage, not a status>\r\nok\r\n")

    thread = threading.Thread(target=answer, daemon=True)
    thread.start()
    try:
        yield device
    finally:
        stop.set()
        os.close(slave)  # the reader gets EIO and returns
        thread.join(timeout=5)
        os.close(master)


def test_ports_probes_emulators_and_a_garbage_port(
    garbage_port: str, cli: Cli, mirobot_emulator_pool: EmulatorPool
) -> None:
    pool = mirobot_emulator_pool  # processes renewed as new ones would be
    with (
        pool.lend(time_scale=0) as quiet,
        pool.lend("classic", time_scale=0, extra_args=["--reset-on-open"]) as booting,
    ):
        started = time.monotonic()
        devices = [quiet.url, booting.url, garbage_port]  # renewed on their return: new URLs
        proc = cli("ports", *devices, "--timeout", "1.5")
        took = time.monotonic() - started
        quiet_stats, booting_stats = stats(quiet), stats(booting)
    quiet_url, booting_url = devices[:2]
    assert proc.returncode == 0, proc.stderr  # a Mirobot answered
    rows = proc.stdout.splitlines()
    assert rows[0].split() == ["DEVICE", "VID:PID", "DESCRIPTION", "VERDICT"]
    verdicts = {row.split()[0]: row for row in rows[1:]}
    assert verdicts[quiet_url].endswith("Mirobot (Alarm), firmware 2021")
    assert verdicts[booting_url].endswith("Mirobot (Idle), firmware classic (20191228_2)")
    assert verdicts[garbage_port].endswith(
        "not a Mirobot (answers something else: no status reply to ?)"
    )
    assert took < 1.5 + 1.5 + 5  # probes run in parallel, each within its timeout (+ $$)
    # Nothing but "?" and one "$$" line (read-only) reached the emulators.
    assert quiet_stats["lines_in"] == 1  # "$$"
    assert quiet_stats["bytes_in"] == quiet_stats["status_requests_in"] + len(b"$$\n")
    assert booting_stats["lines_in"] == 0  # its banner named the firmware: no "$$"
    assert booting_stats["bytes_in"] == booting_stats["status_requests_in"]


def test_ports_with_nothing_to_probe_says_so_and_exits_1(cli: Cli) -> None:
    proc = cli("ports", "/dev/null/nothing", "--timeout", "0.2")
    assert proc.returncode == 1
    assert "cannot open" in proc.stdout
