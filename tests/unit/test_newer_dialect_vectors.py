"""Every line of EVIDENCE-NEWER.md sections 1-2 (the 2024 family), as the client reads it.

For each evidence line the table says what it is (its kind, its code) and whether it is the
final reply of the line that caused it. The protocol tests then put each line between two
pending lines and check that the first gets the outcome the table says, the second its own
``ok``: no lost reply, no misattributed reply, no desync, whatever profile the client assumed
(the state machine has none).
"""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from mirobot_async._client.condition import RobotCondition, firmware_from_banner
from mirobot_async._core.events import PendingLine
from mirobot_async._core.protocol import (
    AlarmRaised,
    BannerReceived,
    LineAcknowledged,
    LineRejected,
    MirobotConnection,
    ProtocolViolation,
    ResetDetected,
)
from mirobot_async._core.replies import ReplyKind, classify_line, find_refusal
from mirobot_async.errors import RefusalReason


@dataclass(frozen=True)
class Vector:
    line: str
    kind: ReplyKind
    code: int | None
    final: bool  # the final reply of its line (no "ok" follows it)
    refusal: RefusalReason | None = None  # with the "ok" that follows: an "ok but dropped"


E, A, INF, T, F = (
    ReplyKind.ERROR,
    ReplyKind.ALARM,
    ReplyKind.INFO,
    ReplyKind.TEXT,
    ReplyKind.FEEDBACK,
)
STATUS = (
    "<Alarm,Angle(ABCDXYZ):0.000,0.000,0.000,0.000,0.000,0.000,0.000,Cartesian coordinate(XYZ "
    "RxRyRz):230.000,0.000,255.570,0.000,0.000,0.000,Pump PWM:0,Valve PWM:0,Motion_MODE:0>"
)
BANNER = "WLKATA Robot started successfully.Firmware version:MT4,20240820"

