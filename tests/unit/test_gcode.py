"""Unit tests for mirobot_async._core.gcode: exact bytes, validation, formatting, offline
checking."""

from __future__ import annotations

import math
import re
from collections.abc import Callable

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mirobot_async._core import gcode
from mirobot_async.errors import MirobotUsageError

# --------------------------------------------------------------------------------------------
# Exact bytes
# --------------------------------------------------------------------------------------------

EXACT: list[tuple[Callable[[], bytes], bytes]] = [
    (lambda: gcode.move_joints(10, -5.5, speed=2000), b"M21 G90 G1 X10 Y-5.5 F2000\n"),
    (lambda: gcode.move_joints(j1=10), b"M21 G90 G0 X10\n"),
    (
        lambda: gcode.move_joints(1, 2, 3, 4, 5, 6, 7, speed=1500.5),
        b"M21 G90 G1 X1 Y2 Z3 A4 B5 C6 D7 F1500.5\n",
    ),
    (lambda: gcode.move_joints(j6=-360, j5=36), b"M21 G90 G0 B36 C-360\n"),
    (lambda: gcode.move_joints(j2=500, relative=True), b"M21 G91 G0 Y500\n"),
    (lambda: gcode.move_joints(j1=500, check_limits=False), b"M21 G90 G0 X500\n"),
    (lambda: gcode.move_joints(rail=-900, firmware="classic"), b"M21 G90 G0 D-900\n"),
    (lambda: gcode.move_joints(j1=1.23456, decimals=1), b"M21 G90 G0 X1.2\n"),
    (lambda: gcode.move_joints(j1=-0.0001), b"M21 G90 G0 X0\n"),
    (lambda: gcode.move_joints(j1=160.0004), b"M21 G90 G0 X160\n"),
    (
        lambda: gcode.move_pose(200, 0, 230.72, linear=True, speed=1000),
        b"M20 G90 G1 X200 Y0 Z230.72 F1000\n",
    ),
    (
        lambda: gcode.move_pose(150, -30, 55, 0, 0, 0),
        b"M20 G90 G0 X150 Y-30 Z55 A0 B0 C0\n",
    ),
    (lambda: gcode.move_pose(z=10, speed=2000), b"M20 G90 G0 Z10 F2000\n"),
    (
        lambda: gcode.move_pose(x=10, y=-30, relative=True, linear=True, speed=500),
        b"M20 G91 G1 X10 Y-30 F500\n",
    ),
    (lambda: gcode.move_pose(rz=-12.5), b"M20 G90 G0 C-12.5\n"),
    (lambda: gcode.arc(250, 10, 60, speed=800), b"M20 G90 G2 X250 Y10 R60 F800\n"),
    (
        lambda: gcode.arc(60, 0, 60, speed=500, clockwise=False, relative=True),
        b"M20 G91 G3 X60 Y0 R60 F500\n",
    ),
    (lambda: gcode.dwell(1.5), b"G4 P1.5\n"),
    (lambda: gcode.dwell(0), b"G4 P0\n"),
    (lambda: gcode.feed_rate(2000), b"F2000\n"),
    (gcode.absolute, b"G90\n"),
    (gcode.relative, b"G91\n"),
    (gcode.cartesian_mode, b"M20\n"),
    (gcode.joint_mode, b"M21\n"),
    (gcode.home, b"$H\n"),
    (lambda: gcode.home(sequential=True), b"$HH\n"),
    (lambda: gcode.home_axis(0), b"$H0\n"),
    (lambda: gcode.home_axis(7), b"$H7\n"),
    (gcode.home_compact, b"$HE\n"),
    (gcode.zero_pose, b"$M\n"),
    (gcode.unlock_axes, b"M50\n"),
    (gcode.clear_alarm, b"$X\n"),
    (gcode.settings_dump, b"$$\n"),
    (lambda: gcode.set_soft_limits(True), b"$20=1\n"),
    (lambda: gcode.set_soft_limits(False), b"$20=0\n"),
    (lambda: gcode.set_hard_limits(True), b"$21=1\n"),
    (lambda: gcode.set_hard_limits(0), b"$21=0\n"),  # type: ignore[arg-type]
    (lambda: gcode.set_homing(True), b"$22=1\n"),
    (lambda: gcode.set_setting(34, -24.28), b"$34=-24.28\n"),
    (lambda: gcode.set_setting(110, 1800), b"$110=1800\n"),
    (lambda: gcode.set_setting(110, 1800.0, firmware="classic"), b"$110=1800\n"),
    (lambda: gcode.set_setting(20, True), b"$20=1\n"),
    (lambda: gcode.set_setting(30, 29.69), b"$30=29.69\n"),
    (lambda: gcode.set_setting(166, 0.5), b"$166=0.5\n"),
    (lambda: gcode.set_pump(gcode.PUMP_SUCK), b"M3 S1000\n"),
    (lambda: gcode.set_pump(gcode.PUMP_BLOW), b"M3 S500\n"),
    (lambda: gcode.set_pump(gcode.PUMP_OFF), b"M3 S0\n"),
    (lambda: gcode.set_pump(500.0), b"M3 S500\n"),  # type: ignore[arg-type]
    (lambda: gcode.set_valve(65), b"M4 E65\n"),
    (lambda: gcode.set_gripper(True), b"M3 S60\n"),
    (lambda: gcode.set_gripper(False), b"M3 S40\n"),
    (lambda: gcode.set_gripper(True, legacy=True), b"M4 E40\n"),
    (lambda: gcode.set_gripper(False, legacy=True), b"M4 E65\n"),
]


