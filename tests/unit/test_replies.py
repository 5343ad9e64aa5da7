"""Unit tests of mirobot_async._core.replies: status parsing/formatting, line classification,
refusals."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mirobot_async._core.replies import (
    Refusal,
    Reply,
    ReplyKind,
    State,
    StatusReport,
    classify_line,
    find_refusal,
    format_status,
    parse_status,
)
from mirobot_async.errors import MirobotProtocolError, RefusalReason

VECTORS: dict[str, Any] = json.loads(
    (Path(__file__).parent.parent / "data" / "vectors.json").read_text(encoding="utf-8")
)
STATUS_VECTORS: list[dict[str, Any]] = VECTORS["status_lines"]
CORRUPTED: list[str] = VECTORS["corrupted_status_lines"]

CANONICAL = STATUS_VECTORS[2]["line"]  # classic firmware, all fields, non-zero values


# ---- parse_status: the device vectors ------------------------------------------------------------


@pytest.mark.parametrize("vector", STATUS_VECTORS, ids=lambda v: v["origin"])
def test_vector_status_lines_parse_to_their_fields(vector: dict[str, Any]) -> None:
    report = parse_status(vector["line"])
    assert report.state is State(vector["state"])
    assert report.joints == tuple(float(v) for v in vector["joints_j1_to_j6"])
    assert report.rail == vector["rail"]
    assert report.pose == tuple(float(v) for v in vector["pose"])
    assert report.pump_pwm == vector["pump_pwm"]
    assert report.valve_pwm == vector["valve_pwm"]
    assert report.motion_mode == vector["motion_mode"]


@pytest.mark.parametrize("vector", STATUS_VECTORS, ids=lambda v: v["origin"])
def test_vector_status_lines_parse_from_bytes_and_with_line_endings(vector: dict[str, Any]) -> None:
    expected = parse_status(vector["line"])
    assert parse_status(vector["line"].encode("ascii")) == expected
    assert parse_status(vector["line"] + "\r\n") == expected
    assert parse_status("  \t" + vector["line"] + " \n") == expected
    assert parse_status(("\r\n" + vector["line"] + "\r\n").encode()) == expected


@pytest.mark.parametrize(
    "vector", [v for v in STATUS_VECTORS if "Valve PWM" in v["line"]], ids=lambda v: v["origin"]
)
def test_firmware_lines_print_back_byte_for_byte(vector: dict[str, Any]) -> None:
    assert parse_status(vector["line"]).to_line() == vector["line"]


@pytest.mark.parametrize("line", CORRUPTED)
def test_vector_corrupted_lines_raise_protocol_error(line: str) -> None:
    with pytest.raises(MirobotProtocolError) as info:
        parse_status(line)
    assert info.value.data == line


def test_wire_order_is_j4_j5_j6_d_j1_j2_j3() -> None:
    line = (
        "<Run,Angle(ABCDXYZ):4.000,5.000,6.000,7.000,1.000,2.000,3.000,"
        "Cartesian coordinate(XYZ RxRyRz):10.000,20.000,30.000,40.000,50.000,60.000,"
        "Pump PWM:1000,Valve PWM:65,Motion_MODE:1>"
    )
    r = parse_status(line)
    assert r == StatusReport(
        State.RUN,
        (1.0, 2.0, 3.0, 4.0, 5.0, 6.0),
        7.0,
        (10.0, 20.0, 30.0, 40.0, 50.0, 60.0),
        1000,
        65,
        1,
    )
    assert r.to_line() == line == format_status(r)


# ---- parse_status: the variants of PROTOCOL.md section 5 -----------------------------------------


def test_variant_value_pwm() -> None:
    line = CANONICAL.replace("Valve PWM", "Value PWM")
    assert parse_status(line) == parse_status(CANONICAL)


def test_variant_without_motion_mode() -> None:
    line = CANONICAL.replace(",Motion_MODE:1", "")
    report = parse_status(line)
    assert report.motion_mode is None
    assert report.joints == parse_status(CANONICAL).joints
    assert report.to_line() == line


def test_variant_without_space_in_cartesian_header() -> None:
    line = CANONICAL.replace("(XYZ RxRyRz)", "(XYZRxRyRz)")
    assert parse_status(line) == parse_status(CANONICAL)


def test_variant_all_variants_together() -> None:
    line = (
        CANONICAL.replace("(XYZ RxRyRz)", "(XYZRxRyRz)")
        .replace("Valve PWM", "Value PWM")
        .replace(",Motion_MODE:1", "")
    )
    report = parse_status(line)
    assert report.motion_mode is None
    assert report.pose == parse_status(CANONICAL).pose


def test_variant_six_angles_assumed_order_j4_j5_j6_j1_j2_j3() -> None:
    line = (
        "<Idle,Angle(ABCDXYZ):4.000,5.000,6.000,1.000,2.000,3.000,"
        "Cartesian coordinate(XYZ RxRyRz):198.670,0.000,230.720,0.000,0.000,0.000,"
        "Pump PWM:0,Valve PWM:0,Motion_MODE:0>"
    )
    report = parse_status(line)
    assert report.joints == (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    assert report.rail is None
    assert report.to_line() == line
    assert parse_status(line.replace("ABCDXYZ", "ABCXYZ")) == report


@pytest.mark.parametrize(
    ("text", "value"), [("3", 3.0), ("3.5", 3.5), ("+3.25", 3.25), (".5", 0.5)]
)
def test_numbers_without_three_decimals_are_accepted(text: str, value: float) -> None:
    report = parse_status(CANONICAL.replace("2.679", text))
    assert report.joints[0] == value


def test_negative_zero_is_kept_so_the_line_round_trips() -> None:
    line = CANONICAL.replace("0.250,", "-0.000,", 1)
    report = parse_status(line)
    assert report.joints[3] == 0.0
    assert report.to_line() == line
    assert parse_status(report.to_line()) == report


def test_to_line_rounds_to_three_decimals() -> None:
    r = StatusReport(
        State.HOLD, (1.23456, -0.0001, 2, 3, 4, 5), None, (0.1, 0.2, 0.3, 0, 0, 0), 1, 2, None
    )
    assert r.to_line() == (
        "<Hold,Angle(ABCDXYZ):3.000,4.000,5.000,1.235,-0.000,2.000,"
        "Cartesian coordinate(XYZ RxRyRz):0.100,0.200,0.300,0.000,0.000,0.000,"
        "Pump PWM:1,Valve PWM:2>"
    )


@pytest.mark.parametrize(
    "line",
    [
        "",
        "   ",
        "ok",
        "<>",
        "<Idle>",
        "<Idle,",
        "garbage",
        CANONICAL[:-1],  # no closing ">"
        CANONICAL[1:],  # no opening "<"
        CANONICAL.replace("Idle", "Sleep"),  # unknown state
        CANONICAL.replace("Idle", "idle"),  # states are exact words
        CANONICAL.replace("Idle", ""),
        CANONICAL.replace("2.679", "nan"),
        CANONICAL.replace("2.679", "inf"),
        CANONICAL.replace("2.679", "-inf"),
        CANONICAL.replace("2.679", "1e3"),
        CANONICAL.replace("2.679", "9" * 400),  # would overflow float() to inf
        CANONICAL.replace("Pump PWM:0", "Pump PWM:" + "9" * 5000),  # int() digit limit
        CANONICAL.replace("2.679", "\u0663.000"),  # Arabic-Indic digit 3
        CANONICAL.replace("2.679", "2..679"),
        CANONICAL.replace("2.679", "2.6.79"),
        CANONICAL.replace("2.679", "--2.679"),
        CANONICAL.replace("2.679", "2.679-"),
        CANONICAL.replace("2.679", "+"),
        CANONICAL.replace("2.679", "."),
        CANONICAL.replace("Pump PWM:0", "Pump PWM:+-0"),
        CANONICAL.replace("2.679", "2_679"),
        CANONICAL.replace("2.679", ""),
        CANONICAL.replace("2.679,", ""),  # 5 angles after D: 6 values but D ambiguous -> 6 ok?
        CANONICAL.replace("0.250,", "0.250,1.000,"),  # 8 angles
        CANONICAL.replace("0.250,8.641,", ""),  # 5 angles
        CANONICAL.replace("212.000,", ""),  # 5 pose values
        CANONICAL.replace("212.000,", "212.000,1.000,"),  # 7 pose values
        CANONICAL.replace("Pump PWM:0", "Pump PWM:0.5"),
        CANONICAL.replace("Valve PWM:0", "Valve PWM:"),
        CANONICAL.replace("Motion_MODE:1", "Motion_MODE:"),
        CANONICAL.replace(",Pump PWM:0", ""),
        CANONICAL + CANONICAL,
        CANONICAL + "ok",
        CANONICAL.replace(",Cartesian", ",Cartesian,Cartesian"),
        CANONICAL.replace("Angle(ABCDXYZ)", "Angle(XYZABCD)"),
    ],
)
def test_malformed_status_lines_raise_protocol_error(line: str) -> None:
    if line == CANONICAL.replace("2.679,", ""):
        # Removing one angle leaves 6 angles: the valid 6-angle variant (D dropped, ASSUMED).
        assert parse_status(line).rail is None
        return
    with pytest.raises(MirobotProtocolError):
        parse_status(line)


@pytest.mark.parametrize("data", [b"\xff\xfe", CANONICAL.encode() + b"\x80", b"<\x00>"])
def test_non_ascii_bytes_raise_protocol_error(data: bytes) -> None:
    with pytest.raises(MirobotProtocolError):
        parse_status(data)


def test_wrong_type_raises_protocol_error() -> None:
    with pytest.raises(MirobotProtocolError):
        parse_status(12)  # type: ignore[arg-type]


# ---- parse_status: fuzzing -----------------------------------------------------------------------


def _parse_or_protocol_error(line: str | bytes) -> None:
    try:
        report = parse_status(line)
    except MirobotProtocolError:
        return
    # Whatever parses is a coherent report whose firmware-format line is a fixed point
    # (the parser accepts more decimals than the firmware prints, so compare printed forms).
    assert isinstance(report, StatusReport)
    printed = report.to_line()
    assert parse_status(printed).to_line() == printed


@settings(max_examples=300)
@given(st.text())
def test_fuzz_random_text_only_raises_protocol_error(text: str) -> None:
    _parse_or_protocol_error(text)


@settings(max_examples=200)
@given(st.binary())
def test_fuzz_random_bytes_only_raise_protocol_error(data: bytes) -> None:
    _parse_or_protocol_error(data)


_ALPHABET = "<>,.:-+0123456789()ABCDXYZ RxRyRzIdleRunPWMotion_MODEnaif\r\n\x00"


@st.composite
def _mutated_line(draw: st.DrawFn) -> str:
    line: str = draw(st.sampled_from([v["line"] for v in STATUS_VECTORS] + CORRUPTED))
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(line)))
        j = draw(st.integers(i, min(len(line), i + 40)))
        op = draw(st.sampled_from(["delete", "insert", "replace", "duplicate", "truncate"]))
        if op == "delete":
            line = line[:i] + line[j:]
        elif op == "insert":
            line = line[:i] + draw(st.text(_ALPHABET, max_size=12)) + line[i:]
        elif op == "replace":
            line = line[:i] + draw(st.text(_ALPHABET, max_size=j - i + 1)) + line[j:]
        elif op == "duplicate":
            line = line[:j] + line[i:j] + line[j:]
        else:
            line = line[:i]
    return line


@settings(max_examples=500)
@given(_mutated_line())
def test_fuzz_mutated_status_lines_only_raise_protocol_error(line: str) -> None:
    _parse_or_protocol_error(line)
    _parse_or_protocol_error(line.encode("utf-8"))


# ---- round trips ---------------------------------------------------------------------------------

_three_decimals = st.integers(-999_999, 999_999).map(lambda i: i / 1000)
_six = st.tuples(*[_three_decimals] * 6)
_reports = st.builds(
    StatusReport,
    st.sampled_from(State),
    _six,
    st.none() | _three_decimals,
    _six,
    st.integers(0, 1000),
    st.integers(0, 1000),
    st.none() | st.integers(0, 1),
)


@settings(max_examples=300)
@given(_reports)
def test_round_trip_report_line_report(report: StatusReport) -> None:
    line = report.to_line()
    assert parse_status(line) == report
    assert parse_status(line).to_line() == line
    assert parse_status(line.encode("ascii") + b"\r\n") == report


def _firmware_line(
    state: str,
    joints: tuple[float, ...],
    rail: float | None,
    pose: tuple[float, ...],
    pump: int,
    valve: int,
    mode: int | None,
) -> str:
    """An independent rendering of the firmware's printf: "%.3f" in the wire order."""
    wire = [joints[3], joints[4], joints[5], *([] if rail is None else [rail]), *joints[:3]]
    fields = [
        "<" + state,
        "Angle(ABCDXYZ):" + ",".join("%.3f" % v for v in wire),  # noqa: UP031 (C printf on purpose)
        "Cartesian coordinate(XYZ RxRyRz):" + ",".join("%.3f" % v for v in pose),  # noqa: UP031
        f"Pump PWM:{pump}",
        f"Valve PWM:{valve}",
    ]
    if mode is not None:
        fields.append(f"Motion_MODE:{mode}")
    return ",".join(fields) + ">"


