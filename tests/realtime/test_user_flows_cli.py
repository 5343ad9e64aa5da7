"""The command line's user flows at the arm's own speed, each command a child process as a
terminal runs it: every command that moves the arm, one after another on a port; the
pick-and-place example as its own comment says to run it; Ctrl-C while homing and while a program
runs, with what the arm does afterwards read back over the port. Each on both emulator profiles
at ``--time-scale 1``."""

from __future__ import annotations

import asyncio
import subprocess
import sys

import pytest
from user_flow_arms import ARMS, ROOT, arm_at_real_speed, spawned

from mirobot_async import Mirobot, State
from mirobot_async.testing import EmulatorPool

pytestmark = [pytest.mark.realtime, pytest.mark.timeout(180)]

EXAMPLES = ROOT / "examples"


def mirobot(*args: str, timeout: float = 90) -> subprocess.CompletedProcess[str]:
    """``python -m mirobot_async ARGS`` to completion."""
    return subprocess.run(
        [sys.executable, "-m", "mirobot_async", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=ROOT,
        stdin=subprocess.DEVNULL,
        check=False,
    )


def table_row(stdout: str, name: str) -> list[float]:
    """The numbers of row ``name`` (``joints``, ``pose``) of the last status table printed."""
    row = [line for line in stdout.splitlines() if line.startswith(f"{name} ")][-1]
    return [float(value) for value in row.split()[1:]]


@pytest.mark.parametrize("arm", ARMS)
def test_every_moving_command_on_a_port(mirobot_emulator_pool: EmulatorPool, arm: str) -> None:
    """A session at a real arm: home, joint moves (absolute, relative), a straight Cartesian
    move, the gripper, the pump and a short program, each command returning when the arm has
    done it (its status table shows it at rest where it was sent)."""
    with arm_at_real_speed(mirobot_emulator_pool, arm) as url:
        port = ("--port", url)
        steps: list[tuple[tuple[str, ...], str, list[float] | None]] = [
            (("home",), "joints", [0, 0, 0, 0, 0, 0]),
            (("move", "joints", "j1=30", "j2=10", "--speed", "2000"), "joints", [30, 10]),
            (("move", "joints", "j1=-10", "--relative"), "joints", [20, 10]),
            (
                ("move", "pose", "x=180", "y=40", "z=160", "--linear", "--speed", "2000"),
                "pose",
                [180, 40, 160],
            ),
            (("gripper", "close"), "pwm", None),
            (("gripper", "open"), "pwm", None),
            (("pump", "on"), "pwm", None),
            (("pump", "off"), "pwm", None),
            (("run", str(EXAMPLES / "square.gcode")), "state", None),
        ]
        for args, row, expected in steps:
            done = mirobot(*args, *port)
            assert done.returncode == 0, (args, done.stderr)
            assert "Traceback" not in done.stderr, done.stderr
            assert "Idle" in done.stdout, (args, done.stdout)
            if expected is not None:
                got = table_row(done.stdout, row)[: len(expected)]
                assert got == pytest.approx(expected, abs=0.1), (args, got)


@pytest.mark.parametrize("arm", ARMS)
def test_pick_and_place_as_its_comment_says(arm: str) -> None:
    """``mirobot run examples/pick_and_place.gcode --home``: embedded at ``--time-scale 1``;
    homing, then the whole program."""
    program = str(EXAMPLES / "pick_and_place.gcode")
    done = mirobot("run", program, "--home", "--time-scale", "1", "--firmware", arm, timeout=150)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    assert "Idle" in done.stdout, done.stdout  # the final status table


async def standing_still(url: str) -> State:
    """Connect to the arm the CLI left and return its state, once two statuses 0.3 s apart
    show it at the same position (it must answer: neither homing nor lost)."""
    async with Mirobot.connect(url) as arm:
        first = await arm.status(fresh=True)
        await asyncio.sleep(0.3)  # the interval measured, not a settling delay
        second = await arm.status(fresh=True)
        assert second.joints == first.joints, (first, second)
        return second.state


@pytest.mark.parametrize("arm", ARMS)
async def test_ctrl_c_while_homing(mirobot_emulator_pool: EmulatorPool, arm: str) -> None:
    """Ctrl-C during ``mirobot home``: the firmware ignores feed hold while it homes, so the CLI
    stops the search with a soft reset and exits 130; the arm answers again at once, standing
    still."""
    with arm_at_real_speed(mirobot_emulator_pool, arm) as url:
        with spawned("home", "--port", url, "-v") as command:
            command.wait_for("-> $H", timeout=30)
            command.interrupt()
            status = command.finish(timeout=30)
            assert status == 130, command.stderr
            assert "Traceback" not in command.stderr, command.stderr
            assert "-> %" in command.stderr, command.stderr
        state = await standing_still(url)
        assert state is not State.HOME, state


@pytest.mark.parametrize("arm", ARMS)
async def test_ctrl_c_while_a_program_runs(mirobot_emulator_pool: EmulatorPool, arm: str) -> None:
    """Ctrl-C during ``mirobot run``: feed hold at once, exit 130 with one line on what became of
    the arm; read back over the port, the arm is in Hold and stands still."""
    with arm_at_real_speed(mirobot_emulator_pool, arm) as url:
        program = str(EXAMPLES / "dance.gcode")
        with spawned("run", program, "--unlock", "--port", url, "-v") as command:
            command.wait_for("<- ok", timeout=30, count=6)  # unlock, then moves under way
            command.interrupt()
            status = command.finish(timeout=30)
            assert status == 130, command.stderr
            assert "Traceback" not in command.stderr, command.stderr
            stopped = [
                line
                for line in command.stderr.splitlines()
                if line.startswith("mirobot: interrupted: ")
            ]
            assert len(stopped) == 1, command.stderr
            assert "feed hold sent" in stopped[0], stopped
        state = await standing_still(url)
        assert state is State.HOLD, state
