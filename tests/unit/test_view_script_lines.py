"""The script view's model of a script's lines (pure): where the predicted path starts and
stops, what a refusal does to it, the events and markers the page lists."""

from __future__ import annotations

import pytest

from mirobot_async._core.line import parse_line
from mirobot_async._core.modal import MotionModes
from mirobot_async._view.script_lines import MAX_PATH_POINTS, ScriptLines

JOINT = MotionModes()  # power-on: M21 G90 G0
ZERO = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def _write(lines: ScriptLines, key: int, text: str, modes: MotionModes = JOINT) -> int:
    return lines.written(key, parse_line(text), text, modes, (0.0, 0.0, 0.0))


@pytest.mark.parametrize("firmware", ["2021", "classic", "2024"])
def test_the_path_starts_at_rest_and_follows_each_line(firmware: str) -> None:
    lines = ScriptLines(firmware)
    _write(lines, 1, "G0 X10")  # before any status at rest: counted, not drawn
    assert lines.undrawn == 1 and not lines.path()
    lines.at_rest(ZERO)
    assert lines.predicting
    assert _write(lines, 2, "G0 X30") == 2
    assert _write(lines, 3, "G0 Y20") == 3
    assert [s.number for s in lines.path()] == [2, 3]
    assert lines.state.joints is not None and lines.state.joints[:2] == (30.0, 20.0)


def test_a_refused_last_line_keeps_the_path_and_a_refused_earlier_one_stops_it() -> None:
    lines = ScriptLines("2021")
    lines.at_rest(ZERO)
    _write(lines, 1, "G0 X30")
    _write(lines, 2, "G0 X200")
    lines.answered(1, "G0 X30", 0.1)
    lines.answered(2, "G0 X200", 0.2, refused="Soft limit triggered:X")
    assert lines.state.joints is not None and lines.state.joints[0] == 30.0  # from before it
    assert [(e.kind, e.text) for e in lines.events] == [
        ("refused", "line 2 `G0 X200`: Soft limit triggered:X")
    ]
    assert [m.label for m in lines.markers] == ["line 2"]
    _write(lines, 3, "G0 X300")
    _write(lines, 4, "G0 X10")  # written behind line 3, predicted from line 3's end
    lines.answered(3, "G0 X300", 0.3, error="error: Bad number")
    assert not lines.predicting and lines.count_failed == 2
    assert lines.events[-1].kind == "error"
    lines.at_rest((10.0, 0.0, 0.0, 0.0, 0.0, 0.0))  # seen at rest: it starts again there
    assert lines.state.joints is not None and lines.state.joints[0] == 10.0


def test_refused_before_sending_alarm_and_reset_are_listed() -> None:
    lines = ScriptLines("classic")
    lines.at_rest(ZERO)
    lines.not_sent("G0 X999", "J1=999 is outside -100..160", 0.5)
    assert lines.predicting  # nothing was written: the path is where it was
    assert [m.label for m in lines.markers] == ["not sent"]
    lines.alarm("Hard limit", 1.0)
    assert not lines.predicting
    lines.at_rest(ZERO)
    lines.reset(2.0)
    assert [e.kind for e in lines.events] == ["not sent", "alarm", "reset"]
    text = lines.describe("ended")
    assert text.startswith("**Script: ended**") and "not sent" in text and "Hard limit" in text


def test_homing_puts_the_path_at_zero_and_an_unknown_mode_stops_it() -> None:
    lines = ScriptLines("2021")
    _write(lines, 1, "$H")
    assert lines.state.joints == ZERO
    _write(lines, 2, "G0 X10", MotionModes.unknown())  # relies on modes nobody stated
    assert not lines.predicting and not lines.path()
    _write(lines, 3, "G0 X20")  # its start is unknown: counted, not drawn
    assert lines.undrawn == 1 and not lines.path()


def test_the_path_kept_is_bounded() -> None:
    lines = ScriptLines("2021")
    lines.at_rest(ZERO)
    for key in range(400):
        _write(lines, key, f"G0 X{100 if key % 2 else -90} Y40")
    assert lines.points <= MAX_PATH_POINTS
    assert lines.path()[-1].number == 400
