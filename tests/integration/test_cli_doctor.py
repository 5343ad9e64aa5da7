"""``mirobot doctor`` and a recorded session replayed: the tapes a user makes of their own arm.

Against a virtual arm of each profile the doctor finds no difference; told to compare with the
other profile it lists the differences (settings, refusal texts, the 2021 power-on alarm). A
session recorded with ``--record`` replays equal with ``mirobot replay``, on both profiles.
"""

from __future__ import annotations

import json
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from mirobot_async._tapes.format import Written, read_tapes

Cli = Callable[..., subprocess.CompletedProcess[str]]
PROFILES = ("classic", "2021", "2024")


@pytest.mark.parametrize("firmware", PROFILES)
def test_the_doctor_finds_no_difference_on_a_virtual_arm(
    cli: Cli, tmp_path: Path, firmware: str
) -> None:
    tape = tmp_path / "doctor.jsonl"
    done = cli("doctor", "--firmware", firmware, "--record", str(tape))
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"no difference from the emulator's {firmware} profile" in done.stdout
    assert f"tape: {tape}" in done.stdout
    (recorded,) = read_tapes(tape)
    written = b"".join(e.data for e in recorded.events if isinstance(e, Written))
    for line in (b"$$\n", b"$I\n", b"G99\n", b"M99\n", b"$3\n"):
        assert line in written
    assert recorded.header["family"] == firmware


@pytest.mark.parametrize(
    ("firmware", "other"), [("classic", "2021"), ("2021", "classic"), ("2024", "2021")]
)
def test_the_doctor_lists_what_the_other_profile_answers_otherwise(
    cli: Cli, tmp_path: Path, firmware: str, other: str
) -> None:
    tape = tmp_path / "doctor.jsonl"
    done = cli("doctor", "--firmware", firmware, "--against", other, "--record", str(tape))
    assert done.returncode == 1, done.stdout + done.stderr
    assert f"difference(s) from the emulator's {other} profile:" in done.stdout
    assert "Invalid statement" in done.stdout  # the profiles word a $3 refusal otherwise
    assert f"attach {tape} to a report" in done.stdout


def test_the_doctor_moves_nothing_without_a_confirmation(cli: Cli, tmp_path: Path) -> None:
    tape = tmp_path / "doctor.jsonl"
    done = cli("doctor", "--motion", "--record", str(tape))
    assert done.returncode == 2
    assert "pass --yes" in done.stderr
    assert not tape.exists()  # refused before the arm was opened


def test_the_doctor_with_motion_homes_and_still_matches(cli: Cli, tmp_path: Path) -> None:
    tape = tmp_path / "doctor.jsonl"
    done = cli(
        "doctor", "--firmware", "classic", "--motion", "--yes", "--time-scale", "100",
        "--record", str(tape),
    )  # fmt: skip
    assert done.returncode == 0, done.stdout + done.stderr
    assert "$H -> " in done.stdout
    (recorded,) = read_tapes(tape)
    assert any(e.data == b"$H\n" for e in recorded.events if isinstance(e, Written))


@pytest.mark.parametrize("firmware", PROFILES)
def test_a_recorded_session_replays_equal(cli: Cli, tmp_path: Path, firmware: str) -> None:
    tape = tmp_path / "session.jsonl"
    run = cli(
        "run", "--firmware", firmware, "--home", "--time-scale", "100", "--record", str(tape),
        str(Path(__file__).resolve().parents[2] / "examples" / "square.gcode"),
    )  # fmt: skip
    assert run.returncode == 0, run.stdout + run.stderr
    done = cli("replay", "--json", str(tape))
    assert done.returncode == 0, done.stdout + done.stderr
    (report,) = [json.loads(line) for line in done.stdout.splitlines()]
    assert report["equal"] is True
    assert report["firmware"] == firmware
    assert report["lines"] > 20
