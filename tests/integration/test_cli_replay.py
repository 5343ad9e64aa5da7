"""``mirobot replay``: per tape, equal or the first difference; exit 0, 1 or 2."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Callable
from pathlib import Path

from mirobot_async._tapes.format import split_tapes

FIRMWARE_TAPES = Path(__file__).resolve().parents[1] / "tapes" / "firmware"
AN_EQUAL_TAPE = "tests/oracle/test_diff_outputs.py::test_answered_at_once[M50]#0"

Cli = Callable[..., subprocess.CompletedProcess[str]]


def _extract(tape_id: str, path: Path, edit: Callable[[str], str] = lambda line: line) -> Path:
    text = next(t for t in split_tapes(FIRMWARE_TAPES / "oracle-suite.jsonl.gz") if t.id == tape_id)
    header = json.dumps(text.header) + "\n"
    path.write_text(header + "".join(edit(line) for line in text.lines))
    return path


def test_an_equal_tape_exits_0(cli: Cli, tmp_path: Path) -> None:
    done = cli("replay", str(_extract(AN_EQUAL_TAPE, tmp_path / "t.jsonl")))
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"equal: {AN_EQUAL_TAPE} [classic]")
    assert "1 equal, 0 differ" in done.stderr


def test_a_difference_names_the_event_bytes_and_instants(cli: Cli, tmp_path: Path) -> None:
    def edit(line: str) -> str:
        return line.replace('"out":"M50: Unlock each axis.', '"out":"M50: Unlock every axis.')

    done = cli("replay", "--json", str(_extract(AN_EQUAL_TAPE, tmp_path / "t.jsonl", edit)))
    assert done.returncode == 1, done.stderr
    (record,) = [json.loads(line) for line in done.stdout.splitlines()]
    assert record["equal"] is False
    difference = record["difference"]
    assert difference["firmware"] == "M50: Unlock every axis.\r\n"
    assert difference["emulator"] == "M50: Unlock each axis.\r\n"
    assert difference["text"].startswith(f"{AN_EQUAL_TAPE} event {difference['event']}: firmware")
    assert " at " in difference["text"]
    assert "; emulator b'M50: Unlock each axis.\\r\\n' at " in difference["text"]


def test_the_other_profile_differs(cli: Cli, tmp_path: Path) -> None:
    done = cli("replay", "--firmware", "2021", str(_extract(AN_EQUAL_TAPE, tmp_path / "t.jsonl")))
    assert done.returncode == 1
    assert done.stdout.startswith("DIFFERS: ")


def test_a_bad_tape_exits_2_naming_the_file_and_line(cli: Cli, tmp_path: Path) -> None:
    good = _extract(AN_EQUAL_TAPE, tmp_path / "good.jsonl")
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"tape":1,"id":"x"}\n{"t":0.1,"in":"?","why":1}\n')
    done = cli("replay", str(good), str(bad))
    assert done.returncode == 2
    assert f"{bad}:2: bad tape: unknown field(s) in a 'in' event: why" in done.stderr
