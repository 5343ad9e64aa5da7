"""Status reports under other ``$10`` masks: fields the client skips (``Buf``, ``RX``, ``Lim``)
are read past; reports without the angles or the PWM values are refused with the reason, and a
mask that would produce them is refused before it is written."""

from __future__ import annotations

import pytest

from mirobot_async._core import gcode
from mirobot_async._core.replies import State, parse_status
from mirobot_async._core.validation import check_line
from mirobot_async.errors import MirobotProtocolError, MirobotUsageError

BASE = (
    "<Idle,Angle(ABCDXYZ):0.000,0.000,0.000,0.000,10.000,0.000,0.000,"
    "Cartesian coordinate(XYZ RxRyRz):198.670,0.000,230.720,0.000,0.000,0.000,"
    "Pump PWM:0,Valve PWM:0"
)


@pytest.mark.parametrize(
    "tail",
    [
        ">",
        ",Motion_MODE:0>",
        ",Motion_MODE:0,Buf:0>",
        ",Buf:15,RX:0>",
        ",Lim:0000000>",
        ",Motion_MODE:1,Buf:2,RX:127,Lim:1000000>",
    ],
)
def test_added_fields_are_read_past(tail: str) -> None:
    report = parse_status(BASE + tail)
    assert report.state is State.IDLE and report.joints[0] == 10.0


@pytest.mark.parametrize("line", ["<Idle>", "<Idle,Pump PWM:0,Valve PWM:0,Motion_MODE:0>"])
def test_a_report_without_angles_names_the_mask(line: str) -> None:
    with pytest.raises(MirobotProtocolError, match=r"\$10"):
        parse_status(line)


@pytest.mark.parametrize("mask", [0, 1, 32, 98, 2, 222])
def test_a_mask_the_client_cannot_read_is_refused(mask: int) -> None:
    with pytest.raises(MirobotUsageError, match=r"angles \(1\) or the PWM values \(32\)"):
        gcode.set_setting(10, mask)
    assert any("status report mask" in p for p in check_line(f"$10={mask}"))


@pytest.mark.parametrize("mask", [33, 99, 103, 127, 255])
def test_a_mask_with_angles_and_pwm_passes(mask: int) -> None:
    assert gcode.set_setting(10, mask) == f"$10={mask}\n".encode()
    assert check_line(f"$10={mask}") == []