@pytest.mark.parametrize(("build", "expected"), EXACT)
def test_exact_bytes(build: Callable[[], bytes], expected: bytes) -> None:
    line = build()
    assert line == expected
    _assert_wire_line(line)
    if expected == b"M21 G90 G0 X500\n":  # built with check_limits=False on purpose
        assert gcode.check_line(line) == ["J1=500 is outside -100..160"]
    else:
        firmware = "classic" if b"D-" in line else "2021"
        assert gcode.check_line(line, firmware=firmware) == []


# --------------------------------------------------------------------------------------------
# fmt_number
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("value", "decimals", "expected"),
    [
        (1e-05, 3, "0"),
        (-1e-05, 3, "0"),
        (-0.0, 3, "0"),
        (-0.0004, 3, "0"),
        (10.0, 3, "10"),
        (10, 3, "10"),
        (-5.5, 3, "-5.5"),
        (1.23456, 3, "1.235"),
        (1.23456, 0, "1"),
        (0.1, 3, "0.1"),
        (100.0, 3, "100"),
        (-0.5, 3, "-0.5"),
        (1e20, 3, "100000000000000000000"),
        (198.67, 3, "198.67"),
        (2.0005, 6, "2.0005"),
    ],
)
def test_fmt_number_examples(value: float, decimals: int, expected: str) -> None:
    assert gcode.fmt_number(value, decimals) == expected


finite = st.floats(min_value=-1e12, max_value=1e12, allow_nan=False, allow_infinity=False)


@given(finite, st.integers(min_value=0, max_value=6))
def test_fmt_number_properties(value: float, decimals: int) -> None:
    text = gcode.fmt_number(value, decimals)
    assert "e" not in text.lower()
    assert re.fullmatch(r"-0(\.0*)?", text) is None
    assert re.fullmatch(r"-?\d+(\.\d*[1-9])?", text), text
    assert math.isclose(float(text), round(value, decimals), rel_tol=0, abs_tol=1e-9)
    assert gcode.fmt_number(value, decimals) == text


@given(st.integers(min_value=-(10**9), max_value=10**9))
def test_fmt_number_integers_have_no_dot(value: int) -> None:
    assert gcode.fmt_number(value) == str(value)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_fmt_number_rejects_non_finite(bad: float) -> None:
    with pytest.raises(MirobotUsageError, match="j3"):
        gcode.fmt_number(bad, name="j3")


@pytest.mark.parametrize("bad", ["1", None, True, 1j])
def test_fmt_number_rejects_non_numbers(bad: object) -> None:
    with pytest.raises(ValueError, match="speed"):
        gcode.fmt_number(bad, name="speed")  # type: ignore[arg-type]


