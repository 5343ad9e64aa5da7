"""The ``mirobot`` command line stops the arm safely and checks it first (issue 15), and reads a
program from stdin (the plots in robot time: ``test_cli.py::test_run_trace_then_plot``).

Ctrl-C / SIGTERM tests run the CLI as a subprocess against an emulator started separately, and
read the emulator through second channels the CLI does not use: its control channel (``stats``:
the bytes it received) while the CLI runs, and the serial port itself once the CLI has exited.
The commands around them, and the stdin tests but one (a real pipe), run ``main(argv)`` in this
process (the ``cli`` fixture).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
import serial
from waiting import wait_for

from mirobot_async._core.replies import State, StatusReport, parse_status
from mirobot_async.testing import EmulatorPool, SyncEmulatorProcess

pytestmark = pytest.mark.timeout(60)

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
FAST = ("--time-scale", "0")
STOP_WITHIN = 1.5
"""Seconds from the signal to the stopping byte reaching the emulator (issue 15), seen through
polls of its counters; a stop that waited for the moves queued in the arm (the dance: ~20 s at
time scale 1, several of them buffered) would come seconds later."""


def mirobot(*args: str, stdin: str | None = None) -> subprocess.CompletedProcess[str]:
    """Run the CLI to completion; if it hangs, its process group (and so its embedded
    emulator) is killed."""
    with subprocess.Popen(
        [sys.executable, "-m", "mirobot_async", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.PIPE if stdin is not None else subprocess.DEVNULL,
        text=True,
        start_new_session=True,
    ) as proc:
        try:
            out, err = proc.communicate(stdin, timeout=45)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            raise
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


Cli = Callable[..., subprocess.CompletedProcess[str]]


def spawn(*args: str) -> subprocess.Popen[str]:
    """Start the CLI in its own process group (see :func:`kill_group`)."""
    return subprocess.Popen(
        [sys.executable, "-m", "mirobot_async", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
        start_new_session=True,
    )


def kill_group(proc: subprocess.Popen[str]) -> None:
    """Kill a spawned CLI that is still running, with its embedded emulator, and reap it."""
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()


def stats(emulator: SyncEmulatorProcess) -> dict[str, int]:
    words = emulator.control("stats").split()
    return {name: int(value) for name, _, value in (w.partition("=") for w in words if "=" in w)}


def realtime_bytes(before: dict[str, int], after: dict[str, int], kind: str) -> int:
    """How many ``!`` (kind "hold") or ``%`` (kind "reset") bytes arrived between two stats,
    when no line was sent in between: every byte that is neither ``?`` nor ``%`` is a ``!``."""
    assert after["lines_in"] == before["lines_in"], "a line was sent after the signal"
    resets = after["resets_in"] - before["resets_in"]
    if kind == "reset":
        return resets
    others = after["bytes_in"] - before["bytes_in"]
    return others - (after["status_requests_in"] - before["status_requests_in"]) - resets


def statuses_over_the_port(url: str, count: int, gap: float) -> list[StatusReport]:
    """``count`` status reports read by opening the port ourselves (the CLI has exited)."""
    reports = []
    with serial.serial_for_url(url, timeout=0.05, exclusive=True) as link:
        for _ in range(count):
            link.write(b"?")
            data = b""
            deadline = time.monotonic() + 5
            while b">" not in data:
                assert time.monotonic() < deadline, f"no status reply: {data!r}"
                data += link.read(512)
            end = data.index(b">") + 1
            reports.append(parse_status(data[data.rindex(b"<", 0, end) : end]))
            time.sleep(gap)  # the measurement window: the arm must not move during it
    return reports


def moving_rows(trace: Path) -> int:
    if not trace.exists():
        return 0
    return sum(1 for line in trace.read_text().splitlines() if ",Run," in line)


@pytest.mark.parametrize(
    ("sig", "mode", "expected_state"),
    [(signal.SIGINT, "hold", State.HOLD), (signal.SIGTERM, "reset", State.ALARM)],
)
def test_a_signal_stops_the_moving_arm_at_once(
    tmp_path: Path,
    sig: signal.Signals,
    mode: str,
    expected_state: State,
    mirobot_emulator_pool: EmulatorPool,
) -> None:
    trace = tmp_path / "t.csv"
    with mirobot_emulator_pool.lend(time_scale=1) as emulator:  # dance: ~20 s at this speed
        argv = ["run", str(EXAMPLES / "dance.gcode"), "--port", emulator.url, "--unlock"]
        proc = spawn(*argv, "--trace", str(trace), "--on-interrupt", mode)
        try:
            wait_for(lambda: moving_rows(trace) >= 3, 30, "the arm to be moving")
            before = stats(emulator)
            signalled = time.monotonic()
            proc.send_signal(sig)
            wait_for(
                lambda: realtime_bytes(before, stats(emulator), mode) >= 1,
                5,
                f"the {mode} byte to reach the emulator",
            )
            took = time.monotonic() - signalled
            _, err = proc.communicate(timeout=20)
        finally:
            kill_group(proc)
        assert took < STOP_WITHIN, f"{mode} reached the arm {took:.3f} s after the signal"
        assert proc.returncode == 130, err
        assert "Traceback" not in err and "error" not in err, err
        assert realtime_bytes(before, stats(emulator), mode) == 1  # exactly one stop byte
        # The second channel: the port itself, once the CLI has let go of it.
        reports = statuses_over_the_port(emulator.url, 4, 0.1)
    assert {report.state for report in reports} == {expected_state}
    assert len({report.joints for report in reports}) == 1  # no further motion
    last_moving = [line for line in trace.read_text().splitlines() if ",Run," in line][-1]
    assert reports[0].to_line() != last_moving  # it did stop where it was, not at the end
    lines = err.splitlines()
    if mode == "hold":
        assert any("feed hold sent (!); the arm is Hold after" in line for line in lines), err
        assert "mirobot: queued moves stay in the arm until `mirobot reset` clears them" in lines
    else:
        assert any("soft reset sent (%)" in line for line in lines), err
    assert any("accepted by the arm" in line or "not sent" in line for line in lines), err


def test_ctrl_c_while_homing_stops_it_with_a_soft_reset(
    mirobot_emulator_pool: EmulatorPool,
) -> None:
    """GRBL checks only for a soft reset while it homes: Ctrl-C sends % (not !) there."""
    with mirobot_emulator_pool.lend(time_scale=1) as emulator:  # homing: seconds at this speed
        before = stats(emulator)
        proc = spawn("home", "--port", emulator.url)
        try:
            wait_for(lambda: stats(emulator)["lines_in"] > before["lines_in"], 20, "$H")
            sent = stats(emulator)
            signalled = time.monotonic()
            proc.send_signal(signal.SIGINT)
            wait_for(lambda: realtime_bytes(sent, stats(emulator), "reset") >= 1, 5, "the %")
            took = time.monotonic() - signalled
            _, err = proc.communicate(timeout=20)
        finally:
            kill_group(proc)
        assert took < STOP_WITHIN, f"% reached the arm {took:.3f} s after the signal"
        assert proc.returncode == 130, err
        assert realtime_bytes(sent, stats(emulator), "hold") == 0  # no feed hold at all
        reports = statuses_over_the_port(emulator.url, 3, 0.1)
    assert "soft reset sent (%)" in err, err
    assert {report.state for report in reports} <= {State.ALARM, State.IDLE}  # not Home
    assert len({report.joints for report in reports}) == 1  # no further motion


def test_a_held_arm_is_refused_by_the_pre_flight_check(
    cli: Cli, mirobot_emulator_pool: EmulatorPool
) -> None:
    with mirobot_emulator_pool.lend(time_scale=1) as emulator:
        program = ["M21 G90", "G0 X100"]
        assert cli("unlock", "--port", emulator.url).returncode == 0
        moving = spawn("move", "joints", "j1=100", "--port", emulator.url, "--speed", "300")
        try:
            # $X, M50; the pre-flight's lock probe and its G90; then the move
            wait_for(lambda: stats(emulator)["lines_in"] >= 5, 20, "the move to be sent")
            moving.send_signal(signal.SIGINT)
            _, err = moving.communicate(timeout=20)
        finally:
            kill_group(moving)
        assert moving.returncode == 130, err
        assert "the arm is Hold" in err
        before = stats(emulator)
        proc = cli("run", "-", "--port", emulator.url, stdin="\n".join(program))
        assert stats(emulator)["lines_in"] == before["lines_in"]  # not a line of it was sent
    assert proc.returncode == 1
    assert proc.stderr.splitlines() == [
        "mirobot: error: the arm is in Hold with moves still queued: `mirobot reset` clears "
        "them (then `mirobot home`, or pass --home)"
    ]


def test_run_reads_the_program_from_stdin(cli: Cli) -> None:
    proc = mirobot("run", "-", *FAST, stdin="; from a pipe\nM21 G90\nG0 X20 Y10 Z0 A0 B0 C0\n")
    assert proc.returncode == 0, proc.stderr
    joints = next(line for line in proc.stdout.splitlines() if line.startswith("joints"))
    j1, j2 = (float(v) for v in joints.split()[1:3])
    assert abs(j1 - 20) < 0.02 and abs(j2 - 10) < 0.02  # within a motor step
    proc = cli("run", "-", *FAST, stdin="; nothing\n")
    assert proc.returncode == 2
    assert proc.stderr.strip() == "mirobot: error: <stdin>: no commands in the input"
    proc = cli("check", "-", stdin="M21 G90\nG0 X500\n")
    assert proc.returncode == 1
    assert proc.stdout.splitlines() == ["<stdin>:2: J1=500 is outside -100..160"]
