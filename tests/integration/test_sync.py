"""The blocking facade (mirobot_async.sync.Mirobot) against the real emulator on a real pty:
in a plain script (a subprocess), from three threads at once, inside a running event loop (as in
Jupyter), interrupted by the caller, and leaving no thread behind."""

from __future__ import annotations

import asyncio
import signal
import subprocess
import sys
import textwrap
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from mirobot_async import LineResult, MirobotLinkLostError, State
from mirobot_async.sync import Mirobot
from mirobot_async.sync._loop import LOOP_THREAD_NAME
from mirobot_async.testing import EmulatorPool, SyncEmulatorProcess

pytestmark = pytest.mark.timeout(60)


def loop_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith(LOOP_THREAD_NAME)]


@pytest.fixture(scope="module")
def emulator(mirobot_emulator_pool: EmulatorPool) -> Iterator[SyncEmulatorProcess]:
    """One instant-motion emulator shared by the tests whose arm state does not matter (from
    the session's pool of emulator processes, as are the others here)."""
    with mirobot_emulator_pool.lend("2021", 0.0) as emu:
        yield emu


@pytest.fixture
def arm(emulator: SyncEmulatorProcess) -> Iterator[Mirobot]:
    with Mirobot.connect(emulator.url) as connected:
        connected.unlock()
        yield connected
    assert not loop_threads(), "close() left the loop thread running"


SCRIPT = """
    import sys, threading
    from mirobot_async.sync import Mirobot

    with Mirobot.connect(sys.argv[1]) as arm:
        arm.unlock()
        arm.home()
        report = arm.move_joints(j1=30, j2=10)
        print("joints", [round(j, 1) for j in report.joints[:2]])
        progress = []
        result = arm.stream(["G90", "M21 G01 X5 F2000", "M20 G00 X200 Y0 Z200 A0 B0 C0"],
                            on_progress=progress.append)
        print("stream", result.sent, result.acknowledged, len(progress))
        arm.wait_idle()  # the streamed moves were accepted, not finished (on a real arm)
        for number, status in enumerate(arm.statuses(0.01)):
            if number == 2:
                break
        print("state", status.state.value, "firmware", arm.detect_firmware())
    print("threads", sorted(t.name for t in threading.enumerate()))
"""


@pytest.mark.parametrize("profile", ["2021", "classic", "2024"])
def test_a_plain_script_drives_the_arm(
    tmp_path: Path, profile: str, mirobot_emulator_pool: EmulatorPool
) -> None:
    script = tmp_path / "script.py"
    script.write_text(textwrap.dedent(SCRIPT))
    with mirobot_emulator_pool.lend(profile, 0.0) as emu:
        done = subprocess.run(
            [sys.executable, str(script), emu.url],
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        )
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "joints [30.0, 10.0]"
    assert lines[1] == "stream 3 3 3"
    assert lines[2] == f"state Idle firmware {profile}"
    assert lines[3] == "threads ['MainThread']"