@pytest.mark.parametrize("decimals", [-1, 10, 1.5, True])
def test_fmt_number_rejects_bad_decimals(decimals: object) -> None:
    with pytest.raises(MirobotUsageError, match="decimals"):
        gcode.fmt_number(1.0, decimals)  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------
# Bad inputs
# --------------------------------------------------------------------------------------------

BAD: list[tuple[Callable[[], bytes], str]] = [
    (lambda: gcode.move_joints(), "at least one"),
    (lambda: gcode.move_joints(j1=500), r"j1=500 is outside the joint range -100\.\.160 deg"),
    (lambda: gcode.move_joints(j2=-31), r"j2=-31 .*-30\.\.70"),
    (lambda: gcode.move_joints(j3=60.1), r"j3=60\.1 .*-170\.\.60"),
    (lambda: gcode.move_joints(j4=351), r"j4=351 .*-350\.\.350"),
    (lambda: gcode.move_joints(j5=37), r"j5=37 .*-205\.\.36"),
    (lambda: gcode.move_joints(j6=-361), r"j6=-361 .*-360\.\.360"),
    (lambda: gcode.move_joints(rail=-1), r"rail=-1 .*0\.\.500"),
    (lambda: gcode.move_joints(rail=1001, firmware="classic"), r"rail=1001 .*-1000\.\.1000"),
    (lambda: gcode.move_joints(j1=math.nan), "j1"),
    (lambda: gcode.move_joints(j4=math.inf, check_limits=False), "j4"),
    (lambda: gcode.move_joints(j1=1, speed=0), "speed"),
    (lambda: gcode.move_joints(j1=1, speed=-5), "speed"),
    (lambda: gcode.move_joints(j1=1, speed=0.0001), "speed"),
    (lambda: gcode.move_joints(j1=1, speed=math.nan), "speed"),
    (lambda: gcode.move_joints(j1=1, firmware="2020"), "firmware"),
    (lambda: gcode.move_joints(j1=1, decimals=12), "decimals"),
    (lambda: gcode.move_pose(), "at least one"),
    (lambda: gcode.move_pose(x=1, linear=True), "speed"),
    (lambda: gcode.move_pose(x=1, speed=0), "speed"),
    (lambda: gcode.move_pose(x=math.nan), "x="),
    (lambda: gcode.move_pose(ry=-math.inf), "ry="),
    (lambda: gcode.move_pose(x=1e75), "80"),
    (
        lambda: gcode.move_pose(*[-123456.789] * 6, speed=123456.789),
        "at most 80",
    ),
    (lambda: gcode.arc(10, 10, 0, speed=100), "radius"),
    (lambda: gcode.arc(10, 10, -5, speed=100), "radius"),
    (lambda: gcode.arc(10, 10, 5, speed=0), "speed"),
    (lambda: gcode.arc(math.nan, 10, 5, speed=10), "x="),
    (lambda: gcode.arc(300, 0, 100, speed=10, relative=True), "radius=100 .*Arc radius error"),
    (lambda: gcode.arc(0, 0, 100, speed=10, relative=True), "chord"),
    (lambda: gcode.arc(10, 0, 100, speed=10, firmware="classic"), "2021"),
    (lambda: gcode.dwell(-1), "seconds"),
    (lambda: gcode.dwell(math.nan), "seconds"),
    (lambda: gcode.feed_rate(0), "speed"),
    (lambda: gcode.home_axis(8), r"axis=8 .*0\.\.7"),
    (lambda: gcode.home_axis(-1), "axis"),
    (lambda: gcode.home_axis(1.0), "axis"),  # type: ignore[arg-type]
    (lambda: gcode.home_axis(1, firmware="classic"), "2021"),
    (lambda: gcode.home_compact(firmware="classic"), "2021"),
    (lambda: gcode.zero_pose(firmware="classic"), "2021"),
    (lambda: gcode.set_setting(99, 1), "number=99"),
    (lambda: gcode.set_setting(29, 127, firmware="classic"), "number=29"),
    (lambda: gcode.set_setting(160, 0, firmware="classic"), "number=160"),
    (lambda: gcode.set_setting(1.5, 1), "number"),  # type: ignore[arg-type]
    (
        lambda: gcode.set_setting(110, -1, firmware="classic"),
        "classic firmware rejects negative values: 'Value < 0'",
    ),
    (lambda: gcode.set_setting(20, 2), r"value=2 for \$20 .*0 or 1"),
    (lambda: gcode.set_setting(21, 0.5), r"value=0\.5 .*0 or 1"),
    (lambda: gcode.set_setting(36, 2.5), "value=2.5 .*integer"),
    (lambda: gcode.set_setting(50, 4), r"value=4 .*0\.\.3"),
    (lambda: gcode.set_setting(110, -1), r"value=-1 .*0\.\."),
    (lambda: gcode.set_setting(110, math.nan), "value"),
    (lambda: gcode.set_soft_limits(2), "on"),  # type: ignore[arg-type]
    (lambda: gcode.set_pump(1001), r"pwm=1001 is outside 0\.\.1000"),
    (lambda: gcode.set_pump(-1), r"pwm=-1 .*0\.\.1000"),
    (lambda: gcode.set_pump(500.5), r"pwm=500\.5 .*integer 0\.\.1000"),  # type: ignore[arg-type]
    (lambda: gcode.set_pump(math.nan), "pwm"),  # type: ignore[arg-type]
    (lambda: gcode.set_pump(True), "pwm"),
    (lambda: gcode.set_pump("500"), "pwm"),  # type: ignore[arg-type]
    (lambda: gcode.set_valve(2000), r"pwm=2000 .*0\.\.1000"),
    (lambda: gcode.set_gripper(3), "closed"),  # type: ignore[arg-type]
]


