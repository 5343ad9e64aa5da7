"""The pure prediction of what the firmware keeps and where its parser stands (issue 23 items
1-4, soft limits): parser position after a refused move, ``M20 G1`` in joint space, startup
lines, work offsets, soft limits; and the parsing of the ``$N``/``$#``/``$G`` listings."""

from __future__ import annotations

from dataclasses import replace

import pytest

from mirobot_async._core.line import parse_line
from mirobot_async._core.modal import LineCheck, MotionModes
from mirobot_async._safety.envelope import Envelope
from mirobot_async._safety.firmware_memory import (
    PARSER_UNKNOWN,
    ParserPosition,
    WorkCoordinates,
    apply_startup_lines,
    parse_coordinate_system,
    parse_startup_lines,
    parse_work_offsets,
    reset_modes,
    soft_limit_ranges,
    work_offset,
)
from mirobot_async._safety.prediction import (
    EnvelopeRefusal,
    MachineState,
    Prediction,
    predict,
    state_after_refusal,
)
from mirobot_async.errors import RefusalReason
from mirobot_async.kinematics import DH_CLASSIC, forward

HOME = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
JOINT = MotionModes(cartesian=False, relative=True, motion=0, inches=False)
J1_50 = Envelope(joints={1: (-50, 50)})
STATE = MachineState(JOINT, HOME, rail=0.0, base_offset=(0.0, 0.0, 0.0), firmware="classic")
# $20, $130..$136 (J4 J5 J6 D J1 J2 J3 positive), $140..$146 (negative magnitudes)
SOFT = (1.0, 350, 36, 360, 1000, 160, 70, 60, 350, 205, 360, 1000, 20, 30, 170)


def passed(result: Prediction | EnvelopeRefusal) -> MachineState:
    assert isinstance(result, Prediction), result
    return result.state


def refused(result: Prediction | EnvelopeRefusal, *words: str) -> str:
    assert isinstance(result, EnvelopeRefusal), result
    for word in words:
        assert word in result.reason, result.reason
    return result.reason


# ---- item 1: the parser's position ----------------------------------------------------------


def test_a_relative_move_starts_where_the_parser_stands() -> None:
    state = replace(STATE, parser=ParserPosition((40.0, 0, 0, 0, 0, 0), 0.0))
    refused(predict(J1_50, "G91 X45", state), "J1 range")  # 40 + 45 = 85
    after = passed(predict(J1_50, "G91 X5", state))
    assert after.joints is not None and after.joints[0] == pytest.approx(45)
    assert after.parser is None  # the parser and the arm meet at the target


def test_a_line_with_m21_rereads_the_arm() -> None:
    state = replace(STATE, parser=ParserPosition((40.0, 0, 0, 0, 0, 0), 0.0))
    after = passed(predict(J1_50, "M21 G91 X45", state))
    assert after.joints is not None and after.joints[0] == pytest.approx(45)


def test_a_missing_axis_keeps_the_parsers_value() -> None:
    state = replace(STATE, parser=ParserPosition((0.0, 0, 0, 0, 0, 30.0), 0.0))
    after = passed(predict(J1_50, "G90 X10", state))
    assert after.joints == pytest.approx((10, 0, 0, 0, 0, 30))


def test_an_unknown_parser_refuses_what_relies_on_it() -> None:
    state = replace(STATE, parser=PARSER_UNKNOWN)
    refused(predict(J1_50, "G91 X5", state), "parser position is unknown")
    refused(predict(J1_50, "G90 X5", state), "parser position is unknown")
    passed(predict(J1_50, "G90 X5 Y0 Z0 A0 B0 C0", state))
    passed(predict(J1_50, "M21 G91 X5", state))


