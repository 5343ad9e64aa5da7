"""The replay's timeline (pure): the pose, the path and the events at any instant."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mirobot_async._view.timeline import Event, Sample, Timeline, load_timeline
from mirobot_async.errors import MirobotUsageError

TAPES = Path(__file__).parents[1] / "tapes" / "firmware"
HEADER = "timestamp,state,j1,j2,j3,j4,j5,j6,rail,x,y,z,rx,ry,rz,pump,valve,time_scale"


def _sample(t: float, j1: float = 0.0) -> Sample:
    return Sample(t, "Idle", (j1, 0, 0, 0, 0, 0), None, (j1, 0.0, 0.0))


def test_pose_path_and_events_at_an_instant() -> None:
    line = Timeline(
        (_sample(0.0), _sample(1.0, 10.0), _sample(2.0, 20.0)),
        (Event(0.5, "output", "suction on"), Event(1.5, "refusal", "error 2")),
    )
    assert line.duration == 2.0
    assert line.sample_at(-1.0).joints[0] == 0.0
    assert line.sample_at(1.4).joints[0] == 10.0  # the last report, not a guess between
    assert line.sample_at(2.0).joints[0] == 20.0
    assert line.path_to(1.0) == [(0.0, 0.0, 0.0), (10.0, 0.0, 0.0)]
    assert [e.label for e in line.events_to(1.0)] == ["suction on"]
    assert len(line.events_to(9.0)) == 2


@given(st.lists(st.floats(0, 100), min_size=1, max_size=30), st.floats(-1, 101))
def test_the_arm_at_t_is_the_last_report_at_or_before_t(times: list[float], t: float) -> None:
    line = Timeline(tuple(_sample(s, float(i)) for i, s in enumerate(sorted(times))), ())
    shown = line.sample_at(t)
    before = [s for s in line.samples if s.t <= t]
    assert shown == (before[-1] if before else line.samples[0])
    assert line.path_to(t)[-1] == shown.xyz
    assert len(line.path_to(t)) == max(len(before), 1)


def test_no_samples_is_refused() -> None:
    with pytest.raises(MirobotUsageError, match="no status samples"):
        Timeline((), ())


def test_a_trace_csv_with_an_output_and_an_alarm(tmp_path: Path) -> None:
    rows = [
        ("00.000", "Idle", 0, 0, "0"),
        ("00.500", "Run", 5, 100, "1000"),
        ("01.000", "Idle", 10, 200, "1000"),
        ("01.500", "Alarm", 10, 200, "1000"),
    ]
    text = [HEADER] + [
        f"2026-01-01T10:00:{s}+00:00,{state},{j1},0,0,0,0,0,,{x},0,230,0,0,0,{pump},0,"
        for s, state, j1, x, pump in rows
    ]
    path = tmp_path / "run.csv"
    path.write_text("\n".join(text) + "\n")
    line = load_timeline(path)
    assert line.duration == pytest.approx(1.5)
    assert line.sample_at(0.7).joints[0] == 5
    assert [(e.kind, e.label) for e in line.events] == [
        ("output", "suction on"),
        ("alarm", "alarm"),
    ]


def test_a_recorded_tape_gives_statuses_and_the_alarm_it_printed() -> None:
    line = load_timeline(TAPES / "integration-oracle-link.jsonl.gz")
    assert len(line.samples) > 10
    kinds = [e.kind for e in line.events]
    assert "alarm" in kinds
    assert line.events_to(0.0) == []
