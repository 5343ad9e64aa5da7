"""``mirobot plot`` on a trace whose pump or valve cell is not a whole number (``inf``, ``nan``,
text): a :class:`TraceError` naming the file and line, exit status 2, no image written."""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from mirobot_async._cli.plotting import TRACE_COLUMNS, TraceError, read_trace

Cli = Callable[..., subprocess.CompletedProcess[str]]

SAMPLE = "{t},Idle,0,0,0,0,0,0,,198.67,0,230.72,0,0,0,{pump},{valve},1"


def _trace(path: Path, pump: str, valve: str) -> Path:
    rows = [
        ",".join(TRACE_COLUMNS),
        SAMPLE.format(t=1.0, pump=0, valve=0),
        SAMPLE.format(t=1.05, pump=pump, valve=valve),
        SAMPLE.format(t=1.10, pump=0, valve=0),
    ]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize(
    ("pump", "valve", "column"),
    [
        ("inf", "0", "pump"),
        ("0", "-inf", "valve"),
        ("1e400", "0", "pump"),
        ("nan", "0", "pump"),
        ("0", "2.5", "valve"),
        ("0", "abc", "valve"),
    ],
)
def test_a_bad_pwm_cell_is_a_trace_error_naming_file_and_line(
    cli: Cli, tmp_path: Path, pump: str, valve: str, column: str
) -> None:
    trace = _trace(tmp_path / "bad.csv", pump, valve)
    with pytest.raises(TraceError, match=rf"bad\.csv:3: bad sample: {column} "):
        read_trace(trace)
    image = tmp_path / "bad.png"
    proc = cli("plot", str(trace), "-o", str(image))
    assert proc.returncode == 2
    assert f"{trace}:3: bad sample" in proc.stderr
    assert "unexpected" not in proc.stderr
    assert not image.exists()


def test_whole_pwm_values_are_read(tmp_path: Path) -> None:
    trace = read_trace(_trace(tmp_path / "good.csv", "1000", "65.0"))
    assert trace.pumps == (0, 1000, 0) and trace.valves == (0, 65, 0)
