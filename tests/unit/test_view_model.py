"""The pure parts of ``mirobot view``: the program preview and the teach table's export
(neither needs viser)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mirobot_async import kinematics
from mirobot_async._core import validation
from mirobot_async._safety.envelope import Envelope
from mirobot_async._urdf import dh_of
from mirobot_async._view.preview import preview_program
from mirobot_async._view.teach import TaughtPoint, TeachTable, export_program
from mirobot_async.errors import MirobotUsageError

PROGRAM = [
    "(comment line)",
    "M21 G90 G21 G1 F2000",
    "X30 Y20 Z10 A0 B-30 C0",
    "G4 P0",  # the arm stops before M20 re-reads its position (else check flags the M20 line)
    "M20 G90 G1 X200 Y0 Z150 A0 B0 C0 F1500",
    "M21 G90 G1 X400",
    "M21 G0 X0 Y0 Z0 A0 B0 C0",
]


@pytest.mark.parametrize("firmware", ["2021", "classic"])
def test_flagged_lines_are_check_s(firmware: str) -> None:
    preview = preview_program(PROGRAM, firmware=firmware)
    expected = sorted({n for n, _ in validation.check_program(PROGRAM, firmware=firmware)})
    assert preview.flagged_numbers == expected == [6]
    assert "J1=400" in preview.flagged[0].message
    assert [s.number for s in preview.segments if s.kind != "snap"] == [3, 5, 7]


def test_joint_move_is_drawn_as_the_arm_runs_it() -> None:
    """An M21 move: the forward kinematics of the linear joint interpolation, end to end."""
    dh = dh_of("2021")
    preview = preview_program(PROGRAM, firmware="2021")
    joint = preview.segments[0]
    assert joint.kind == "joint"
    assert np.allclose(joint.points[0], kinematics.forward((0,) * 6, dh)[:3])
    assert np.allclose(joint.points[-1], kinematics.forward((30, 20, 10, 0, -30, 0), dh)[:3])
    steps = np.linalg.norm(np.diff(joint.points, axis=0), axis=1)
    assert steps.max() <= 2.0 + 1e-9  # sampled at most 2 mm apart


def test_linear_move_is_a_straight_line() -> None:
    preview = preview_program(PROGRAM, firmware="2021")
    line = next(s for s in preview.segments if s.kind == "cartesian")
    start, end = line.points[0], line.points[-1]
    assert np.allclose(end, (200, 0, 150))
    direction = (end - start) / np.linalg.norm(end - start)
    offsets = line.points - start
    across = offsets - np.outer(offsets @ direction, direction)
    assert np.abs(across).max() < 1e-6


def test_envelope_refusals_are_flagged() -> None:
    fence = Envelope(z=(180, None), dh=dh_of("2021"))
    preview = preview_program(PROGRAM, firmware="2021", envelope=fence)
    numbers = preview.flagged_numbers
    assert 5 in numbers  # z = 150 is below the fence
    assert any("envelope" in f.message or "z" in f.message for f in preview.flagged)


def test_position_unknown_after_a_line_the_prediction_cannot_follow() -> None:
    preview = preview_program(["M21 G91 G0 X10", "$RST=*", "M21 G90 G0 X5"], firmware="2021")
    assert preview.unknown and preview.unknown[0].number == 2
    assert [s.number for s in preview.segments] == [1]


joints = st.tuples(*(st.floats(lo, hi, allow_nan=False) for lo, hi in kinematics.JOINT_LIMITS))


@pytest.mark.parametrize("firmware", ["2021", "classic"])
@given(points=st.lists(joints, min_size=1, max_size=5))
def test_export_passes_check_with_modes_stated_once(
    firmware: str, points: list[tuple[float, ...]]
) -> None:
    taught = [TaughtPoint(q, None, kinematics.forward(q)) for q in points]  # type: ignore[arg-type]
    lines = export_program(taught, firmware=firmware)
    assert validation.check_program(lines, firmware=firmware) == []
    assert sum(1 for line in lines if "M21" in line) == 1
    assert len(lines) == len(points) + 2
    for line, q in zip(lines[2:], points, strict=True):
        values = [float(word[1:]) for word in line.split()]
        assert values == pytest.approx(q, abs=5e-4 + 1e-9)  # printed to 3 decimals
    preview = preview_program(lines, firmware=firmware)
    assert preview.end_joints == pytest.approx([round(v, 3) for v in points[-1]], abs=5e-4 + 1e-9)


def test_teach_table_edits() -> None:
    table = TeachTable()
    points = [TaughtPoint((float(i),) + (0.0,) * 5, None, (0.0,) * 6) for i in range(3)]
    for p in points:
        table.add(p)
    assert table.move(3, -1) == 2
    assert [p.joints[0] for p in table.points] == [0.0, 2.0, 1.0]
    table.delete(1)
    assert [p.joints[0] for p in table.points] == [2.0, 1.0]
    table.replace(2, points[0])
    assert table.get(2) == points[0]
    with pytest.raises(MirobotUsageError):
        table.delete(5)
    with pytest.raises(MirobotUsageError):
        export_program([])
    assert "| 1 |" in table.markdown()


def test_view_without_the_extra_says_how_to_install_it() -> None:
    """No viser: one line naming the extra, exit status 2, no virtual arm started."""
    code = (
        "import sys; sys.modules['viser'] = None; from mirobot_async._cli import main; "
        "sys.exit(main(['view', '--no-browser']))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 2, done.stderr
    assert "pip install 'mirobot-async[view]'" in done.stderr
    assert "virtual Mirobot" not in done.stderr
    assert done.stdout == ""