@pytest.mark.parametrize(("build", "message"), BAD)
def test_bad_input_raises_usage_error(build: Callable[[], bytes], message: str) -> None:
    with pytest.raises(MirobotUsageError, match=message) as info:
        build()
    assert isinstance(info.value, ValueError)


# --------------------------------------------------------------------------------------------
# Properties of encoded lines
# --------------------------------------------------------------------------------------------


def _assert_wire_line(line: bytes) -> None:
    assert line.endswith(b"\n")
    assert line.count(b"\n") == 1
    assert b"\r" not in line
    line.decode("ascii")
    assert bytes(line) == bytes(line.upper())
    assert b"  " not in line
    assert len(bytes(b for b in line if b > 0x20)) <= gcode.MAX_LINE_LENGTH


def _in(joint: str) -> st.SearchStrategy[float | None]:
    low, high = gcode.JOINT_RANGES[joint]
    return st.none() | st.floats(min_value=low, max_value=high)


@given(
    _in("J1"),
    _in("J2"),
    _in("J3"),
    _in("J4"),
    _in("J5"),
    _in("J6"),
    st.none() | st.floats(min_value=0, max_value=500),
    st.none() | st.floats(min_value=0.01, max_value=100_000),
)
def test_move_joints_lines_are_valid(
    j1: float | None,
    j2: float | None,
    j3: float | None,
    j4: float | None,
    j5: float | None,
    j6: float | None,
    rail: float | None,
    speed: float | None,
) -> None:
    targets = (j1, j2, j3, j4, j5, j6, rail)
    if all(value is None for value in targets):
        with pytest.raises(MirobotUsageError):
            gcode.move_joints(*targets, speed=speed)
        return
    line = gcode.move_joints(*targets, speed=speed)
    _assert_wire_line(line)
    assert gcode.check_line(line) == []
    words = dict(gcode.parse_words(line)[3:])
    for letter, value in zip("XYZABCD", targets, strict=True):
        if value is not None:
            assert words[letter] == float(gcode.fmt_number(value))
    if speed is not None:
        assert words["F"] == float(gcode.fmt_number(speed))


@given(
    st.lists(st.none() | finite, min_size=6, max_size=6),
    st.none() | st.floats(min_value=0.01, max_value=1e9),
    st.booleans(),
    st.booleans(),
)
def test_move_pose_lines_are_valid_or_refused(
    values: list[float | None], speed: float | None, linear: bool, relative: bool
) -> None:
    try:
        line = gcode.move_pose(*values, speed=speed, linear=linear, relative=relative)
    except MirobotUsageError as exc:
        assert (
            all(value is None for value in values)
            or (linear and speed is None)
            or "at most 80" in str(exc)
            or "8 digits" in str(exc)
        )
        return
    _assert_wire_line(line)
    assert gcode.check_line(line) == []


