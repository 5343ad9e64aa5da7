"""The homing bound (how long a homing line may go unanswered) and the default timeouts of the
lines the firmware answers late (ARCHITECTURE.md, "Timeouts and liveness", rows 4, 10, 14)."""

from __future__ import annotations

import pytest

from mirobot_async._client.condition import (
    HOMING_BOUND,
    RobotCondition,
    homing_bound,
)
from mirobot_async._client.parts import (
    DEFAULT_TIMEOUT,
    HOME_TIMEOUT,
    MOVE_TIMEOUT,
    default_reply_timeout,
)
from mirobot_async._core.line import parse_line
from mirobot_async.bus._ledger import Kind, NodeLedger, Owed, forwarded_line


@pytest.mark.parametrize(
    ("line", "homing"),
    [
        ("$H", "$H"),
        ("(x)$H", "$H"),
        ("$h ; home", "$H"),
        ("$HH", "$HH"),
        ("$H0", "$H"),
        ("$H7", "$H"),
        ("$HE", "$HH"),
        ("$HX", "$HH"),
        ("$H9", "$HH"),
        ("$X", None),
        ("G28", None),
        ("(x)", None),
    ],
)
def test_homing_lines(line: str, homing: str | None) -> None:
    parsed = parse_line(line)
    assert parsed.homing_kind == homing and parsed.is_homing is (homing is not None)
    assert forwarded_line(line, 1).homing_kind == homing  # the bus reads the same parse


def test_bounds_cover_the_measured_searches_with_room() -> None:
    assert homing_bound("$H") == HOMING_BOUND["$H"] >= 3 * 15.0  # real arms: 10-15 s
    assert homing_bound("$HH") == HOMING_BOUND["$HH"] >= 4 * 29.11


def test_slower_homing_rates_stretch_the_bound_faster_ones_do_not_shrink_it() -> None:
    assert homing_bound("$H", (750.0, 2000.0)) == pytest.approx(2 * HOMING_BOUND["$H"])
    assert homing_bound("$H", (1500.0, 500.0)) == pytest.approx(4 * HOMING_BOUND["$H"])
    assert homing_bound("$H", (3000.0, 4000.0)) == HOMING_BOUND["$H"]
    assert homing_bound("$H", (0.0, 2000.0)) == HOMING_BOUND["$H"]  # nonsense rate: ignored


def test_the_condition_learns_the_rates_from_settings_and_lines() -> None:
    condition = RobotCondition("classic")
    assert condition.homing_rates is None
    condition.learn_firmware_from_settings({24: 1000.0, 25: 1000.0, 22: 1.0})
    assert condition.homing_rates == (1000.0, 1000.0)
    condition.set_homing_rate(25, 500.0)
    assert condition.homing_rates == (1000.0, 500.0)
    assert condition.homing_silent(0.0) is None


@pytest.mark.parametrize(
    ("line", "timeout"),
    [
        ("$H", HOME_TIMEOUT),
        ("$HH", HOME_TIMEOUT),
        ("M3 S1000", MOVE_TIMEOUT),
        ("M4 E500", MOVE_TIMEOUT),
        ("M5", MOVE_TIMEOUT),
        ("M30", MOVE_TIMEOUT),
        ("G4 P5", MOVE_TIMEOUT + 5),
        ("M21 G90 G0 X10", DEFAULT_TIMEOUT),
        ("$$", DEFAULT_TIMEOUT),
    ],
)
def test_default_reply_timeouts(line: str, timeout: float) -> None:
    assert default_reply_timeout(parse_line(line)) == timeout


def test_a_bus_status_request_answers_every_copy_it_stands_for() -> None:
    delivered: list[bytes] = []
    ledger = NodeLedger(delivered.append)
    owed = Owed(Kind.STATUS, "?", 2, status_owed=True, copies=3)
    ledger.add(owed)
    ledger.take(b"<Idle,Angle(ABCDXYZ):0.000>\r\n")
    assert delivered == [b"<Idle,Angle(ABCDXYZ):0.000>\r\n"] * 3