# Section 1 (the MT4 capture) and section 2 (the message table), in the evidence's order.
VECTORS = (
    # 1: $I, $3, ?
    Vector("[0.9j.20160303:]", F, None, False),
    Vector("Info,E102,Invalid statement", E, 102, True),
    # 2: GRBL's status errors 1..11: a refusal, the line's only reply
    Vector("Info,E100,Expected command letter", E, 100, True),
    Vector("Info,E101,Bad number format", E, 101, True),
    Vector("Info,E103,Value < 0", E, 103, True),
    Vector("Info,E104,Setting disabled", E, 104, True),
    Vector("Info,E105,Value < 3 usec", E, 105, True),
    Vector("Info,E106,EEPROM read fail. Using defaults", E, 106, True),
    Vector("Info,E107,Not idle", E, 107, True),
    Vector("Info,E108,Alarm lock", E, 108, True),
    Vector("Info,E109,Homing not enabled", E, 109, True),
    Vector("Info,E110,Line overflow", E, 110, True),
    # the g-code errors, with and without the 2021 manual's space
    Vector("Error,E111,Modal group violation", E, 111, True),
    Vector("Error,E112,Unsupported command", E, 112, True),
    Vector("Error,E113,Undefined feed rate", E, 113, True),
    Vector("Error, E113,Undefined feed rate", E, 113, True),
    Vector("Error,E114,Door command only applies to Cartesian mode", E, 114, True),
    Vector("Error,E115,Arc command only applies to Cartesian mode", E, 115, True),
    Vector("Error,E116,Arc radius error", E, 116, True),
    Vector("Error,E117,ijk command error", E, 117, True),
    Vector("Error,E000,Invalid gcode ID:", E, 0, True),
    Vector("Error,E000, Invalid gcode ID:24", E, 0, True),
    # "Line Discard": its ok follows (the table prints "...Line Discard\nok\n")
    Vector("Info,A100,Line Discard", INF, 100, False),
    # alarms, some followed by an axis letter
    Vector("Error,A101,Hard limit:", A, 101, False),
    Vector("Error,A101,Hard limit:X", A, 101, False),
    Vector("Error,A102,Soft limit:", A, 102, False, RefusalReason.SOFT_LIMIT),
    Vector("Error,A102,Soft limit:B", A, 102, False, RefusalReason.SOFT_LIMIT),
    Vector("Error,A103,Abort during cycle", A, 103, False),
    Vector("Error,A104,Probe fail", A, 104, False),
    Vector("Error,A105,Homing fail", A, 105, False),
    Vector("Error,A106,Locked status of each axis", A, 106, False, RefusalReason.LOCKED),
    Vector(
        "Error,A107,Axis 2 and 3 have conflicting angles.:",
        A,
        107,
        False,
        RefusalReason.ANGLE_OUT_OF_LIMIT,
    ),
    # information texts (no space after "Info,"), before the line's ok
    Vector("Info,in homing moving...", INF, None, False),
    Vector("Info,M20: Cartesian mode start.", INF, None, False),
    Vector("Info,M21: Angle mode start.", INF, None, False),
    Vector("Info,M50: Unlock each axis.", INF, None, False),
    Vector("Info,M40: Start calibration, clear the original reset parameters.", INF, None, False),
    # the IK texts: "ok but dropped" (INFERRED), text for the line, never its reply
    Vector(
        "The Cartesian position exceeds the boundary.", T, None, False, RefusalReason.UNREACHABLE
    ),
    Vector("Axis 2 and 3 angles are too small.", T, None, False, RefusalReason.ANGLE_OUT_OF_LIMIT),
    Vector("Axis 2 and 3 angles are too big.", T, None, False, RefusalReason.ANGLE_OUT_OF_LIMIT),
    # feedback
    Vector("[Restoring defaults]", F, None, False),
    Vector("[Pgm End]", F, None, False),
    Vector("[Disabled]", F, None, False),
    Vector("[Enabled]", F, None, False),
    Vector("[Caution: Unlocked]", F, None, False),
    Vector("['$H'|'$X' to unlock]", F, None, False),
    Vector("[Reset to continue]", F, None, False),
    # the 6-axis tail of the same image (a Mirobot build)
    Vector(
        "Error,E118,The given location is outside the workspace.",
        T,
        118,
        False,
        RefusalReason.UNREACHABLE,
    ),
    Vector(
        "Error,E119,The angle of an axis is out of range.",
        T,
        119,
        False,
        RefusalReason.ANGLE_OUT_OF_LIMIT,
    ),
    Vector(
        "Info,M42: Start axis 6 calibration, clear the original axis 6 reset parameters.",
        INF,
        None,
        False,
    ),
    Vector("Info,M43: Write the reset parameters of axis 6 to the EEPROM.", INF, None, False),
)
"""The evidence lines. The status line, the banner and the settings lines are tested below."""

STATES = ("Idle", "Alarm", "Run", "Home", "Hold", "Check", "Door")


@pytest.mark.parametrize("vector", VECTORS, ids=lambda v: v.line)
def test_each_evidence_line_is_classified(vector: Vector) -> None:
    reply = classify_line(vector.line + "\r\n")
    assert (reply.kind, reply.code) == (vector.kind, vector.code)
    assert reply.kind is not ReplyKind.UNKNOWN
    assert (reply.kind is ReplyKind.ERROR) is vector.final
    assert not reply.ok


def _around(
    line_bytes: bytes,
) -> tuple[MirobotConnection, list[object], tuple[PendingLine, PendingLine]]:
    conn = MirobotConnection()
    first, second = conn.send_line("G4 P0"), conn.send_line("M3 S0")
    conn.receive_data(line_bytes)
    return conn, list(conn.events()), (first, second)


@pytest.mark.parametrize("ending", [b"\r\n", b"\n"], ids=["crlf", "lf"])
@pytest.mark.parametrize("vector", VECTORS, ids=lambda v: v.line)
def test_each_evidence_line_gives_its_line_one_outcome_and_shifts_nothing(
    vector: Vector, ending: bytes
) -> None:
    """The line between two pending lines: the first gets the outcome the table says, the
    second (answered ``ok``) its own ``ok``, whatever follows."""
    ok_after = b"" if vector.final else b"ok" + ending
    conn, events, (first, second) = _around(vector.line.encode() + ending + ok_after + b"ok\n")
    replies = [e for e in events if isinstance(e, LineAcknowledged | LineRejected)]
    assert [r.line for r in replies] == [first, second]
    one, two = replies
    if vector.final:
        assert isinstance(one, LineRejected) and one.code == vector.code
    else:
        assert isinstance(one, LineAcknowledged)
        if vector.refusal is None:
            assert one.refusal is None
        else:
            assert one.refusal is not None and one.refusal.reason is vector.refusal
    assert isinstance(two, LineAcknowledged) and two.output == () and two.refusal is None
    assert conn.pending_count == 0 and conn.bytes_in_flight == 0
    assert not [e for e in events if isinstance(e, ProtocolViolation | ResetDetected)]
    alarms = [e for e in events if isinstance(e, AlarmRaised)]
    assert alarms == (
        [AlarmRaised(classify_line(vector.line).text, vector.code)] if vector.kind is A else []
    )