@given(st.integers(min_value=0, max_value=1000))
def test_pwm_lines(pwm: int) -> None:
    for line in (gcode.set_pump(pwm), gcode.set_valve(pwm)):
        _assert_wire_line(line)
        assert gcode.check_line(line) == []


@pytest.mark.parametrize("firmware", gcode.FIRMWARE_PROFILES)
def test_every_known_setting_can_be_written(firmware: str) -> None:
    for number, info in gcode.SETTINGS[firmware].items():
        value = 1 if info.minimum is None else info.minimum
        line = gcode.set_setting(number, value, firmware=firmware)
        assert line == f"${number}={gcode.fmt_number(value)}\n".encode()
        assert gcode.check_line(line, firmware=firmware) == []
        assert info.description


def test_settings_tables() -> None:
    classic, new = gcode.SETTINGS["classic"], gcode.SETTINGS["2021"]
    assert set(classic) < set(new)
    for number in (20, 21, 22, 4, 5, 6, 13):
        assert classic[number].kind == "bool"
    assert new[35].kind == "bool"
    for number in (*range(29, 37), *range(41, 44), *range(46, 51), *range(150, 157), 160, 166):
        assert number in new and number not in classic
    assert "J1" in new[104].description and "J4" in new[100].description
    assert "rail" in new[103].description and new[103].unit == "steps/mm"
    assert "backlash" in new[164].description
    assert gcode.JOINT_RANGES["J1"] == (-100.0, 160.0)
    assert gcode.RAIL_RANGES == {
        "2021": (0.0, 500.0),
        "classic": (-1000.0, 1000.0),
        "2024": (0.0, 500.0),
    }


# --------------------------------------------------------------------------------------------
# Offline checker
# --------------------------------------------------------------------------------------------

GOOD_LINES = [
    "",
    "   ",
    "M21 G90 X10 Y15 C10 F2000",
    "m20g90g0x150y-30z55a0b0c0f2000",
    "M20 G91 G03 X60 Y0 Z0 R60 F100",
    "G04 P1.5",
    "M3S500",
    "M4 E65",
    "$H",
    "$HH",
    "$HE",
    "$H0",
    "$M",
    "$$",
    "$X",
    "$20=0",
    "$34=-24.28",
    "M50",
    "F2000",
    "(a comment) G0 X10 ; another",
    "M21 G90 X160 Y-30 Z60 A-350 B36 C360 D500",
    "G90 X-100",
    "M21 G91 X500",
    "M20 G90 G0 X250",
    "M2",
    "M21 G21 G90 G0 X1",
    "N10 G00 X-.5",
    "$041=1",
]


@pytest.mark.parametrize("line", GOOD_LINES)
def test_check_line_good(line: str) -> None:
    assert gcode.check_line(line) == []