_any_value = st.floats(-1e7, 1e7, allow_nan=False, allow_infinity=False)
_any_six = st.tuples(*[_any_value] * 6)


@settings(max_examples=300)
@given(
    st.sampled_from([s.value for s in State]),
    _any_six,
    st.none() | _any_value,
    _any_six,
    st.integers(0, 1000),
    st.integers(0, 1000),
    st.none() | st.integers(0, 1),
)
def test_firmware_format_of_any_report_parses_back_equal(
    state: str,
    joints: tuple[float, ...],
    rail: float | None,
    pose: tuple[float, ...],
    pump: int,
    valve: int,
    mode: int | None,
) -> None:
    line = _firmware_line(state, joints, rail, pose, pump, valve, mode)
    report = parse_status(line)

    def q(v: float) -> float:
        return float("%.3f" % v)  # noqa: UP031

    assert report.state is State(state)
    assert report.joints == tuple(q(v) for v in joints)
    assert report.rail == (None if rail is None else q(rail))
    assert report.pose == tuple(q(v) for v in pose)
    assert (report.pump_pwm, report.valve_pwm, report.motion_mode) == (pump, valve, mode)
    # to_line is the firmware's own format, byte for byte, for every report (3 decimals or not).
    built = StatusReport(
        State(state),
        joints,  # type: ignore[arg-type]
        rail,
        pose,  # type: ignore[arg-type]
        pump,
        valve,
        mode,
    )
    assert built.to_line() == line
    assert report.to_line() == line


