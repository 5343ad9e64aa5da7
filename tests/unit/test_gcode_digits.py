"""The builders' own digit check agrees with the firmware's number reader (no re-parse needed)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mirobot_async import MirobotUsageError
from mirobot_async._core import gcode
from mirobot_async._core.line import parse_line, read_number
from mirobot_async._core.values import fmt_number


@settings(max_examples=2000)
@given(st.floats(-1e12, 1e12, allow_nan=False), st.integers(0, 6))
def test_the_builders_digit_check_is_the_firmwares(value: float, decimals: int) -> None:
    text = fmt_number(value, decimals)
    number = read_number(text, 0)
    assert number is not None
    assert gcode._lossy_number(text) == number.lossy


@given(st.floats(-1e6, 1e6, allow_nan=False), st.integers(0, 6))
def test_a_built_line_is_read_back_as_written_or_refused(value: float, decimals: int) -> None:
    try:
        line = gcode.move_pose(x=value, z=value, decimals=decimals)
    except MirobotUsageError as err:
        assert "8 digits" in str(err) or "Line overflow" in str(err)
        return
    assert not parse_line(line).has_odd_numbers


def test_a_number_the_firmware_would_cut_is_refused() -> None:
    with pytest.raises(MirobotUsageError, match=r"would read 123456\.78"):
        gcode.move_pose(x=123456.789)
