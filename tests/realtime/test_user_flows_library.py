"""The library's user flows at the arm's own speed: README's two examples as written (the
asyncio one on an emulator at ``time_scale=1``, the blocking one on a port, as a user with an arm
runs it), a monitor thread running through homing, and a move that lasts 20 s. Each on both
emulator profiles at ``--time-scale 1``."""

from __future__ import annotations

import asyncio
import contextlib
import re
import subprocess
import sys
import threading
import time

import pytest
from user_flow_arms import ARMS, ROOT, arm_at_real_speed
from waiting import wait_for

from mirobot_async import Mirobot, State, StatusReport
from mirobot_async.sync import Mirobot as SyncMirobot
from mirobot_async.testing import EmulatorPool

pytestmark = [pytest.mark.realtime, pytest.mark.timeout(180)]

README = ROOT / "README.md"


def python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def run_python(code: str, *args: str, timeout: float = 150) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=ROOT,
        check=False,
    )


@pytest.mark.parametrize("profile", ["2021", "classic", "2024"])
def test_readme_example_at_real_speed(profile: str) -> None:
    """The 15 lines with the virtual arm at real speed instead of 100x: homing (8-10 s of a
    search that answers no ``?``), two moves, suction, a stream that waits for the arm."""
    example = python_blocks()[0]
    fast = "start_emulator(time_scale=100)"
    assert example.count(fast) == 1, example
    done = run_python(example.replace(fast, f"start_emulator(time_scale=1, firmware={profile!r})"))
    assert done.returncode == 0, done.stderr
    assert "2 lines acknowledged" in done.stdout
    assert "StatusReport(state=<State.IDLE" in done.stdout
    assert done.stderr == ""


@pytest.mark.parametrize("arm", ARMS)
def test_readme_script_example_on_a_port(mirobot_emulator_pool: EmulatorPool, arm: str) -> None:
    """README's blocking example with the port of an arm at real speed in place of
    ``/dev/ttyUSB0``: home, a move, examples/square.gcode streamed (the call returns when the
    last line is acknowledged, the arm still drawing), then statuses until the arm is Idle."""
    example = next(block for block in python_blocks() if "mirobot_async.sync" in block)
    assert example.count('"/dev/ttyUSB0"') == 1, example
    script = example.replace('"/dev/ttyUSB0"', "sys.argv[1]")
    script = "import sys\n" + script + "print('final', report.state.value, report.joints)\n"
    with arm_at_real_speed(mirobot_emulator_pool, arm) as url:
        done = run_python(script, url)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    lines = done.stdout.splitlines()
    joints = [float(v) for v in lines[0].strip("()").split(",")]
    assert joints[0] == pytest.approx(30, abs=0.05), lines[0]  # arm.move_joints(j1=30)
    assert lines[-1].startswith("final Idle"), lines[-1]
    assert len(lines) > 3, lines  # the stream's progress, line by line


@pytest.mark.parametrize("arm", ARMS)
def test_homing_with_a_monitor_thread_running(
    mirobot_emulator_pool: EmulatorPool, arm: str
) -> None:
    """A script shows the status in a second thread (the blocking ``statuses()`` iterator)
    while the main thread homes: both calls live through the silent search, the monitor is
    still reporting after it, and its last report is the arm at rest at zero."""
    with arm_at_real_speed(mirobot_emulator_pool, arm) as url, SyncMirobot.connect(url) as bot:
        seen: list[StatusReport] = []
        failed: list[BaseException] = []
        stop = threading.Event()

        def monitor() -> None:
            try:
                for report in bot.statuses(0.2):
                    seen.append(report)
                    if stop.is_set():
                        return
            except BaseException as exc:
                failed.append(exc)

        watcher = threading.Thread(target=monitor, name="monitor")
        watcher.start()
        try:
            homed = bot.home()
            after = len(seen)
            wait_for(
                lambda: len(seen) >= after + 2 or not watcher.is_alive(),
                10,
                "two reports of the monitor after homing",
            )
            assert len(seen) >= after + 2, "the monitor stopped reporting after homing"
        finally:
            stop.set()
            watcher.join(15)
        assert not watcher.is_alive()
        assert failed == [], failed
        assert homed.state is State.IDLE and all(abs(j) < 0.05 for j in homed.joints)
        assert seen[-1].state is State.IDLE and all(abs(j) < 0.05 for j in seen[-1].joints)


@pytest.mark.parametrize("arm", ARMS)
async def test_a_move_of_twenty_seconds(mirobot_emulator_pool: EmulatorPool, arm: str) -> None:
    """J1 by 100 degrees at 300 deg/min: 20 s of motion in one ``move_joints`` call, which waits
    for it with its default timeout (no liveness verdict meanwhile: the arm answers every
    ``?`` while it moves), while another task reads the status and sees it run."""
    with arm_at_real_speed(mirobot_emulator_pool, arm) as url:
        async with Mirobot.connect(url) as bot:
            await bot.unlock()
            running: list[State] = []

            async def watch() -> None:
                async with contextlib.aclosing(bot.statuses(interval=1.0)) as reports:
                    async for report in reports:
                        running.append(report.state)

            watcher = asyncio.create_task(watch())
            try:
                start = time.monotonic()
                report = await bot.move_joints(j1=100, speed=300)
                elapsed = time.monotonic() - start
            finally:
                watcher.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await watcher
            assert report is not None and report.state is State.IDLE
            assert report.joints[0] == pytest.approx(100, abs=0.05)
            assert elapsed >= 19.5, elapsed  # the arm's own time (a loaded host only adds)
            assert running.count(State.RUN) >= 10, running  # one a second while it moved
            assert bot.stats.replies_lost == 0