# ---- classify_line -------------------------------------------------------------------------------


def R(kind: ReplyKind, text: str, code: int | None = None, ok: bool = False) -> tuple[Any, ...]:
    return (kind, text, code, ok)


@pytest.mark.parametrize(
    ("line", "expected"),
    [
        # success, both profiles
        ("ok", R(ReplyKind.OK, "", ok=True)),
        ("ok\r\n", R(ReplyKind.OK, "", ok=True)),
        (" ok ", R(ReplyKind.OK, "", ok=True)),
        # glued ok (homing)
        ("in homeing moving...ok", R(ReplyKind.TEXT, "in homeing moving...", ok=True)),
        ("Info, in homing moving...ok", R(ReplyKind.INFO, "in homing moving...", ok=True)),
        ("[Caution: Unlocked]ok", R(ReplyKind.FEEDBACK, "Caution: Unlocked", ok=True)),
        # words that merely end in "ok" are not a glued ok
        ("Take a look", R(ReplyKind.TEXT, "Take a look")),
        ("Info, notebook", R(ReplyKind.INFO, "notebook")),
        # errors: classic
        ("error: Undefined feed rate", R(ReplyKind.ERROR, "Undefined feed rate")),
        ("error: Alarm lock", R(ReplyKind.ERROR, "Alarm lock")),
        ("error: Invalid gcode ID:24", R(ReplyKind.ERROR, "Invalid gcode ID:24")),
        ("error:Line overflow", R(ReplyKind.ERROR, "Line overflow")),
        ("error:20", R(ReplyKind.ERROR, "20", 20)),
        # errors: 2021 (lenient about spaces)
        ("Error, E113,Undefined feed rate", R(ReplyKind.ERROR, "Undefined feed rate", 113)),
        ("Error, E116,Arc radius error", R(ReplyKind.ERROR, "Arc radius error", 116)),
        ("Error,E120, Unsupported command", R(ReplyKind.ERROR, "Unsupported command", 120)),
        ("Error , E113 , Undefined feed rate", R(ReplyKind.ERROR, "Undefined feed rate", 113)),
        ("Error, E113", R(ReplyKind.ERROR, "", 113)),
        ("Error, Something odd", R(ReplyKind.UNKNOWN, "Error, Something odd")),  # never final
        # alarms
        ("ALARM: Hard limit", R(ReplyKind.ALARM, "Hard limit")),
        ("ALARM: Abort during cycle", R(ReplyKind.ALARM, "Abort during cycle")),
        ("ALARM:Homing fail", R(ReplyKind.ALARM, "Homing fail")),
        # feedback
        ("[Reset to continue]", R(ReplyKind.FEEDBACK, "Reset to continue")),
        ("['$H'|'$X' to unlock]", R(ReplyKind.FEEDBACK, "'$H'|'$X' to unlock")),
        ("[Caution: Unlocked]", R(ReplyKind.FEEDBACK, "Caution: Unlocked")),
        ("[Enabled]", R(ReplyKind.FEEDBACK, "Enabled")),
        ("[Pgm End]", R(ReplyKind.FEEDBACK, "Pgm End")),
        # information: classic bare text, 2021 "Info, "
        ("M50: Unlock each axis.", R(ReplyKind.TEXT, "M50: Unlock each axis.")),
        ("Info, M50: Unlock each axis.", R(ReplyKind.INFO, "M50: Unlock each axis.")),
        ("Info, M20: Cartesian mode start.", R(ReplyKind.INFO, "M20: Cartesian mode start.")),
        ("Info,M21: Angle mode start.", R(ReplyKind.INFO, "M21: Angle mode start.")),
        ("Free memory: 2036", R(ReplyKind.TEXT, "Free memory: 2036")),
        ("Locked status of each axis!", R(ReplyKind.TEXT, "Locked status of each axis!")),
        ("Soft limit triggered:X", R(ReplyKind.TEXT, "Soft limit triggered:X")),
        ("$10=99 (status report mask)", R(ReplyKind.TEXT, "$10=99 (status report mask)")),
        # status (also truncated ones: they are parsed, and maybe corrupted, never text)
        (CANONICAL, R(ReplyKind.STATUS, CANONICAL)),
        (CORRUPTED[1], R(ReplyKind.STATUS, CORRUPTED[1])),
        # banner
        ("Grbl 0.9j ['$' for help]", R(ReplyKind.BANNER_START, "Grbl 0.9j ['$' for help]")),
        (
            "Qinnew Robot 20191228_2 based on Grbl 0.9j ['$' for help]",
            R(
                ReplyKind.BANNER_START,
                "Qinnew Robot 20191228_2 based on Grbl 0.9j ['$' for help]",
            ),
        ),
        ("WLKATA Mirobot", R(ReplyKind.TEXT, "WLKATA Mirobot")),
        ("D1: 78", R(ReplyKind.TEXT, "D1: 78")),
        ("Using reset pos!", R(ReplyKind.BANNER_END, "Using reset pos!")),
        # empty
        ("", R(ReplyKind.TEXT, "")),
        ("\r\n", R(ReplyKind.TEXT, "")),
    ],
)
def test_classify_line(line: str, expected: tuple[Any, ...]) -> None:
    reply = classify_line(line)
    assert isinstance(reply, Reply)
    assert (reply.kind, reply.text, reply.code, reply.ok) == expected
    assert reply.raw == line.rstrip("\r\n")
    assert classify_line(line.encode("ascii")) == reply