BAD_LINES: list[tuple[str, str, str]] = [
    ("M21 G90 X500", "2021", "J1=500 is outside -100..160"),
    ("G0 X500", "2021", "J1=500 is outside -100..160"),
    ("M21 X10 C400", "2021", "J6=400 is outside -360..360"),
    ("M21 G90 D600", "2021", "rail D=600 is outside 0..500"),
    ("M21 G90 D-1", "classic", ""),
    ("G0 " + "X1.0000000 " * 9, "2021", "Line overflow"),
    ("M20 G1 G0 X1", "2021", "Modal group violation"),
    ("G90 G91 X1", "2021", "Modal group violation"),
    ("M20 M21", "2021", "Modal group violation"),
    ("X1 X2", "2021", "twice"),
    ("G0 X", "2021", "Bad number format"),
    ("G0 #1", "2021", "Expected command letter"),
    ("T1", "2021", "not used by the Mirobot"),
    ("G20", "2021", "inches"),
    ("G0 X0000000030", "2021", "reads it as 0"),
    ("M16404", "2021", "read by the firmware as M20"),
    ("M20.001 G0 X10", "2021", "read by the firmware as M20"),
    ("M20.5", "2021", "Invalid gcode ID:23"),
    ("G21 M21", "2021", "first in the line"),
    ("M21 M3 S10", "2021", "use two lines"),
    ("$041.5=1", "2021", "reads this as $41=1"),
    ("$H8", "2021", "homes the arm"),
    ("M7", "2021", "Unsupported command"),
    ("M20 G2 X10 Y10 R5 F100", "classic", "needs the 2021 firmware"),
    ("$H7", "classic", "needs the 2021 firmware"),
    ("$M", "classic", "needs the 2021 firmware"),
    ("G4", "2021", "G4 needs P"),
    ("G4 P-1", "2021", "Value < 0"),
    ("G1 X10 F-5", "2021", "Value < 0"),
    ("G1 X10 F0", "2021", "Undefined feed rate"),
    ("M3 S2000", "2021", "0..1000"),
    ("M4 E-1", "2021", "0..1000"),
    ("M20 G91 G2 X300 Y0 R100 F100", "2021", "Arc radius error"),
    ("M20 G2 X10 Y10 F100", "2021", "needs R"),
    ("M21 G2 X10 Y10 R100 F100", "2021", "M20"),
    ("G0 X10 R5", "2021", "unused"),
    ("$20=2", "2021", "$20=2 (soft limits) must be 0 or 1"),
    ("$99=1", "2021", "$99 is not a known"),
    ("$110=-1", "classic", "Value < 0"),
    ("$110=abc", "2021", "Bad number format"),
    ("$110", "2021", "=value"),
    ("$Q", "2021", "Invalid statement"),
    ("G0 X1 ?", "2021", "status request"),
    ("G0 X1 %", "2021", "soft reset"),
    ("G0 X1 (open", "2021", "not closed"),
    ("G0 X1\nG0 X2", "2021", "line break"),
    ("G0 X1 \u00e9", "2021", "printable ASCII"),
]


@pytest.mark.parametrize(("line", "firmware", "expected"), BAD_LINES)
def test_check_line_bad(line: str, firmware: str, expected: str) -> None:
    problems = gcode.check_line(line, firmware=firmware)
    if not expected:
        assert problems == []
        return
    assert any(expected in problem for problem in problems), problems


def test_check_line_accepts_bytes_and_line_endings() -> None:
    assert gcode.check_line(b"M21 G90 X10\n") == []
    assert gcode.check_line("M21 G90 X10\r\n") == []
    assert gcode.check_line(b"M21 G90 X500\n") == ["J1=500 is outside -100..160"]


def test_check_line_rejects_unknown_firmware() -> None:
    with pytest.raises(MirobotUsageError, match="firmware"):
        gcode.check_line("G0 X1", firmware="1999")


def test_check_program_tracks_modal_state() -> None:
    program = [
        "M20",  # Cartesian: X is mm now
        "G0 X500",
        "G4 P0",  # the arm stops: the M21 below restarts from where that move ends
        "M21 G91",  # joint increments: not checkable
        "X500",
        "G90",
        "X500",  # absolute joint target: out of range
        "M20",
        "$H",  # homing re-initialises the parser: M21 G90
        "X500",
    ]
    assert gcode.check_program(program) == [
        (7, "J1=500 is outside -100..160"),
        (10, "J1=500 is outside -100..160"),
    ]


def test_check_line_state_is_updated_in_place() -> None:
    state = gcode.ModalState()
    assert gcode.check_line("M20 G91", state=state) == []
    assert state == gcode.ModalState(cartesian=True, relative=True)


def test_normalize_and_parse_words() -> None:
    assert gcode.normalize_line("m20 g90 (move) g0\tx1 ; rest") == "M20G90G0X1"
    assert gcode.normalize_line(b"g0 x1?") == "G0X1"
    assert gcode.parse_words("g1x10 f200") == [("G", 1.0), ("X", 10.0), ("F", 200.0)]
    assert gcode.parse_words("G00 X-.5 Y+2.") == [("G", 0.0), ("X", -0.5), ("Y", 2.0)]
    with pytest.raises(MirobotUsageError, match="line"):
        gcode.parse_words("G0 X")
    with pytest.raises(MirobotUsageError, match=r"\$ command"):
        gcode.parse_words("$H")
