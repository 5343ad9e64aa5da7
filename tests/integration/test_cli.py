"""The ``mirobot`` command line: ``main(argv)`` in this process, and as a user runs it.

Most tests run ``mirobot_async._cli.main(argv)`` in the test's process (the ``cli`` fixture:
stdout and stderr captured at the file descriptors, so an embedded emulator's output is seen
too, as in a terminal): the subcommands' logic without an interpreter start per command. The
entry point itself (``python -m mirobot_async``: exit statuses 0, 1, 2 and 130, signals, Ctrl-C,
README's first command, the example scripts) runs as subprocesses (``mirobot``, ``spawn``).

Every subcommand runs twice: against the embedded virtual Mirobot (no ``--port``: the command
starts and stops its own emulator) and against an emulator started separately (``--port``): one
started by ``python -m mirobot_async emulator`` (the ``emulator`` subcommand) for the whole module,
and one classic-profile emulator lent by the session's pool of emulator processes (the
plugin's ``mirobot_emulator_pool``: a process renewed as a new one would be), as are the
emulators of single tests.
Error paths check the exit status and that the error is one line without a traceback.
Waits are conditions with deadlines; every process is stopped and reaped.
"""

from __future__ import annotations

import contextlib
import csv
import math
import os
import re
import selectors
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import psutil
import pytest
import serial
from waiting import wait_for

from mirobot_async._cli.plotting import read_trace
from mirobot_async.testing import EmulatorPool, SyncEmulatorProcess

pytestmark = pytest.mark.timeout(60)

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
TRACE_HEADER = ["timestamp", "state", "j1", "j2", "j3", "j4", "j5", "j6", "rail"]
TRACE_HEADER += ["x", "y", "z", "rx", "ry", "rz", "pump", "valve", "time_scale"]
FAST = ("--time-scale", "0")  # every move of the embedded emulator completes at once
LOCKED = "the arm is locked: run `mirobot home` or pass --home"
LOCKED_PROBED = (
    "the arm is locked (a zero-length move got 'Locked status of each axis!'): "
    "run `mirobot home` or pass --home"
)


def emulator_stats(emulator: SyncEmulatorProcess) -> dict[str, int]:
    """The emulator's wire counters (its ``stats`` control command)."""
    words = emulator.control("stats").split()
    return {name: int(value) for name, _, value in (w.partition("=") for w in words if "=" in w)}