@pytest.mark.parametrize("transcript", VECTORS["transcripts"], ids=lambda t: t["about"])
def test_classify_every_transcript_line(transcript: dict[str, Any]) -> None:
    # The firmware ends a line at "\r" and at "\n": "cmd\r\n" is two lines, two final replies.
    lines_sent = len(re.split(r"\r|\n", transcript["send"])) - 1
    replies = [classify_line(text) for text in transcript["receive"]]
    finals = [r for r in replies if r.ok or r.kind is ReplyKind.ERROR]
    assert len(finals) == lines_sent
    assert replies[-1] is finals[-1]
    for reply in replies:
        if reply not in finals:
            assert reply.kind in (ReplyKind.TEXT, ReplyKind.INFO, ReplyKind.FEEDBACK)


def test_classify_classic_banner() -> None:
    kinds = [classify_line(line).kind for line in VECTORS["banner_classic"] if line]
    assert kinds[0] is ReplyKind.BANNER_START
    assert kinds[1] is ReplyKind.BANNER_START  # "... based on Grbl ..."
    assert kinds[-1] is ReplyKind.BANNER_END
    assert set(kinds[2:-1]) == {ReplyKind.TEXT}


@settings(max_examples=300)
@given(st.text() | st.binary())
def test_fuzz_classify_line_never_raises(line: str | bytes) -> None:
    reply = classify_line(line)
    assert isinstance(reply.kind, ReplyKind)