def test_where_a_refusal_leaves_the_parser() -> None:
    before = STATE
    check = LineCheck(JOINT, True, (40.0, 0, 0, 0, 0, 0), None, 0.0)
    locked = state_after_refusal(before, before, check, RefusalReason.LOCKED)
    assert locked.parser == ParserPosition((40.0, 0, 0, 0, 0, 0), 0.0)
    assert locked.joints == HOME
    soft = state_after_refusal(before, before, check, RefusalReason.SOFT_LIMIT)
    assert soft.parser is None
    assert state_after_refusal(before, before, None, RefusalReason.LOCKED).parser is PARSER_UNKNOWN
    pose = (200.0, 0.0, 150.0, 0.0, 0.0, 0.0)
    cart = LineCheck(replace(JOINT, cartesian=True), True, None, pose, 0.0)
    moved = state_after_refusal(before, before, cart, RefusalReason.UNREACHABLE)
    assert moved.pose == pose and moved.joints == HOME and moved.parser is None


# ---- item 2: M20 G1 in joint space -----------------------------------------------------------


def _mirror_line(j1: float) -> str:
    x, y, z, a, b, c = forward((j1, 0.0, 0.0, 0.0, 0.0, 0.0), DH_CLASSIC)
    return f"M20 G90 G1 X{x:.3f} Y{y:.3f} Z{z:.3f} A{a:.3f} B{b:.3f} C{c:.3f} F2000"


