"""``--envelope FILE`` on the commands that move the arm (``run``, ``move``): the envelope of the
file is on the connection, so a program or a move that would leave it is refused before a
line of it is sent. The emulator is read through its control channel (``stats``: the lines it
received) and its port, channels the CLI does not use."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from mirobot_async.testing import EmulatorPool, SyncEmulatorProcess

pytestmark = pytest.mark.timeout(60)

ROOT = Path(__file__).resolve().parents[2]
ENVELOPE = str(ROOT / "examples" / "envelope.toml")
Cli = Callable[..., subprocess.CompletedProcess[str]]

LEAVING = (
    "M20 G90 G21 G0 X200 Y0 Z150 A0 B0 C0 ; inside the box; modes stated (the arm is in use)\n"
    "G1 X200 Y0 Z5 F1000                ; 5 mm: below the box's z = 20\n"
)


def lines_received(emulator: SyncEmulatorProcess) -> int:
    words = emulator.control("stats").split()
    counts = {name: value for name, _, value in (w.partition("=") for w in words if "=" in w)}
    return int(counts["lines_in"])


def test_run_refuses_a_program_leaving_the_box_with_nothing_sent(
    cli: Cli, tmp_path: Path, mirobot_emulator_pool: EmulatorPool
) -> None:
    program = tmp_path / "leaves.gcode"
    program.write_text(LEAVING)
    with mirobot_emulator_pool.lend(time_scale=0) as emulator:
        homed = cli("home", "--port", emulator.url)
        assert homed.returncode == 0, homed.stderr
        before = lines_received(emulator)
        result = cli("run", str(program), "--port", emulator.url, "--envelope", ENVELOPE, "-v")
        after = lines_received(emulator)
        # without the envelope the first line runs: the same program is not refused otherwise
        control = cli("run", str(program), "--port", emulator.url, "--continue-on-error")
    said = [line for line in result.stderr.splitlines() if " ms mirobot_async." not in line]
    assert result.returncode == 1, said
    assert f"{program.name}:2: G1 X200 Y0 Z5 F1000" in result.stderr, said
    assert "below the envelope's minimum z=20 mm" in result.stderr
    assert f"{program.name} leaves the safety envelope at line 2: nothing was sent" in result.stderr
    assert "Traceback" not in result.stderr
    # the connection reads the firmware's stored state (read-only queries), no line of the
    # program is written (the -v wire log)
    written = [
        line.split("-> ", 1)[1]
        for line in result.stderr.splitlines()
        if "mirobot_async.wire: -> " in line
    ]
    assert set(written) <= {"?", "$$", "$N", "$#", "$G"}, written
    assert after - before == sum(1 for line in written if line != "?"), result.stderr
    assert control.returncode == 0, control.stderr


def test_run_inside_the_envelope_runs(cli: Cli) -> None:
    result = cli(
        "run", str(ROOT / "examples" / "square.gcode"), "--envelope", ENVELOPE, "--time-scale", "0"
    )
    assert result.returncode == 0, result.stderr
    assert "Idle" in result.stdout


def test_move_outside_the_envelope_is_refused(cli: Cli) -> None:
    result = cli("move", "joints", "j1=120", "--envelope", ENVELOPE, "--time-scale", "0")
    assert result.returncode == 1, result.stderr  # as run's refusal (one status for both)
    assert "outside the envelope's J1 range -100..100 deg" in result.stderr, result.stderr
    inside = cli("move", "pose", "x=220", "z=150", "--envelope", ENVELOPE, "--time-scale", "0")
    assert inside.returncode == 0, inside.stderr


def test_a_bad_envelope_file_is_a_usage_error(cli: Cli, tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[box]\nz = [300, 20]\n")
    result = cli("move", "joints", "j1=10", "--envelope", str(bad))
    assert result.returncode == 2
    assert result.stderr.strip().splitlines()[-1] == (
        f"mirobot: error: {bad}: box.z = [300, 20]: min is above max (reversed range)"
    )
    assert "virtual Mirobot" not in result.stderr  # refused before an arm was opened


def test_mcp_without_the_sdk_says_how_to_install_it(
    cli: Cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delitem(sys.modules, "mirobot_async._mcp_server.server", raising=False)
    for name in [name for name in sys.modules if name == "mcp" or name.startswith("mcp.")]:
        monkeypatch.setitem(sys.modules, name, None)  # imported before: ImportError now
    monkeypatch.setitem(sys.modules, "mcp", None)
    result = cli("mcp", "--time-scale", "0")
    assert result.returncode == 2
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("mirobot: error: mirobot mcp needs the MCP SDK: pip install ")
    assert "'mirobot-async[mcp]'" in last
    assert "virtual Mirobot" not in result.stderr  # said before anything was started


def test_check_with_an_envelope_says_what_run_says(
    cli: Cli, tmp_path: Path, mirobot_emulator_pool: EmulatorPool
) -> None:
    """``check --envelope`` offline: the line run's envelope check refuses, with run's reason."""
    program = tmp_path / "leaves.gcode"
    program.write_text(LEAVING)
    offline = cli("check", str(program), "--envelope", ENVELOPE)
    assert offline.returncode == 1
    assert offline.stdout.splitlines() == [
        f"{program}:2: G1 X200 Y0 Z5 F1000: target z=5.000 mm is below the envelope's minimum "
        "z=20 mm (line 2)"
    ]
    assert f"{program} leaves the safety envelope at line 2" in offline.stderr
    assert cli("check", str(program)).returncode == 0  # without the envelope: nothing to say
    with mirobot_emulator_pool.lend(time_scale=0) as emulator:
        assert cli("home", "--port", emulator.url).returncode == 0
        online = cli("run", str(program), "--port", emulator.url, "--envelope", ENVELOPE)
    assert online.returncode == 1
    said = next(line for line in online.stderr.splitlines() if line.startswith(f"{program}:2:"))
    reason = offline.stdout.splitlines()[0].split(": ", 2)[2]
    assert said.startswith(f"{program}:2: G1 X200 Y0 Z5 F1000: ")
    assert reason.split(" (line 2)")[0] in said
    bad = tmp_path / "bad.toml"
    bad.write_text("[box]\nz = [300, 20]\n")
    assert cli("check", str(program), "--envelope", str(bad)).returncode == 2