# ---- find_refusal --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("output", "expected"),
    [
        ((), None),
        (("Free memory: 2036", "in homeing moving...ok"), None),
        (("ALARM: Soft limit",), None),
        (
            ("Locked status of each axis!",),
            Refusal(RefusalReason.LOCKED, "Locked status of each axis!", None),
        ),
        (
            ("Info, Locked status of each axis!",),
            Refusal(RefusalReason.LOCKED, "Info, Locked status of each axis!", None),
        ),
        (
            ("Soft limit triggered:X",),
            Refusal(RefusalReason.SOFT_LIMIT, "Soft limit triggered:X", "X"),
        ),
        (
            ("M21: ...", "Info, Soft limit triggered: D"),
            Refusal(RefusalReason.SOFT_LIMIT, "Info, Soft limit triggered: D", "D"),
        ),
        (
            ("Soft limit triggered",),
            Refusal(RefusalReason.SOFT_LIMIT, "Soft limit triggered", None),
        ),
        (
            ("GOAL OUT OF WORKSPACE, THERE IS NO VAILD VALUS FOR  THETA3!",),
            Refusal(
                RefusalReason.UNREACHABLE,
                "GOAL OUT OF WORKSPACE, THERE IS NO VAILD VALUS FOR  THETA3!",
                None,
            ),
        ),
        (
            ("There is one angle out of limit!!!",),
            Refusal(RefusalReason.ANGLE_OUT_OF_LIMIT, "There is one angle out of limit!!!", None),
        ),
        (
            ("Info, There is one angle out of limit!!!", "Locked status of each axis!"),
            Refusal(
                RefusalReason.ANGLE_OUT_OF_LIMIT,
                "Info, There is one angle out of limit!!!",
                None,
            ),
        ),
    ],
)
def test_find_refusal(output: tuple[str, ...], expected: Refusal | None) -> None:
    assert find_refusal(output) == expected
    assert find_refusal(list(output)) == expected


def test_hard_limit_alarm_after_the_switch_bits_is_an_alarm() -> None:
    """The firmware prints the tripped switches as eight bits before ``ALARM:`` (oracle)."""
    reply = classify_line("00010000ALARM: Hard limit")
    assert reply.kind is ReplyKind.ALARM
    assert reply.text == "Hard limit"
    assert classify_line("0001000ALARM: Hard limit").kind is ReplyKind.TEXT
