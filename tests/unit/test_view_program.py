"""The teach table as a program (pure): rows -> G-code -> rows, Play's lines, the check."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mirobot_async._core import validation
from mirobot_async._core.gcode import JOINT_RANGES
from mirobot_async._urdf import dh_of
from mirobot_async._view.program import (
    OUTPUTS,
    Dwell,
    Output,
    ProgramTable,
    Row,
    Speed,
    TeachProgram,
    parse_program,
    parse_row,
    play_lines,
    program_lines,
    row_line,
)
from mirobot_async._view.teach import TaughtPoint, modes_line
from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import forward

DH = dh_of("2021")


def _decimal(low: float, high: float, places: int) -> st.SearchStrategy[float]:
    scale = 10**places
    return st.integers(int(low * scale), int(high * scale)).map(lambda n: round(n / scale, places))


@st.composite
def points(draw: st.DrawFn) -> TaughtPoint:
    joints = tuple(draw(_decimal(*JOINT_RANGES[f"J{i}"], 3)) for i in range(1, 7))
    rail = draw(st.none() | _decimal(0.0, 500.0, 3))
    return TaughtPoint(joints, rail, forward(joints, DH))  # type: ignore[arg-type]


rows: st.SearchStrategy[Row] = st.one_of(
    points(),
    st.sampled_from(sorted(OUTPUTS)).map(Output),
    _decimal(0.0, 60.0, 3).map(Dwell),
    _decimal(10.0, 3000.0, 1).map(Speed),
)
programs = st.builds(
    TeachProgram,
    st.tuples(points()).flatmap(
        lambda first: st.lists(rows, max_size=12).map(lambda r: (*first, *r))
    ),
    _decimal(10.0, 3000.0, 1),
)


@settings(max_examples=200, deadline=None)
@given(programs)
def test_rows_to_gcode_to_rows_is_the_identity(program: TeachProgram) -> None:
    lines = program_lines(program)
    assert parse_program(lines) == program
    assert validation.check_program(lines) == []


@settings(max_examples=50, deadline=None)
@given(programs, st.integers(1, 3))
def test_play_starts_slow_and_repeats_the_rows(program: TeachProgram, loops: int) -> None:
    lines = play_lines(program, loops=loops)
    assert lines[0] == modes_line(min(500.0, program.speed))
    body = program_lines(program)[2:]
    assert lines[-len(body) :] == body
    assert len(lines) == 2 + loops * (len(body) + 1)
    assert validation.check_program(lines) == []


def test_the_lines_of_each_kind_of_row() -> None:
    point = TaughtPoint((5.0, 0.0, -5.0, 0.0, 0.0, 0.0), None, forward((5, 0, -5, 0, 0, 0), DH))
    program = TeachProgram(
        (point, Output("pump on"), Dwell(0.5), Speed(1000.0), Output("gripper close")), 2000.0
    )
    assert program_lines(program)[1:] == [
        "M21 G90 G21 G1 F2000",
        "X5 Y0 Z-5 A0 B0 C0",
        "M3 S1000",
        "G4 P0.5",
        "F1000",
        "M3 S60",
    ]


@pytest.mark.parametrize(
    ("lines", "says"),
    [
        (["X0 Y0 Z0 A0 B0 C0"], "expected the modes line"),
        (["M21 G90 G21 G1 F2000", "M20 G1 X1"], "not a teach-table line"),
        (["M21 G90 G21 G1 F2000", "M3 S700"], "not a teach-table line"),
        (["M21 G90 G21 G1 F2000", "X500 Y0 Z0 A0 B0 C0"], r":2: .*j1=500"),
        ([], "no modes line"),
    ],
)
def test_what_is_not_a_table_is_refused_with_its_line(lines: list[str], says: str) -> None:
    with pytest.raises(MirobotUsageError, match=says):
        parse_program(lines)


def test_no_points_is_refused() -> None:
    with pytest.raises(MirobotUsageError, match="no points"):
        program_lines(TeachProgram((Output("pump on"),)))
    with pytest.raises(MirobotUsageError, match="loops"):
        play_lines(TeachProgram((Output("pump on"),)), loops=0)


def test_the_table_edits_rows_and_a_row_edits_as_its_line() -> None:
    point = TaughtPoint((5.0, 0.0, -5.0, 0.0, 0.0, 0.0), None, forward((5, 0, -5, 0, 0, 0), DH))
    table = ProgramTable([point, Output("pump on"), Dwell(1.0)])
    assert table.move(3, -1) == 2
    assert table.rows == [point, Dwell(1.0), Output("pump on")]
    table.replace(2, parse_row("G4 P2.5"))
    table.delete(3)
    assert table.rows == [point, Dwell(2.5)]
    assert table.points() == [(1, point)]
    assert parse_row(row_line(point)) == point
    with pytest.raises(MirobotUsageError, match="no row 9"):
        table.get(9)
    with pytest.raises(MirobotUsageError, match="not a teach-table line"):
        parse_row("M20 G1 X1")