def mirobot(
    *args: str, cwd: Path | None = None, timeout: float = 45, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    """Run ``python -m mirobot_async ARGS`` to completion. In its own process group: if it
    hangs, the group (the CLI and its embedded emulator) is killed, not only the CLI."""
    with subprocess.Popen(
        [sys.executable, "-m", "mirobot_async", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=cwd,
        env=env,
        stdin=subprocess.DEVNULL,
        start_new_session=True,
    ) as proc:
        try:
            out, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            kill_group(proc)
            raise
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


Cli = Callable[..., subprocess.CompletedProcess[str]]


def spawn(*args: str, cwd: Path | None = None) -> subprocess.Popen[str]:
    """Start ``python -m mirobot_async ARGS`` in its own process group, as a terminal runs a
    command (a Ctrl-C there reaches every process of the group; :func:`kill_group` too)."""
    return subprocess.Popen(
        [sys.executable, "-m", "mirobot_async", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
        cwd=cwd,
        start_new_session=True,
    )


def kill_group(proc: subprocess.Popen[str]) -> None:
    """Kill a spawned CLI that is still running, with its embedded emulator, and reap it.

    The emulator runs in a session of its own (a terminal's Ctrl-C reaches only the CLI), so it
    is killed as the CLI's descendant, not through the CLI's process group."""
    if proc.poll() is None:
        with contextlib.suppress(psutil.NoSuchProcess):
            for child in psutil.Process(proc.pid).children(recursive=True):
                with contextlib.suppress(psutil.NoSuchProcess):
                    child.kill()
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()


def assert_clean(proc: subprocess.CompletedProcess[str]) -> None:
    assert "Traceback" not in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stdout, proc.stdout


def error_line(proc: subprocess.CompletedProcess[str]) -> str:
    """The one ``mirobot: error:`` line of a failed command (and nothing after it)."""
    assert_clean(proc)
    errors = [line for line in proc.stderr.splitlines() if "error" in line.lower()]
    assert len(errors) == 1, proc.stderr
    assert errors[0].startswith("mirobot: error: "), proc.stderr
    assert proc.stderr.rstrip("\n").endswith(errors[0])
    return errors[0]


@dataclass
class Status:
    state: str
    joints: list[float]
    pose: list[float]
    pump: int
    valve: int


def parse_table(stdout: str) -> Status:
    """The status table printed by status/home/move/run...: the last one in ``stdout``."""
    lines = stdout.splitlines()
    start = max(i for i, line in enumerate(lines) if line.startswith("state "))
    table = lines[start : start + 7]
    pwm = table[5].replace(",", "").split()
    return Status(
        state=table[0].split()[1],
        joints=[float(v) for v in table[2].split()[1:7]],
        pose=[float(v) for v in table[4].split()[1:]],
        pump=int(pwm[2]),
        valve=int(pwm[4]),
    )


def read_csv(path: Path) -> list[list[str]]:
    with path.open(newline="") as file:
        return list(csv.reader(file))


def close_to(actual: list[float], expected: list[float], tol: float = 0.05) -> bool:
    """Within ``tol`` (default half a motor step: the emulator reports whole steps)."""
    return all(abs(a - e) <= tol for a, e in zip(actual, expected, strict=True))


# --------------------------------------------------------------------------------------------
# Emulators started separately


class CliEmulator:
    """``python -m mirobot_async emulator ...``: the port path is its first stdout line."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "mirobot_async", "emulator", *args],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        assert self.proc.stdout is not None
        data = b""
        deadline = time.monotonic() + 20
        with selectors.DefaultSelector() as selector:
            selector.register(self.proc.stdout, selectors.EVENT_READ)
            while b"\n" not in data:
                left = deadline - time.monotonic()
                assert left > 0, "the emulator printed no port path"
                if selector.select(left):
                    chunk = os.read(self.proc.stdout.fileno(), 1)
                    assert chunk, "the emulator exited before printing its port path"
                    data += chunk
        self.url = data.decode().strip()

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            status = self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            status = self.proc.wait()
        for pipe in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            if pipe is not None:
                pipe.close()
        return status


@pytest.fixture(scope="module")
def port() -> Iterator[str]:
    """A 2021 emulator started with ``mirobot emulator`` for the whole module (time scale 0)."""
    emulator = CliEmulator("--time-scale", "0")
    try:
        assert emulator.url.startswith("/dev/")
        yield emulator.url
    finally:
        assert emulator.stop() == 0  # SIGTERM: a clean exit


@pytest.fixture(scope="module")
def classic_port(mirobot_emulator_pool: EmulatorPool) -> Iterator[str]:
    """A classic-profile emulator from the testing helper's pool (time scale 0)."""
    with mirobot_emulator_pool.lend("classic", 0) as emulator:
        yield emulator.url


# --------------------------------------------------------------------------------------------
# status, home, unlock, reset


def test_status_embedded_says_so_on_stderr() -> None:
    proc = mirobot("status", *FAST)
    assert proc.returncode == 0, proc.stderr
    assert_clean(proc)
    assert "no --port given; using an embedded virtual Mirobot (firmware 2021, time-scale 0)" in (
        proc.stderr
    )
    status = parse_table(proc.stdout)
    assert status.state == "Alarm"  # the 2021 firmware powers on in Alarm
    assert close_to(status.pose, [198.67, 0, 230.72, 0, 0, 0])
    assert "J1" in proc.stdout and "rail" in proc.stdout and "mode" in proc.stdout


def test_status_embedded_classic(cli: Cli) -> None:
    proc = cli("status", "--firmware", "classic")
    assert proc.returncode == 0, proc.stderr
    assert "firmware classic, time-scale 10" in proc.stderr
    status = parse_table(proc.stdout)
    assert status.state == "Idle"
    assert close_to(status.pose, [202, 0, 181, 0, 0, 0])


def test_status_on_a_port(cli: Cli, port: str) -> None:
    proc = cli("status", "--port", port)
    assert proc.returncode == 0, proc.stderr
    assert_clean(proc)
    assert "embedded" not in proc.stderr
    assert parse_table(proc.stdout).state in ("Alarm", "Idle")


def test_verbose_shows_the_wire_traffic(cli: Cli, port: str) -> None:
    proc = cli("status", "--port", port, "-v")
    assert proc.returncode == 0, proc.stderr
    assert "-> ?" in proc.stderr
    assert "<- <" in proc.stderr  # the status line as received
    quiet = cli("status", "--port", port)
    assert "->" not in quiet.stderr


@pytest.mark.parametrize("sequential", [False, True])
def test_home_embedded(cli: Cli, sequential: bool) -> None:
    proc = cli("home", *FAST, *(["--sequential"] if sequential else []))
    assert proc.returncode == 0, proc.stderr
    status = parse_table(proc.stdout)
    assert status.state == "Idle"
    assert close_to(status.joints, [0] * 6)


def test_home_unlock_reset_on_a_port(cli: Cli, port: str) -> None:
    proc = cli("reset", "--port", port)
    assert proc.returncode == 0, proc.stderr
    assert parse_table(proc.stdout).state == "Alarm"  # 2021: locked again after a reset
    proc = cli("unlock", "--port", port)
    assert proc.returncode == 0, proc.stderr
    assert parse_table(proc.stdout).state == "Idle"
    proc = cli("home", "--port", port)
    assert proc.returncode == 0, proc.stderr
    status = parse_table(proc.stdout)
    assert status.state == "Idle" and close_to(status.joints, [0] * 6)


def test_unlock_and_reset_embedded(cli: Cli) -> None:
    proc = cli("unlock", *FAST)
    assert proc.returncode == 0, proc.stderr
    assert parse_table(proc.stdout).state == "Idle"
    proc = cli("reset", *FAST)
    assert proc.returncode == 0, proc.stderr
    assert parse_table(proc.stdout).state == "Alarm"


# --------------------------------------------------------------------------------------------
# move, pump, gripper


def test_move_joints_embedded_homes_first(cli: Cli) -> None:
    proc = cli("move", "joints", "j1=30", "j2=10", "J6=-45", *FAST)
    assert proc.returncode == 0, proc.stderr
    assert "homing the virtual Mirobot first" in proc.stderr
    status = parse_table(proc.stdout)
    assert status.state == "Idle"
    assert close_to(status.joints, [30, 10, 0, 0, 0, -45])


def test_move_joints_relative_with_speed_on_a_port(cli: Cli, port: str) -> None:
    proc = cli("move", "joints", "j1=0", "j3=5", "--port", port, "--home")
    assert proc.returncode == 0, proc.stderr
    proc = cli("move", "joints", "j1=10", "j3=-5", "--relative", "--speed", "2000", "--port", port)
    assert proc.returncode == 0, proc.stderr
    assert "homing" not in proc.stderr  # never implicitly on a real port
    assert close_to(parse_table(proc.stdout).joints, [10, 0, 0, 0, 0, 0])


def test_move_pose_linear_embedded(cli: Cli) -> None:
    proc = cli("move", "pose", "x=200", "y=50", "z=150", "--linear", *FAST)
    assert proc.returncode == 0, proc.stderr
    status = parse_table(proc.stdout)
    assert close_to(status.pose[:3], [200, 50, 150], tol=0.1)


def test_move_pose_on_a_port(cli: Cli, port: str) -> None:
    proc = cli("move", "pose", "x=220", "y=-40", "z=120", "--port", port, "--home")
    assert proc.returncode == 0, proc.stderr
    assert close_to(parse_table(proc.stdout).pose[:3], [220, -40, 120], tol=0.1)
    proc = cli("move", "pose", "z=20", "--relative", "--linear", "--speed", "1000", "--port", port)
    assert proc.returncode == 0, proc.stderr
    assert close_to(parse_table(proc.stdout).pose[:3], [220, -40, 140], tol=0.1)


def test_move_refused_while_locked_exits_1(cli: Cli) -> None:
    proc = cli("move", "joints", "j1=30", "--no-home", *FAST)
    assert proc.returncode == 1
    assert error_line(proc) == "mirobot: error: " + LOCKED


def test_move_to_an_unreachable_pose_exits_1_with_the_firmware_words(cli: Cli) -> None:
    proc = cli("move", "pose", "x=900", *FAST)
    assert proc.returncode == 1
    line = error_line(proc)
    assert "not executed (unreachable)" in line
    assert "OUT OF WORKSPACE" in line  # the firmware's own words


@pytest.mark.parametrize(
    ("argv", "pump", "valve"),
    [
        (["pump", "on"], 1000, 0),
        (["pump", "blow"], 500, 0),
        (["pump", "off"], 0, 0),
        (["gripper", "open"], 40, 0),
        (["gripper", "close"], 60, 0),
        (["gripper", "close", "--legacy"], 0, 40),
    ],
)
def test_pump_and_gripper_embedded(cli: Cli, argv: list[str], pump: int, valve: int) -> None:
    proc = cli(*argv, *FAST)
    assert proc.returncode == 0, proc.stderr
    assert "unlocking the virtual Mirobot first" in proc.stderr
    status = parse_table(proc.stdout)
    assert (status.pump, status.valve) == (pump, valve)


def test_pump_and_gripper_on_a_port(cli: Cli, port: str) -> None:
    proc = cli("pump", "blow", "--port", port, "--unlock")
    assert proc.returncode == 0, proc.stderr
    assert parse_table(proc.stdout).pump == 500
    proc = cli("gripper", "open", "--legacy", "--port", port)
    assert proc.returncode == 0, proc.stderr
    status = parse_table(proc.stdout)
    assert (status.pump, status.valve) == (500, 65)
    proc = cli("pump", "off", "--port", port)
    assert parse_table(proc.stdout).pump == 0


# --------------------------------------------------------------------------------------------
# run


def test_readme_command_runs_pick_and_place_in_seconds() -> None:
    """``mirobot run examples/pick_and_place.gcode`` as README's first command: default speed."""
    started = time.monotonic()
    proc = mirobot("run", "examples/pick_and_place.gcode", cwd=ROOT)
    elapsed = time.monotonic() - started
    assert proc.returncode == 0, proc.stderr
    assert_clean(proc)
    assert elapsed < 15
    assert "using an embedded virtual Mirobot" in proc.stderr
    assert "homing the virtual Mirobot first" in proc.stderr
    progress = [line for line in proc.stderr.splitlines() if line.startswith("[")]
    assert progress, proc.stderr
    assert "\r" not in proc.stderr  # not a terminal: plain lines
    assert progress[-1].startswith("[##############################] 14/14 lines 100%")
    assert "elapsed" in progress[-1] and progress[-1].endswith("done")
    assert any("ETA" in line for line in progress)
    status = parse_table(proc.stdout)
    assert status.state == "Idle"
    assert close_to(status.pose, [200, 0, 230, 0, 0, 0], tol=0.1)
    assert status.pump == 0


@pytest.mark.parametrize("example", ["square.gcode", "dance.gcode"])
def test_run_the_other_examples_on_a_port(cli: Cli, port: str, example: str) -> None:
    proc = cli("run", str(EXAMPLES / example), "--port", port, "--home")
    assert proc.returncode == 0, proc.stderr
    assert parse_table(proc.stdout).state == "Idle"


def test_run_on_a_classic_port(cli: Cli, classic_port: str) -> None:
    proc = cli("run", str(EXAMPLES / "pick_and_place.gcode"), "--port", classic_port, "--home")
    assert proc.returncode == 0, proc.stderr
    assert close_to(parse_table(proc.stdout).pose[:3], [200, 0, 230], tol=0.1)


def test_run_stops_at_a_refused_line(cli: Cli, tmp_path: Path) -> None:
    program = tmp_path / "bad.gcode"
    program.write_text("; a program with a typo\nM21 G90\nG0 X10\n\nG7 X1 ; no such G code\n")
    proc = cli("run", "bad.gcode", "--no-check", *FAST, cwd=tmp_path)
    assert proc.returncode == 1
    assert_clean(proc)
    # refused by the robot, or by the client's check before sending: either way named
    refused = [line for line in proc.stderr.splitlines() if line.startswith("bad.gcode:5: G7 X1: ")]
    assert len(refused) == 1 and "Unsupported command" in refused[0], proc.stderr
    assert "1 line was refused" in proc.stderr
    assert parse_table(proc.stdout).state == "Idle"  # the final status is still shown


def test_run_and_move_on_a_locked_arm_send_nothing_and_say_so_once(
    cli: Cli, tmp_path: Path, mirobot_emulator_pool: EmulatorPool
) -> None:
    """Pre-flight: one line, exit 1, and not a byte of the program on the wire."""
    program = tmp_path / "p.gcode"
    program.write_text("M21 G90 G0 X10\nG0 X20\nG0 X30\n")
    with mirobot_emulator_pool.lend(time_scale=0) as emulator:  # powers on locked (Alarm)
        for argv in (["run", str(program)], ["move", "joints", "j1=10"]):
            before = emulator_stats(emulator)
            proc = cli(*argv, "--port", emulator.url)  # a real port: no implicit homing
            assert proc.returncode == 1
            assert error_line(proc) == "mirobot: error: " + LOCKED
            assert proc.stdout == ""
            after = emulator_stats(emulator)
            assert after["lines_in"] == before["lines_in"]  # not one line was sent
            sent = after["bytes_in"] - before["bytes_in"]
            assert sent == after["status_requests_in"] - before["status_requests_in"]  # only "?"


@pytest.mark.parametrize("firmware", ["classic", "2021"])
def test_run_on_an_arm_locked_in_idle_is_refused_before_its_first_motion_line(
    cli: Cli, tmp_path: Path, mirobot_emulator_pool: EmulatorPool, firmware: str
) -> None:
    """The status does not show the lock (classic after power-on, 2021 after ``$X``): the
    pre-flight's zero-length move finds it; the program is refused whole with the way out,
    and runs once the arm is homed."""
    from mirobot_async.sync import Mirobot as SyncMirobot

    program = tmp_path / "p.gcode"
    program.write_text("M21 G90 G0 X10\nG0 X20\n")
    with mirobot_emulator_pool.lend(firmware, 0) as emulator:
        if firmware == "2021":
            with SyncMirobot.connect(emulator.url) as arm:
                arm.clear_alarm()  # $X: Idle, still locked
        before = emulator_stats(emulator)
        proc = cli("run", str(program), "--port", emulator.url)
        after = emulator_stats(emulator)
        assert proc.returncode == 1
        assert error_line(proc) == "mirobot: error: " + LOCKED_PROBED
        assert proc.stdout == ""
        assert after["lines_in"] - before["lines_in"] == 2  # the probe and its G90: no program
        assert cli("home", "--port", emulator.url).returncode == 0
        proc = cli("run", str(program), "--port", emulator.url)
        assert proc.returncode == 0, proc.stderr
        assert close_to(parse_table(proc.stdout).joints, [20, 0, 0, 0, 0, 0], tol=0.01)


def test_run_home_refuses_a_g1_without_feed_before_homing(
    cli: Cli, tmp_path: Path, mirobot_emulator_pool: EmulatorPool
) -> None:
    """After homing the feed rate is 0: the check judges from there (not from power-on's 200),
    so the program is refused whole before a byte, homing included."""
    program = tmp_path / "nofeed.gcode"
    program.write_text("M21 G90 G0 X10\nG1 X20\n")
    assert cli("check", str(program)).returncode == 0  # from power-on: feed 200
    with mirobot_emulator_pool.lend(time_scale=0) as emulator:
        before = emulator_stats(emulator)
        proc = cli("run", str(program), "--port", emulator.url, "--home")
        after = emulator_stats(emulator)
    assert proc.returncode == 1
    assert f"{program}:2: G1 X20: no feed rate in effect" in proc.stderr
    assert error_line(proc).endswith("nothing was sent (--no-check sends it anyway)")
    assert after["lines_in"] - before["lines_in"] <= 1  # at most "$$": no $H, no program
    proc = cli("run", str(program), *FAST)  # the embedded arm is homed by default: the same
    assert proc.returncode == 1
    assert "no feed rate in effect" in proc.stderr


@pytest.mark.parametrize("firmware", ["classic", "2021"])
def test_check_and_run_flag_a_cartesian_target_the_arm_cannot_reach(
    cli: Cli, tmp_path: Path, mirobot_emulator_pool: EmulatorPool, firmware: str
) -> None:
    """The firmware's inverse kinematics on the targets the program gives whole (absolute, or
    relative after a known one); a target whose start is unknown is not judged."""
    program = tmp_path / "far.gcode"
    program.write_text(
        "M20 G90 G0 X500 ; start unknown: not judged\nG0 X200 Y0 Z200 A0 B0 C0\nG91 G0 X300\n"
    )
    proc = cli("check", str(program), "--firmware", firmware)
    assert proc.returncode == 1
    assert proc.stdout.splitlines() == [
        f"{program}:3: the Cartesian target X500 Y0 Z200 A0 B0 C0 is unreachable: the "
        "firmware's inverse kinematics has no solution and drops the move ('GOAL OUT OF "
        "WORKSPACE')"
    ]
    with mirobot_emulator_pool.lend(firmware, 0) as emulator:  # run refuses it whole
        before = emulator_stats(emulator)
        proc = cli("run", str(program), "--port", emulator.url, "--home")
        after = emulator_stats(emulator)
    assert proc.returncode == 1
    assert "nothing was sent" in error_line(proc)
    assert after["lines_in"] - before["lines_in"] <= 1  # at most "$$"


def test_run_checks_the_whole_program_before_sending_anything(
    cli: Cli, tmp_path: Path, mirobot_emulator_pool: EmulatorPool
) -> None:
    program = tmp_path / "bad.gcode"
    program.write_text("M21 G90\nG0 X10\nM3 S2000 ; not a PWM value\nG0 X20\n")
    with mirobot_emulator_pool.lend(time_scale=0) as emulator:
        before = emulator_stats(emulator)
        proc = cli("run", str(program), "--port", emulator.url, "--home")
        after = emulator_stats(emulator)
    assert proc.returncode == 1
    assert proc.stderr.splitlines() == [
        f"{program}:3: M3 S2000: S2000: PWM must be an integer 0..1000",
        f"mirobot: error: 1 problem in {program} (firmware 2021): nothing was sent "
        "(--no-check sends it anyway)",
    ]
    assert after["lines_in"] - before["lines_in"] <= 1  # at most "$$", never the program


def test_run_no_check_sends_what_check_flags_with_a_warning(cli: Cli, tmp_path: Path) -> None:
    """``--no-check`` sends the lines check flags (saying so), never half a program: the library
    used to refuse the flagged line after the lines before it had moved the arm."""
    program = tmp_path / "flagged.gcode"
    program.write_text("M21 G90\nG0 X10\nM3 S2000 ; check: not a PWM value\nG0 X20\n")
    proc = cli("run", str(program), "--no-check", *FAST)
    assert proc.returncode == 0, proc.stderr
    assert (
        f"mirobot: warning: {program}:3: M3 S2000: S2000: PWM must be an integer 0..1000 "
        "(sent anyway: --no-check)"
    ) in proc.stderr.splitlines()
    assert close_to(parse_table(proc.stdout).joints[:1], [20])


def test_run_continue_on_error_reports_every_refused_line(cli: Cli, tmp_path: Path) -> None:
    program = tmp_path / "bad.gcode"
    program.write_text("M21 G90\nG7\nG0 X20\nG0 X500\nG0 X25\n")
    proc = cli("run", str(program), "--continue-on-error", "--no-check", *FAST)
    assert proc.returncode == 1
    assert re.search(rf"^{re.escape(str(program))}:2: G7: .*Unsupported command", proc.stderr, re.M)
    assert f"{program}:4: G0 X500: " in proc.stderr  # refused by the firmware (out of limit)
    assert "2 lines were refused; 3 of 5 acknowledged" in proc.stderr
    assert close_to(parse_table(proc.stdout).joints[:1], [25])


def test_run_trace_then_plot(cli: Cli, tmp_path: Path) -> None:
    """The square, then the pump, the pump off and the older gripper, at the default speed:
    the trace is in the robot's time, dense enough for the corners, with the events."""
    trace = tmp_path / "square.csv"
    image = tmp_path / "square.png"
    program = tmp_path / "square_and_events.gcode"
    square = (EXAMPLES / "square.gcode").read_text()
    program.write_text(square + "M3 S1000\nG4 P0.2\nM3 S0\nM4 E65\n")
    proc = cli("run", str(program), "--trace", str(trace), "--unlock")  # homing: elsewhere
    assert proc.returncode == 0, proc.stderr
    recorded = read_trace(trace)
    assert recorded.robot_time
    # The square is drawn at 1500 mm/min (25 mm/s): 4 x 60 mm take >= 9.6 s of robot time,
    # about 1 s of wall time at the default time scale 10.
    assert recorded.seconds[-1] > 9.6
    for corner in ((170, -30), (230, -30), (230, 30), (170, 30)):  # sampled densely enough
        nearest = min(math.dist(corner, (x, y)) for x, y, _ in recorded.positions)
        assert nearest < 1.5, (corner, nearest)
    events = [event.label for event in recorded.events()]
    assert events == ["suction on", "pump off", "gripper open (PWM2)"]
    rows = read_csv(trace)
    assert rows[0] == TRACE_HEADER
    samples = rows[1:]
    assert len(samples) >= 10  # ~20 Hz while the square is drawn
    xs = [float(row[9]) for row in samples]
    ys = [float(row[10]) for row in samples]
    assert min(xs) < 172 and max(xs) > 228 and min(ys) < -28 and max(ys) > 28  # the square
    assert samples[-1][1] == "Idle"  # the final status closes the trace

    proc = cli("plot", str(trace), "-o", str(image))
    assert proc.returncode == 0, proc.stderr
    assert f"wrote {image} (1200x800 px" in proc.stdout
    import matplotlib.image

    pixels = matplotlib.image.imread(str(image))
    assert pixels.shape[:2] == (800, 1200)
    colours = {tuple(int(c * 255) // 16 for c in px[:3]) for px in pixels.reshape(-1, 4)[::97]}
    assert len(colours) >= 8  # a drawing, not a blank page: path, markers, 6 joint curves
    white = (pixels[..., :3] > 0.98).all(axis=-1).mean()
    assert 0.3 < white < 0.99


def test_plot_marks_the_pump_where_it_took_effect(cli: Cli, tmp_path: Path) -> None:
    """The pick-and-place example: the status shows the pump on while the arm still goes down
    to the part (the firmware reports M3 when it reads the line), but the pump switches once
    the arm is down at z = 60; the plot's marks (the trace's events) are there, not 33 mm
    above."""
    trace = tmp_path / "pick.csv"
    proc = cli("run", str(EXAMPLES / "pick_and_place.gcode"), "--trace", str(trace), "--unlock")
    assert proc.returncode == 0, proc.stderr
    recorded = read_trace(trace)
    outputs = [e for e in recorded.events() if e.kind == "output"]
    assert [e.label for e in outputs] == ["suction on", "blow", "pump off"]
    for event, y in zip(outputs, (-100, 100, 100), strict=True):
        x_, y_, z_ = recorded.positions[event.index]
        assert (x_, y_, z_) == pytest.approx((200, y, 60), abs=0.5), event


def test_plot_without_matplotlib_says_how_to_install_it(tmp_path: Path) -> None:
    trace = tmp_path / "t.csv"
    trace.write_text(",".join(TRACE_HEADER) + "\n2025-01-01T00:00:00+00:00,Idle" + ",0" * 15 + "\n")
    blocker = tmp_path / "block"
    (blocker / "matplotlib").mkdir(parents=True)
    (blocker / "matplotlib" / "__init__.py").write_text("raise ImportError('no matplotlib')\n")
    env = dict(os.environ, PYTHONPATH=str(blocker))
    proc = mirobot("plot", str(trace), env=env)
    assert proc.returncode == 2
    assert "pip install 'mirobot-async[plot]'" in error_line(proc)


# --------------------------------------------------------------------------------------------
# monitor


def test_monitor_samples_to_csv_on_a_port(cli: Cli, port: str, tmp_path: Path) -> None:
    trace = tmp_path / "m.csv"
    proc = cli(
        "monitor", "--port", port, "--interval", "0.05", "--samples", "3", "--csv", str(trace)
    )
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 3  # not a terminal: one line per sample
    assert all("joints" in line and "pose" in line for line in lines)
    proc = cli("monitor", "--port", port, "--samples", "2", "--csv", str(trace))
    assert proc.returncode == 0, proc.stderr
    rows = read_csv(trace)
    assert rows[0] == TRACE_HEADER
    assert len(rows) == 1 + 3 + 2  # appended, one header


def test_monitor_waits_for_an_arm_that_stops_answering(
    tmp_path: Path, mirobot_emulator_pool: EmulatorPool
) -> None:
    """The firmware answers no ``?`` while it searches its homing switches: monitor waits."""
    trace = tmp_path / "m.csv"
    with mirobot_emulator_pool.lend(time_scale=0) as emulator:
        proc = spawn("monitor", "--port", emulator.url, "--interval", "0.05", "--csv", str(trace))
        try:
            wait_for(lambda: trace.exists() and len(read_csv(trace)) >= 3, 20, "two samples")
            emulator.control("stall 2.5")  # longer than the client's status timeout (2 s)
            stalled_at = len(read_csv(trace))
            wait_for(lambda: len(read_csv(trace)) >= stalled_at + 3, 20, "samples after the stall")
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=20)
        finally:
            kill_group(proc)
    assert proc.returncode == 0, err
    assert "still waiting (is the arm homing?)" in err, err
    assert "Traceback" not in err and "error" not in err, err


def test_monitor_stops_cleanly_on_sigint(tmp_path: Path) -> None:
    trace = tmp_path / "m.csv"
    proc = spawn("monitor", "--interval", "0.05", "--csv", str(trace), *FAST)
    try:
        wait_for(
            lambda: trace.exists() and len(trace.read_text().splitlines()) >= 4,
            20,
            "three samples in the CSV",
        )
        # the embedded virtual Mirobot runs in the command's process: nothing to leave behind
        assert not psutil.Process(proc.pid).children(recursive=True)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20)
    finally:
        kill_group(proc)
    assert proc.returncode == 0, err
    assert "Traceback" not in err and "Traceback" not in out, err
    assert "samples written to" in err
    rows = read_csv(trace)
    assert rows[0] == TRACE_HEADER
    assert len(rows) >= 4 and all(len(row) == len(TRACE_HEADER) for row in rows)
    assert len(out.splitlines()) >= 3


def test_run_interrupted_exits_130_quietly(tmp_path: Path) -> None:
    """Ctrl-C in a terminal: SIGINT to the CLI's process group (the embedded emulator has a
    session of its own: the CLI stops it)."""
    trace = tmp_path / "t.csv"
    proc = spawn(
        "run",
        str(EXAMPLES / "dance.gcode"),
        "--trace",
        str(trace),
        "--unlock",
        "--time-scale",
        "0.5",
    )
    try:
        wait_for(
            lambda: trace.exists() and len(trace.read_text().splitlines()) >= 3,
            30,
            "the run to be under way",
        )
        children = psutil.Process(proc.pid).children(recursive=True)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=20)
    finally:
        kill_group(proc)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "error" not in err, err
    stopped = [line for line in err.splitlines() if line.startswith("mirobot: interrupted: ")]
    assert len(stopped) == 1, err  # one line says what became of the (virtual) arm
    _, alive = psutil.wait_procs(children, timeout=5)
    assert not alive


# --------------------------------------------------------------------------------------------
# check


def test_check_examples(cli: Cli) -> None:
    for example in ("pick_and_place.gcode", "square.gcode", "dance.gcode"):
        proc = cli("check", f"examples/{example}", cwd=ROOT)
        assert proc.returncode == 0, proc.stdout
        assert proc.stdout.startswith("OK: ")
        assert " lines" in proc.stdout


def test_check_lists_problems_by_line(cli: Cli, tmp_path: Path) -> None:
    program = tmp_path / "bad.gcode"
    program.write_text("M21 G90\nG0 X500 ; too far\nG0 X10\nM3 S5000\n")
    proc = cli("check", "bad.gcode", cwd=tmp_path)
    assert proc.returncode == 1
    assert proc.stdout.splitlines() == [
        "bad.gcode:2: J1=500 is outside -100..160",
        "bad.gcode:4: S5000: PWM must be an integer 0..1000",
    ]
    assert "2 problems in bad.gcode" in proc.stderr


# --------------------------------------------------------------------------------------------
# errors: one line, exit status 2


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["move", "joints", "j7=1"], "unknown joint 'j7' in 'j7=1'"),
        (["move", "pose", "x=abc"], "x=abc: 'abc' is not a number"),
        (["move", "joints", "j1=500"], "j1=500 is outside the joint range -100..160 deg"),
        (["run", "missing.gcode"], "missing.gcode: no such file"),
        (["check", "missing.gcode"], "missing.gcode: no such file"),
        (["plot", "missing.csv"], "cannot read missing.csv"),
        (["pump", "sideways"], "invalid choice: 'sideways'"),
        (["status", "--time-scale", "fast"], "'fast' is not a number"),
        (["teleport"], "invalid choice: 'teleport'"),
    ],
)
def test_bad_arguments_exit_2_with_one_line(
    cli: Cli, argv: list[str], message: str, tmp_path: Path
) -> None:
    proc = cli(*argv, cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1, proc.stderr  # no emulator started, nothing else said
    assert message in error_line(proc)
    assert proc.stdout == ""


@pytest.mark.parametrize(
    "argv",
    [
        ["move", "joints", "j7=1"],
        ["move", "pose", "x=abc"],
        ["move", "joints", "j1=500"],
        ["run", "missing.gcode"],
    ],
)
def test_bad_arguments_with_a_port_exit_2(
    cli: Cli, port: str, argv: list[str], tmp_path: Path
) -> None:
    proc = cli(*argv, "--port", port, cwd=tmp_path)
    assert proc.returncode == 2
    error_line(proc)


def test_missing_port_exits_2(cli: Cli, tmp_path: Path) -> None:
    proc = cli("status", "--port", str(tmp_path / "ttyUSB9"))
    assert proc.returncode == 2
    assert "ttyUSB9: no such port" in error_line(proc)
    proc = cli("status", "--port", "socket://127.0.0.1:9")
    assert proc.returncode == 2
    assert "could not open 'socket://127.0.0.1:9'" in error_line(proc)


def test_busy_port_exits_2(cli: Cli, port: str) -> None:
    with serial.Serial(port, exclusive=True):  # another program holds the port
        proc = cli("status", "--port", port)
    assert proc.returncode == 2
    assert f"{port} is busy" in error_line(proc)


def test_emulator_subcommand_help_and_errors() -> None:
    proc = mirobot("emulator", "--help")
    assert proc.returncode == 0
    assert "--firmware" in proc.stdout and "--time-scale" in proc.stdout
    proc = mirobot("emulator", "--firmware", "1999")
    assert proc.returncode == 2
    assert_clean(proc)


# --------------------------------------------------------------------------------------------
# examples/*.py run as written (each starts its own embedded virtual Mirobot)


def test_example_scripts_run_as_written() -> None:
    scripts = {
        "hello.py": "Idle: tool at x=200.0 y=0.0 z=150.0 mm",
        "status_monitor.py": "  15 Idle ",
        "monitor_while_streaming.py": "[monitor] Run",
    }
    procs = {
        name: subprocess.Popen(
            [sys.executable, str(EXAMPLES / name)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
            text=True,
        )
        for name in scripts
    }
    try:
        results = {name: proc.communicate(timeout=40) for name, proc in procs.items()}
    finally:
        for proc in procs.values():
            kill_group(proc)
    for name, (out, err) in results.items():
        assert procs[name].returncode == 0, f"{name}: {err}"
        assert "using an embedded virtual Mirobot" in out
        assert scripts[name] in out, f"{name}: {out}"


def test_link_lost_while_monitoring_exits_1_with_one_line(
    tmp_path: Path, mirobot_emulator_pool: EmulatorPool
) -> None:
    trace = tmp_path / "m.csv"
    with mirobot_emulator_pool.lend(time_scale=0) as emulator:  # killed: stopped, not kept
        proc = spawn("monitor", "--port", emulator.url, "--interval", "0.05", "--csv", str(trace))
        try:
            wait_for(lambda: trace.exists() and len(read_csv(trace)) >= 3, 20, "two samples")
            emulator.kill()  # the cable is pulled
            out, err = proc.communicate(timeout=20)
        finally:
            kill_group(proc)
    assert proc.returncode == 1
    assert "Traceback" not in err and "never retrieved" not in err, err
    errors = [line for line in err.splitlines() if line.startswith("mirobot: error: ")]
    assert len(errors) == 1 and "lost the link" in errors[0], err
    assert len(out.splitlines()) >= 2
