"""The same client scenarios over the emulator's pty and its TCP socket (issue 14 item 2).

Connect, home, moves, a 1000-line stream, status polling while streaming, a reset and a lost link,
each run once with ``listen="pty"`` and once with ``listen="tcp"`` (``socket://127.0.0.1:PORT``).
The whole integration suite can also be run over TCP with ``MIROBOT_TEST_LINK=tcp``; the plugin's
``--mirobot-link both`` parametrisation is checked at the end.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import subprocess
import sys
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
from waiting import wait_until

from mirobot_async import Mirobot, MirobotError, State
from mirobot_async.testing import EmulatorPool, EmulatorProcess, SyncEmulatorProcess, start_emulator

# the emulator as a process and its links: run on the link lanes (MIROBOT_TEST_LINK=pty|tcp)
pytestmark = pytest.mark.emulator_process

LINKS = ("pty", "tcp") if os.name == "posix" else ("tcp",)
HALF_STEP = 0.05  # degrees: the emulator reports whole motor steps
LOST_LIMIT = 3.0  # seconds from the emulator's death to every pending call failing (the dwell
# pending then would last 20 s, so a margin for a loaded machine proves the same)


@pytest.fixture(params=LINKS)
def link(request: pytest.FixtureRequest) -> str:
    """The emulator's link under test."""
    return str(request.param)


@pytest.fixture
async def emulator(
    link: str, mirobot_emulator_pool: EmulatorPool
) -> AsyncIterator[EmulatorProcess]:
    """A classic-profile emulator on ``link`` (classic: wait=True moves settle on whole steps),
    from the session's pool of emulator processes (renewed as a new process would be)."""
    async with mirobot_emulator_pool.lend_async("classic", 0.0, listen=link) as lent:
        yield lent


def test_url_names_the_link(emulator: EmulatorProcess, link: str) -> None:
    assert emulator.url.startswith("socket://127.0.0.1:") == (link == "tcp")


async def test_connect_home_and_moves(emulator: EmulatorProcess) -> None:
    async with Mirobot.connect(emulator.url) as arm:
        await arm.home(timeout=10)
        await arm.move_joints(j1=30, j2=10, wait=True, timeout=10)
        report = await arm.status()
        assert report.state is State.IDLE
        assert report.joints[0] == pytest.approx(30, abs=HALF_STEP)
        assert report.joints[1] == pytest.approx(10, abs=HALF_STEP)
        assert arm.pending_count == 0


async def test_stream_1000_lines_while_polling_status(emulator: EmulatorProcess) -> None:
    lines = [f"M3 S{i % 1001}" if i % 3 else "G4 P0" for i in range(1000)]
    async with Mirobot.connect(emulator.url) as arm:
        await arm.unlock()
        reports: list[Any] = []

        async def monitor() -> None:
            async with contextlib.aclosing(arm.statuses(interval=0.005)) as stream:
                async for report in stream:
                    reports.append(report)

        watcher = asyncio.create_task(monitor())
        numbers = []
        stream = arm.stream(lines)
        async with asyncio.timeout(15):
            async for result in stream:
                assert result.ok, result
                numbers.append(result.number)
        watcher.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await watcher
        assert numbers == list(range(1, 1001))
        assert stream.result.acknowledged == 1000
        assert reports, "no status report arrived while streaming"
        assert arm.stats.replies_lost == 0 and arm.stats.protocol_violations == 0
        assert (await arm.status()).pump_pwm == 998 % 1001


async def test_reset_reprints_the_banner(emulator: EmulatorProcess) -> None:
    async with Mirobot.connect(emulator.url) as arm:
        await arm.unlock()
        banner = await arm.reset()
        assert banner[-1] == "Using reset pos!"
        assert arm.stats.resets >= 1
        await arm.unlock()
        assert (await arm.status()).state is State.IDLE


async def test_lost_link_fails_pending_calls_promptly(
    link: str, mirobot_emulator_pool: EmulatorPool
) -> None:
    pool = mirobot_emulator_pool  # the killed process is stopped, not kept
    async with (
        pool.lend_async("classic", 1.0, listen=link) as emulator,  # the dwell lasts 20 s
        Mirobot.connect(emulator.url) as arm,
    ):
        await arm.unlock()
        dwell = asyncio.create_task(arm.send("G4 P20", timeout=30))
        await wait_until(lambda: arm.pending_count >= 1, 5, "the dwell written", every=0.001)
        loop = asyncio.get_running_loop()
        killed_at = loop.time()
        emulator.kill()
        with pytest.raises(MirobotError):
            async with asyncio.timeout(5):
                await dwell
        assert loop.time() - killed_at < LOST_LIMIT
        with pytest.raises(MirobotError):
            await arm.status(timeout=LOST_LIMIT)


async def test_start_emulator_over_tcp_serves_a_client() -> None:
    async with start_emulator("2021", listen="tcp") as url:
        assert url.startswith("socket://127.0.0.1:")
        async with Mirobot.connect(url) as arm:
            assert (await arm.status()).state in (State.IDLE, State.ALARM)


def test_env_chooses_the_default_link(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MIROBOT_TEST_LINK", "tcp")
    with SyncEmulatorProcess("2021") as emulator:
        assert emulator.url.startswith("socket://127.0.0.1:")


def test_plugin_runs_each_test_once_per_link(tmp_path: Path) -> None:
    (tmp_path / "test_plugin_link.py").write_text(
        "def test_link(mirobot_emulator, mirobot_link):\n"
        "    assert mirobot_emulator.startswith('socket://') == (mirobot_link == 'tcp')\n"
    )
    run = subprocess.run(
        [
            *(sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist"),
            *("--mirobot-link", "both", "-o", "addopts=", str(tmp_path)),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "2 passed" in run.stdout, run.stdout