def test_the_soft_limit_alarm_names_its_axis() -> None:
    refusal = find_refusal(("Error,A102,Soft limit:B",))
    assert refusal is not None and (refusal.reason, refusal.axis) == (RefusalReason.SOFT_LIMIT, "B")


def test_info_a100_ends_in_a_bare_lf_then_ok() -> None:
    """``Info,A100,Line Discard\\nok\\n``: the text is the line's, the ok its reply."""
    _conn, events, (first, second) = _around(b"Info,A100,Line Discard\nok\nok\n")
    assert events[0] == LineAcknowledged(first, ("Info,A100,Line Discard",), None)
    assert events[1] == LineAcknowledged(second, (), None)


@pytest.mark.parametrize("state", STATES)
def test_the_status_line_and_its_states(state: str) -> None:
    conn, events, _ = _around(STATUS.replace("<Alarm", f"<{state}").encode() + b"\r\n")
    assert len(events) == 1 and events[0].report.state.value == state  # type: ignore[attr-defined]
    assert conn.pending_count == 2


def test_the_one_line_banner_is_a_reset() -> None:
    _conn, events, (first, second) = _around(BANNER.encode() + b"\r\n")
    assert events == [ResetDetected((), (first, second)), BannerReceived((BANNER,))]
    assert firmware_from_banner((BANNER,)) == ("2024", "MT4,20240820")


@pytest.mark.parametrize(
    "line",
    ["Error,X12,what", "Error, Something odd", "Info,E1x2,Bad", "Error,E", "o\xffk", "Info,A1b"],
)
def test_a_line_in_no_known_form_is_a_violation_and_shifts_nothing(line: str) -> None:
    conn, events, (first, second) = _around(line.encode("latin-1") + b"\r\nok\r\n")
    assert events[0] == ProtocolViolation(
        "a line in none of the known reply forms", line.encode("latin-1")
    )
    assert events[1] == LineAcknowledged(first, (), None)
    assert conn.pending_lines == (second,)


# ---- the family, from the banner, $$ and $I ------------------------------------------------


def test_the_family_from_the_banner_once_per_connection() -> None:
    condition = RobotCondition(None)
    condition.on_banner((BANNER,))
    assert (condition.firmware, condition.firmware_version) == ("2024", "MT4,20240820")
    assert condition.firmware_evidence == f"the banner {BANNER!r}"
    condition.learn_firmware_from_settings({29: 127.0})  # later evidence does not overrule
    assert condition.firmware == "2024"


@pytest.mark.parametrize(
    ("numbers", "family"),
    [
        ({10, 29, 44, 45, 51, 52, 140, 146, 160, 166}, "2024"),
        ({10, 29, 140, 146, 160, 166}, "2021"),
        ({10, 140, 146}, "classic"),
    ],
)
def test_the_family_from_the_shape_of_the_settings(numbers: set[int], family: str) -> None:
    condition = RobotCondition(None)
    condition.learn_firmware_from_settings(numbers)
    assert condition.firmware == family
    assert condition.firmware_evidence is not None and "$$" in condition.firmware_evidence


@pytest.mark.parametrize(
    ("line", "family"),
    [("[0.9j.20160303:]", "2024"), ("[0.9j.20160303:--ZDX&LEAH(201306)]", None)],
)
def test_the_family_from_build_info(line: str, family: str | None) -> None:
    condition = RobotCondition(None)
    condition.learn_build_info((line,))
    assert condition.firmware == family