def test_three_threads_share_one_arm(arm: Mirobot) -> None:
    before = arm.stats.lines_acknowledged
    errors: list[BaseException] = []
    outputs: dict[int, list[object]] = {0: [], 1: [], 2: []}
    start = threading.Barrier(3)

    def work(index: int) -> None:
        try:
            start.wait(5)
            for _ in range(15):
                if index == 0:
                    outputs[index].append(arm.status().state)
                elif index == 1:
                    outputs[index].append(arm.send("G90"))
                else:
                    outputs[index].append(arm.send("M3 S0"))
        except BaseException as err:  # reported by the main thread
            errors.append(err)

    workers = [threading.Thread(target=work, args=(i,)) for i in range(3)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join(30)
    assert not any(worker.is_alive() for worker in workers)
    assert errors == []
    assert outputs[0] == [State.IDLE] * 15
    assert outputs[1] == [()] * 15
    assert outputs[2] == [()] * 15
    assert arm.stats.lines_acknowledged - before == 30
    assert arm.pending_count == 0


def test_inside_a_running_event_loop_as_in_jupyter(emulator: SyncEmulatorProcess) -> None:
    async def notebook() -> tuple[float, State]:
        # Jupyter runs cells on its own loop, in the calling thread: blocking calls still work.
        arm = Mirobot.connect(emulator.url)
        try:
            arm.unlock()
            report = arm.move_joints(j1=-15)
            await asyncio.sleep(0)  # the notebook's own loop is not disturbed
            assert report is not None
            return report.joints[0], arm.status().state
        finally:
            arm.close()

    joint, state = asyncio.run(notebook())
    assert joint == pytest.approx(-15.0, abs=0.05)  # whole motor steps
    assert state is State.IDLE
    assert not loop_threads()


def test_errors_are_the_asyncio_errors(arm: Mirobot) -> None:
    from mirobot_async import MirobotCommandError, MirobotUsageError

    with pytest.raises(MirobotUsageError):
        arm.send("G01 X1\nG01 X2")
    with pytest.raises(MirobotUsageError):
        arm.send("G999")  # refused by the client's validation, before a byte is written
    with pytest.raises(MirobotCommandError):
        arm.send("G999", validate=False)  # the firmware's own refusal
    assert arm.status().state is State.IDLE
    arm.close()
    with pytest.raises(MirobotLinkLostError, match="closed"):
        arm.status()
    assert arm.closed


def test_an_interrupt_during_a_stream_stops_sending(mirobot_emulator_pool: EmulatorPool) -> None:
    # Real-time motion, so the robot's buffer holds the stream back and lines remain unsent.
    with mirobot_emulator_pool.lend("2021", 1.0) as emu, Mirobot.connect(emu.url) as arm:
        arm.unlock()
        # the modes once, at the top: a line with M21 restarts from where the arm is
        lines = [f"{'' if i else 'M21 G91 '}G01 X{1 if i % 2 else -1} F200" for i in range(60)]
        seen: list[LineResult] = []

        def on_progress(result: LineResult) -> None:
            seen.append(result)
            if len(seen) == 2:
                raise KeyboardInterrupt  # as Ctrl-C in the calling thread would

        with pytest.raises(KeyboardInterrupt):
            arm.stream(lines, on_progress=on_progress)
        assert len(seen) == 2
        assert arm.stats.lines_sent < 40  # stopped sending; what was in flight still runs
        arm.reset()
        assert arm.status().state in (State.IDLE, State.ALARM)
    assert not loop_threads()


CTRL_C_SCRIPT = """
    import sys, threading
    from mirobot_async.sync import Mirobot

    arm = Mirobot.connect(sys.argv[1])
    arm.unlock()
    lines = [f"{'' if i else 'M21 G91 '}G01 X{1 if i % 2 else -1} F100" for i in range(200)]
    try:
        arm.stream(lines, on_progress=lambda r: print("line", r.number, flush=True))
    except KeyboardInterrupt:
        print("interrupted", arm.stats.lines_sent, arm.hold().state.value, flush=True)
    arm.close()
    print("threads", [t.name for t in threading.enumerate()], flush=True)
"""


def default_sigint() -> None:
    """In the child before it runs: SIGINT back to its default action."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_in_a_script_interrupts_a_blocking_call(
    tmp_path: Path, mirobot_emulator_pool: EmulatorPool
) -> None:
    script = tmp_path / "ctrl_c.py"
    script.write_text(textwrap.dedent(CTRL_C_SCRIPT))
    with mirobot_emulator_pool.lend("2021", 1.0) as emu:
        process = subprocess.Popen(
            [sys.executable, str(script), emu.url],
            stdout=subprocess.PIPE,
            text=True,
            # SIGINT's default action, as in a terminal (a runner started in the background
            # leaves it ignored in its children, and Python then installs no handler)
            preexec_fn=default_sigint,
        )
        try:
            assert process.stdout is not None
            assert process.stdout.readline().strip() == "line 1"
            process.send_signal(signal.SIGINT)
            out, _ = process.communicate(timeout=20)
        finally:
            if process.poll() is None:
                process.kill()
                process.communicate()
    assert process.returncode == 0
    # Progress lines printed before the signal landed may come first.
    outcome = [line for line in out.splitlines() if not line.startswith("line ")]
    words = outcome[0].split()
    assert words[0] == "interrupted" and int(words[1]) < 100 and words[2] == "Hold", out
    assert out.splitlines()[-1] == "threads ['MainThread']"