@pytest.mark.parametrize("firmware", ["classic", "2021"])
def test_m20_g1_is_a_joint_move_on_classic_and_with_35_off(firmware: str) -> None:
    envelope = Envelope(x=(None, 170), dh=DH_CLASSIC)
    start = (-40.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    state = replace(STATE, joints=start, firmware=firmware, linear_g1=firmware == "2021")
    line = _mirror_line(40)
    if firmware == "2021":  # $35=1: a straight line at x = 154.7 mm
        passed(predict(envelope, line, state))
        state = replace(state, linear_g1=False)
    refused(predict(envelope, line, state), "joint-space path", "maximum x=170")


def test_m20_g1_on_2021_needs_setting_35() -> None:
    state = replace(STATE, firmware="2021", linear_g1=None)
    refused(predict(J1_50, "M20 G90 G1 X200 Y0 Z200 F2000", state), "$35")
    after = passed(predict(J1_50, "$35=0", state))
    assert after.linear_g1 is False


# ---- item 3: startup lines -------------------------------------------------------------------


def test_homing_runs_the_startup_lines() -> None:
    state = replace(STATE, startup_lines=("G91",))
    after = passed(predict(J1_50, "$H", state))
    assert after.modes.relative is True
    unknown = passed(predict(J1_50, "$H", replace(STATE, startup_lines=None)))
    assert unknown.modes == MotionModes.unknown()


def test_startup_lines_after_a_reset() -> None:
    assert reset_modes(("G91",), ran=True).relative is True
    assert reset_modes(("G91",), ran=None).relative is None  # may have run: unknown
    assert reset_modes(("G91",), ran=None).cartesian is False  # untouched: power-on
    assert reset_modes((), ran=None) == MotionModes()
    assert reset_modes(None, ran=None) == MotionModes.unknown()
    assert apply_startup_lines(MotionModes(), ("M20", "G20"), certain=True).inches is True


def test_parse_startup_lines() -> None:
    assert parse_startup_lines(["$N0=G91", "$N1="]) == ("G91",)
    assert parse_startup_lines(["$N0=", "$N1="]) == ()
    assert parse_startup_lines(["ok"]) is None


# ---- item 4: work offsets --------------------------------------------------------------------


def test_work_offsets_add_to_absolute_targets() -> None:
    state = replace(STATE, modes=replace(JOINT, relative=False), work_offset=(40, 0, 0, 0, 0, 0, 0))
    refused(predict(J1_50, "X30", state), "J1 range")  # 30 + 40
    after = passed(predict(J1_50, "X-30", state))
    assert after.joints is not None and after.joints[0] == pytest.approx(10)
    relative = passed(predict(J1_50, "G91 X5", state))  # relative words: no offset
    assert relative.joints is not None and relative.joints[0] == pytest.approx(5)


def test_work_offsets_add_to_cartesian_targets() -> None:
    state = replace(STATE, work_offset=(40, 0, 0, 0, 0, 0, 0))
    after = passed(predict(Envelope(dh=DH_CLASSIC), "M20 G90 G0 X202 Y0 Z181 A0 B0 C0", state))
    assert after.pose is not None and after.pose[0] == pytest.approx(242)  # oracle: x = 242


def test_an_unknown_work_offset_refuses_absolute_moves() -> None:
    state = replace(STATE, work_offset=None)
    refused(predict(J1_50, "G90 X10", state), "work offset")
    passed(predict(J1_50, "G91 X10", state))


def test_parse_work_offsets_and_coordinate_system() -> None:
    zero = "0.000,0.000,0.000,0.000,0.000,0.000,0.000"
    rows = [f"[G{n}:{zero}]" for n in (55, 56, 57, 58, 59, 28, 30, 92)]
    parsed = parse_work_offsets(["[G54:1.000,2.000,3.000,4.000,40.000,5.000,6.000]", *rows])
    assert parsed is not None
    systems, g92 = parsed
    assert systems[0] == (40, 5, 6, 1, 2, 3, 4)  # ABCDXYZ printed, XYZABCD kept
    assert parse_work_offsets(rows[1:]) is None
    assert work_offset(systems, g92, 54) == systems[0]
    assert work_offset(systems, g92, None) is None  # rows differ, system unknown
    assert work_offset(systems[1:] + systems[1:2], g92, None) == systems[1]
    assert parse_coordinate_system(["[G0 G55 G17 G21 G90 G94 M0 M5 M9 T0 F200. S0.]"]) == 55


# ---- soft limits -----------------------------------------------------------------------------


def test_soft_limits_narrow_the_envelope() -> None:
    state = replace(STATE, modes=replace(JOINT, relative=False), soft_limits=SOFT)
    refused(predict(J1_50, "X-45", state), "J1 range -20..50")
    passed(predict(J1_50, "X-15", state))
    off = passed(predict(J1_50, "$20=0", state))
    passed(predict(J1_50, "X-45", off))
    wider = passed(predict(J1_50, "$144=100", state))
    passed(predict(J1_50, "X-45", wider))


def test_soft_limit_ranges() -> None:
    ranges = soft_limit_ranges(SOFT)
    assert ranges is not None
    assert ranges[0] == (-20, 160) and ranges[3] == (-350, 350) and ranges[6] == (-1000, 1000)
    assert soft_limit_ranges((0.0, *SOFT[1:])) is None


def test_work_coordinates_bookkeeping() -> None:
    work = WorkCoordinates()
    assert work.wanted(startup_known=False) == ("$N", "$#", "$G")
    zero = "0.000,0.000,0.000,0.000,0.000,0.000,0.000"
    work.adopt("$#", [f"[G{n}:{zero}]" for n in (54, 55, 56, 57, 58, 59, 28, 30, 92)])
    assert work.wanted(startup_known=True) == ()  # all six equal: which one does not matter
    assert work.offset(None) == (0.0,) * 7
    work.forget_after(parse_line("G10 L2 P2 X5"))
    assert work.systems is None and work.wanted(startup_known=True) == ("$#", "$G")
    work.adopt("$#", None)  # the firmware refused it: not asked again, stays unknown
    assert work.wanted(startup_known=True) == ("$G",)
    assert work.offset(None) is None
    work.forget_after(parse_line("G55"))
    assert work.coordinate is None
    work.follow(parse_line("G54 G90"))
    assert work.coordinate == 54
    work.reinitialised(("G0 X10",), ran=True)  # a startup line that moves: read again
    assert work.systems is None and work.g92 is None
