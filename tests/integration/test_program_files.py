"""Program files (``mirobot check`` and ``mirobot run``): read as UTF-8 and cut into lines at
``\\n``, ``\\r\\n`` and ``\\r`` only, and judged by one validation, so that ``check`` passes exactly
the programs ``run`` sends and reports every problem on the line where it is."""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from mirobot_async.testing import EmulatorPool

Cli = Callable[..., subprocess.CompletedProcess[str]]

NORWEGIAN = "M21 G90\n; Åpne griper\nG0 X10\nG0 X999\n"  # Å is C3 85 in UTF-8


def test_a_utf8_comment_is_one_comment(cli: Cli, tmp_path: Path) -> None:
    program = tmp_path / "norsk.gcode"
    program.write_bytes(NORWEGIAN.encode("utf-8"))
    proc = cli("check", str(program))
    assert proc.returncode == 1
    # the problem is on line 4 (not 5: no phantom line "pne griper" cut at the byte 0x85)
    assert proc.stdout.splitlines() == [f"{program}:4: J1=999 is outside -100..160"]


@pytest.mark.parametrize("odd", ["\x0b", "\x0c", "\x1c", "\x1d", "\x1e", "\x85", "\u2028"])
def test_only_cr_and_lf_end_a_line(cli: Cli, tmp_path: Path, odd: str) -> None:
    program = tmp_path / "odd.gcode"
    program.write_bytes(f"M21 G90\r(a{odd}b)\rG0 X10\r\nG0 X20\n".encode())
    proc = cli("check", str(program))
    assert proc.returncode == 0, proc.stdout
    assert proc.stdout.strip() == "OK: 4 lines (3 commands, firmware 2021)"


def test_bytes_that_are_not_utf8_are_a_clear_error(cli: Cli, tmp_path: Path) -> None:
    program = tmp_path / "latin1.gcode"
    program.write_bytes("M21 G90\r\nG0 X10\n; Åpne\n".encode("latin-1"))
    for command in ("check", "run"):
        proc = (
            cli(command, str(program), "--no-check")
            if command == "run"
            else cli(command, str(program))
        )
        assert proc.returncode == 2
        assert f"{program}:3: byte 0xc5 is not UTF-8 text" in proc.stderr


def test_stdin_is_read_the_same_way(cli: Cli) -> None:
    proc = cli("check", "-", stdin=NORWEGIAN)
    assert proc.returncode == 1
    assert proc.stdout.splitlines() == ["<stdin>:4: J1=999 is outside -100..160"]


COMMENTED = (
    "M21 G90\nG0 X10 (why? stop! @ now)\nG0 X20 (a comment left open\nG0 X30 ; Åpne griper ~ %\n"
)


def test_check_and_run_agree_on_what_is_only_in_comments(
    cli: Cli, tmp_path: Path, mirobot_emulator_pool: EmulatorPool
) -> None:
    program = tmp_path / "commented.gcode"
    program.write_text(COMMENTED, encoding="utf-8")
    checked = cli("check", str(program))
    assert checked.returncode == 0, checked.stdout
    assert checked.stdout.strip() == "OK: 4 lines (4 commands, firmware 2021)"
    with mirobot_emulator_pool.lend(time_scale=0) as emulator:
        ran = cli("run", str(program), "--port", emulator.url, "--home")
    assert ran.returncode == 0, ran.stderr
    assert "4/4 lines 100%" in ran.stderr and "30.002" in ran.stdout  # J1 at 30 (its whole steps)


def test_check_and_run_agree_on_a_realtime_byte_outside_comments(
    cli: Cli, tmp_path: Path, mirobot_emulator_pool: EmulatorPool
) -> None:
    program = tmp_path / "realtime.gcode"
    program.write_text("M21 G90\nG0 X10 ? (status)\nG0 X20\n", encoding="utf-8")
    checked = cli("check", str(program))
    assert checked.returncode == 1
    assert checked.stdout.startswith(f"{program}:2: contains '?'")
    with mirobot_emulator_pool.lend(time_scale=0) as emulator:
        ran = cli("run", str(program), "--port", emulator.url, "--home")
    assert ran.returncode == 1
    assert ran.stderr.startswith(f"{program}:2: G0 X10 ?: contains '?'")
