"""``mirobot demo``: the shipped examples are listed and run on the embedded virtual Mirobot.

The command runs as ``main(argv)`` in this process (the ``cli`` fixture, output captured at the
file descriptors: an example script runs as a child writing to them), from a directory that is
not the checkout, so that no relative path can find the examples by accident."""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path

from mirobot_async._cli.demo import example_files, find_example

Cli = Callable[..., subprocess.CompletedProcess[str]]


EXAMPLES = {"dance", "hello", "monitor_while_streaming", "pick_and_place", "square"}
EXAMPLES |= {"status_monitor"}


def test_every_example_is_found() -> None:
    """In a checkout (examples/) and in an installed copy (mirobot_async._examples) alike."""
    found = example_files()
    assert set(found) == EXAMPLES
    assert all(path.is_file() for path in found.values())
    assert find_example("square.gcode").name == "square.gcode"
    assert find_example("hello").name == "hello.py"


def test_list_names_programs_and_scripts(cli: Cli, tmp_path: Path) -> None:
    proc = cli("demo", "--list", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    names = {line.split()[0]: line.split()[1] for line in proc.stdout.splitlines()}
    assert names["pick_and_place"] == "program" and names["hello"] == "script"


def test_demo_runs_the_default_program_on_the_embedded_arm(cli: Cli, tmp_path: Path) -> None:
    proc = cli("demo", "--time-scale", "0", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "pick_and_place.gcode" in proc.stderr
    assert "embedded virtual Mirobot" in proc.stderr
    assert proc.stdout.splitlines()[0].split() == ["state", "Idle"]


def test_demo_runs_a_script(cli: Cli, tmp_path: Path) -> None:
    proc = cli("demo", "hello", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "Idle: tool at x=200.0 y=0.0 z=150.0 mm" in proc.stdout


def test_an_unknown_example_lists_the_others(cli: Cli, tmp_path: Path) -> None:
    proc = cli("demo", "nope", cwd=tmp_path)
    assert proc.returncode == 2
    assert "no example called 'nope'" in proc.stderr and "square" in proc.stderr
    assert "Traceback" not in proc.stderr
