"""The envelope guard's bookkeeping around refusals, resets and listings (issue 23 items 1, 3
and 4), without a link: lines are 'written' by calling the guard as the scheduler does."""

from __future__ import annotations

import pytest

from mirobot_async._client.condition import Firmware, RobotCondition
from mirobot_async._client.guard import EnvelopeGuard, NullGuard, Tracked
from mirobot_async._client.wire import ClientStats
from mirobot_async._core.line import parse_line
from mirobot_async._core.modal import LineCheck
from mirobot_async._core.replies import parse_status
from mirobot_async._safety.envelope import Envelope
from mirobot_async.errors import MirobotUsageError, RefusalReason

AT_REST = (
    "<Idle,Angle(ABCDXYZ):0.000,0.000,0.000,0.000,0.000,0.000,0.000,Cartesian coordinate(XYZ "
    "RxRyRz):202.000,0.000,181.000,0.000,0.000,0.000,Pump PWM:0,Valve PWM:0,Motion_MODE:0>"
)
ZERO = "0.000,0.000,0.000,0.000,0.000,0.000,0.000"
SETTINGS = {
    20: 1.0,
    35: 1.0,
    41: 0.0,
    42: 0.0,
    43: 0.0,
    **{n: 1000.0 for n in (*range(130, 137), *range(140, 147))},
}


def ready_guard(startup: list[str] | None = None, firmware: Firmware = "classic") -> EnvelopeGuard:
    """A guard on an arm at rest at zero, with the listings read."""
    guard = EnvelopeGuard(Envelope(joints={1: (-50, 50)}), RobotCondition(firmware), ClientStats())
    guard.adopt_settings(SETTINGS)
    guard.adopt_query("$N", [f"$N{n}={text}" for n, text in enumerate(startup or ["", ""])])
    guard.adopt_query("$#", [f"[G{n}:{ZERO}]" for n in (54, 55, 56, 57, 58, 59, 28, 30, 92)])
    guard.adopt_status(parse_status(AT_REST))
    assert guard.wanted_queries() == () and not guard.wants_settings
    return guard


def write(guard: EnvelopeGuard, line_id: int, text: str) -> Tracked:
    parsed = parse_line(text)
    verdict = guard.verdict(parsed, None)
    assert isinstance(verdict, LineCheck), verdict
    tracked = guard.track_written(
        line_id, text, parsed, verdict, checked=True, what=None, warn_unchecked=False
    )
    assert tracked is not None
    return tracked


def test_a_locked_refusal_of_the_last_line_moves_the_parser() -> None:
    guard = ready_guard()
    tracked = write(guard, 1, "M21 G91 G0 G21 X40")
    guard.line_failed(tracked, rejected=False, reason=RefusalReason.LOCKED)
    write(guard, 2, "M50")
    with pytest.raises(MirobotUsageError, match="J1 range"):
        guard.verdict(parse_line("G91 X45"), None)  # from the parser's 40: 85
    assert write(guard, 3, "G91 X5").check is not None


def test_a_soft_limit_refusal_leaves_the_parser() -> None:
    guard = ready_guard()
    tracked = write(guard, 1, "M21 G91 G0 G21 X40")
    guard.line_failed(tracked, rejected=False, reason=RefusalReason.SOFT_LIMIT)
    check = write(guard, 2, "G91 X45").check
    assert check is not None and check.joints is not None and check.joints[0] == pytest.approx(45)


def test_a_refusal_followed_by_other_lines_makes_the_parser_unknown() -> None:
    guard = ready_guard()
    first = write(guard, 1, "M21 G91 G0 G21 X40")
    write(guard, 2, "G4 P0")
    guard.line_failed(first, rejected=False, reason=RefusalReason.LOCKED)
    guard.adopt_status(parse_status(AT_REST))
    with pytest.raises(MirobotUsageError, match="parser position is unknown"):
        guard.verdict(parse_line("G91 X5"), None)
    write(guard, 3, "M21 G91 X5")  # M21 re-reads the arm's position


@pytest.mark.parametrize(("firmware", "relative"), [("classic", True), ("2021", None)])
def test_a_reset_runs_the_startup_lines(firmware: Firmware, relative: bool | None) -> None:
    guard = ready_guard(["G91", ""], firmware)
    guard.forget("reset")
    assert guard.modes.relative is relative  # 2021: they may not have run (Alarm)
    assert guard.modes.cartesian is False


def test_homing_runs_the_startup_lines() -> None:
    guard = ready_guard(["G91", ""])
    write(guard, 1, "$H")
    assert guard.modes.relative is True


def test_an_unchecked_g10_makes_the_offsets_unknown() -> None:
    guard = ready_guard()
    parsed = parse_line("G10 L2 P1 X40")
    guard.track_written(
        1, "G10 L2 P1 X40", parsed, None, checked=False, what=None, warn_unchecked=False
    )
    assert "$#" in guard.wanted_queries()
    guard.adopt_status(parse_status(AT_REST))
    with pytest.raises(MirobotUsageError, match="work offset"):
        guard.verdict(parse_line("M21 G90 G0 G21 X10"), None)


@pytest.mark.parametrize(
    ("line", "predicted"),
    [("$41=5", (5.0, 0.0, 0.0)), ("$042=1", (0.0, 1.0, 0.0)), ("$RST=*", None), ("$41=", None)],
)
def test_both_guards_forget_the_base_offset_by_the_same_rule(
    line: str, predicted: tuple[float, float, float] | None
) -> None:
    envelope = ready_guard(firmware="2021")
    null = NullGuard(RobotCondition("2021"))
    null.adopt_settings(SETTINGS)
    assert envelope.base_offset == null.base_offset == (0.0, 0.0, 0.0)
    for guard in (envelope, null):
        guard.track_written(
            9, line, parse_line(line), None, checked=False, what=None, warn_unchecked=False
        )
    # the envelope predicts the setting it can follow; what it cannot, neither guard knows
    assert envelope.base_offset == predicted and null.base_offset is None
    assert envelope.wants_settings is (predicted is None)
