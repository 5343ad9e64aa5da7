"""Unit tests of mirobot_async._core.protocol: the sans-IO connection state machine (no event
loop)."""

from __future__ import annotations

import itertools
import json
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, note, settings
from hypothesis import strategies as st
from hypothesis.stateful import (
    RuleBasedStateMachine,
    initialize,
    invariant,
    precondition,
    rule,
)
from mirobot_emulator.settings import PROFILES, default_settings, format_dump

from mirobot_async._core.protocol import (
    AlarmRaised,
    BannerReceived,
    ConnectionClosed,
    DoubtResolved,
    Event,
    LineAcknowledged,
    LineOutcomeUnknown,
    LineRejected,
    MirobotConnection,
    PendingLine,
    ProtocolViolation,
    ResetDetected,
    StatusCorrupted,
    StatusReceived,
    UnsolicitedText,
)
from mirobot_async._core.replies import ReplyKind, find_refusal, parse_status
from mirobot_async.errors import MirobotProtocolError, MirobotUsageError, RefusalReason

VECTORS: dict[str, Any] = json.loads(
    (Path(__file__).parent.parent / "data" / "vectors.json").read_text(encoding="utf-8")
)
STATUS_LINES: list[str] = [v["line"] for v in VECTORS["status_lines"]]
CORRUPTED: list[str] = VECTORS["corrupted_status_lines"]
BANNER_CLASSIC: list[str] = VECTORS["banner_classic"]
BANNER_2021: list[str] = [
    "",
    "Grbl 0.9j ['$' for help]",
    "",
    "Qinnew Robot 20210516 based on Grbl 0.9j ['$' for help]",
    "",
    "D1: 127",
    "Using reset pos!",
]


def wire(lines: Iterable[str], end: str = "\r\n") -> bytes:
    """What the firmware prints: every line followed by CR LF."""
    return "".join(line + end for line in lines).encode("ascii")


def drain(conn: MirobotConnection) -> list[Event]:
    events = []
    while (event := conn.next_event()) is not None:
        events.append(event)
    return events


def feed(conn: MirobotConnection, chunks: Iterable[bytes]) -> list[Event]:
    for chunk in chunks:
        conn.receive_data(chunk)
    return drain(conn)


def split_at(data: bytes, points: Iterable[int]) -> list[bytes]:
    cuts = sorted({p for p in points if 0 < p < len(data)})
    edges = [0, *cuts, len(data)]
    return [data[a:b] for a, b in itertools.pairwise(edges) if b > a]


# ---- basics --------------------------------------------------------------------------------------


def test_send_line_returns_the_wire_bytes_and_counts_them() -> None:
    conn = MirobotConnection()
    a = conn.send_line("M21 G90 X10 F2000")
    b = conn.send_line(b"$H\n")  # one trailing "\n" is stripped and re-added
    assert a == PendingLine(0, b"M21 G90 X10 F2000", b"M21 G90 X10 F2000\n")
    assert b == PendingLine(1, b"$H", b"$H\n")
    assert conn.pending_lines == (a, b)
    assert conn.pending_count == 2
    assert conn.bytes_in_flight == len(a.wire) + len(b.wire) == 21
    assert conn.next_event() is None


def test_ok_acknowledges_oldest_line_in_order() -> None:
    conn = MirobotConnection()
    a, b = conn.send_line("G4 P1"), conn.send_line("M50")
    assert feed(conn, [b"ok\r\nM50: Unlock each axis.\r\nok\r\n"]) == [
        LineAcknowledged(a, (), None),
        LineAcknowledged(b, ("M50: Unlock each axis.",), None),
    ]
    assert conn.pending_count == 0
    assert conn.bytes_in_flight == 0


def test_errors_reject_the_oldest_line_classic_and_2021() -> None:
    conn = MirobotConnection()
    a, b, c = (conn.send_line(x) for x in ("M21 G90 G1 X10", "M20 G90 G1 X200", "G4 P0"))
    events = feed(
        conn,
        [wire(["error: Undefined feed rate", "", "Error, E113,Undefined feed rate", "ok"])],
    )
    assert events == [
        LineRejected(a, "Undefined feed rate", None, ()),
        LineRejected(b, "Undefined feed rate", 113, ()),
        LineAcknowledged(c, (), None),
    ]


def test_events_generator_drains() -> None:
    conn = MirobotConnection()
    a = conn.send_line("M50")
    conn.receive_data(b"ok\n")
    assert list(conn.events()) == [LineAcknowledged(a, (), None)]
    assert list(conn.events()) == []
    assert conn.next_event() is None


@pytest.mark.parametrize("transcript", VECTORS["transcripts"], ids=lambda t: t["about"])
def test_vector_transcripts(transcript: dict[str, Any]) -> None:
    conn = MirobotConnection()
    # "cmd\r\n" is two lines for the firmware (cmd and an empty line): send them as such.
    sent = [conn.send_line(x) for x in re.split(r"\r|\n", transcript["send"])[:-1]]
    events = feed(conn, [wire(transcript["receive"])])
    assert len(events) == len(sent)
    for line, event in zip(sent, events, strict=True):
        assert event.line == line  # type: ignore[union-attr]
    about = transcript["about"]
    last = events[-1]
    if about == "motion while locked":
        assert isinstance(last, LineAcknowledged)
        assert last.refusal is not None and last.refusal.reason is RefusalReason.LOCKED
    elif "soft limit" in about:
        assert isinstance(last, LineAcknowledged)
        assert last.refusal is not None
        assert (last.refusal.reason, last.refusal.axis) == (RefusalReason.SOFT_LIMIT, "X")
    elif about.startswith("homing"):
        assert isinstance(last, LineAcknowledged)
        assert last.output == tuple(x for x in transcript["receive"] if x)
        assert last.refusal is None
    elif "M50" in about:
        assert last == LineAcknowledged(sent[0], (transcript["receive"][0],), None)
    elif "without F" in about or "too long" in about:
        assert isinstance(last, LineRejected)
        assert last.code == (113 if "2021" in about else None)
    else:
        assert all(isinstance(e, LineAcknowledged) and e.output == () for e in events)


def test_glued_ok_adds_its_text_and_acknowledges() -> None:
    conn = MirobotConnection()
    home, nxt = conn.send_line("$H"), conn.send_line("M20")
    events = feed(
        conn,
        [b"\r\nFree memory: 2036\r\nin homeing moving...ok\r\nInfo, in homing moving...ok\r\n"],
    )
    assert events == [
        LineAcknowledged(home, ("Free memory: 2036", "in homeing moving...ok"), None),
        LineAcknowledged(nxt, ("Info, in homing moving...ok",), None),
    ]


def test_text_with_nothing_pending_is_unsolicited() -> None:
    conn = MirobotConnection()
    events = feed(conn, [wire(["[Reset to continue]", "Info, hello", "hello", ""])])
    assert events == [
        UnsolicitedText(ReplyKind.FEEDBACK, "Reset to continue"),
        UnsolicitedText(ReplyKind.INFO, "hello"),
        UnsolicitedText(ReplyKind.TEXT, "hello"),
    ]


def test_final_reply_with_nothing_pending_is_a_violation_not_an_exception() -> None:
    conn = MirobotConnection()
    events = feed(conn, [wire(["ok", "error: Alarm lock", "in homeing moving...ok"])])
    assert [type(e) for e in events] == [
        ProtocolViolation,
        ProtocolViolation,
        UnsolicitedText,
        ProtocolViolation,
    ]
    assert events[0] == ProtocolViolation("'ok' with no line pending", b"ok")
    assert isinstance(events[1], ProtocolViolation) and events[1].data == b"error: Alarm lock"
    assert events[2] == UnsolicitedText(ReplyKind.TEXT, "in homeing moving...")
    # The machine carries on.
    a = conn.send_line("M50")
    assert feed(conn, [b"ok\r\n"]) == [LineAcknowledged(a, (), None)]


def test_status_lines_are_events_and_count_requests() -> None:
    conn = MirobotConnection()
    assert conn.request_status() == b"?"
    assert conn.request_status() == b"?"
    assert conn.status_requests_outstanding == 2
    a = conn.send_line("M21 G90 X10 F2000")
    events = feed(conn, [wire([STATUS_LINES[0], CORRUPTED[0], "ok", STATUS_LINES[2]])])
    assert events[0] == StatusReceived(parse_status(STATUS_LINES[0]), STATUS_LINES[0])
    assert isinstance(events[1], StatusCorrupted) and events[1].raw == CORRUPTED[0]
    assert events[1].reason
    assert events[2] == LineAcknowledged(a, (), None)  # the status lines did not touch it
    assert isinstance(events[3], StatusReceived)
    assert conn.status_requests_outstanding == 0  # never below 0


def test_truncated_status_line_is_corrupted_not_text() -> None:
    conn = MirobotConnection()
    a = conn.send_line("M50")
    events = feed(conn, [wire([CORRUPTED[1], " " + CORRUPTED[2], "ok"])])
    assert [type(e) for e in events] == [StatusCorrupted, StatusCorrupted, LineAcknowledged]
    assert events[2] == LineAcknowledged(a, (), None)


def test_alarm_is_an_event_not_output() -> None:
    conn = MirobotConnection()
    a = conn.send_line("M21 G90 X10 F2000")
    events = feed(conn, [wire(["ALARM: Hard limit", "[Reset to continue]", "ok"])])
    assert events == [
        AlarmRaised("Hard limit"),
        UnsolicitedText(ReplyKind.FEEDBACK, "Reset to continue"),  # news at once
        LineAcknowledged(a, ("[Reset to continue]",), None),
    ]


def test_refusals_are_attached_to_the_acknowledgement() -> None:
    conn = MirobotConnection()
    lines = [conn.send_line(f"M20 G90 G0 X{i}") for i in range(3)]
    texts = [
        "GOAL OUT OF WORKSPACE, THERE IS NO VAILD VALUS FOR  THETA3!",
        "Info, There is one angle out of limit!!!",
        "Soft limit triggered:Y",
    ]
    events = feed(conn, [wire([x for t in texts for x in ("", t, "ok")])])
    reasons = [e.refusal.reason for e in events if isinstance(e, LineAcknowledged) and e.refusal]
    assert reasons == [
        RefusalReason.UNREACHABLE,
        RefusalReason.ANGLE_OUT_OF_LIMIT,
        RefusalReason.SOFT_LIMIT,
    ]
    assert [e.line for e in events] == lines  # type: ignore[union-attr]


# ---- send_line validation and character counting -------------------------------------------------


@pytest.mark.parametrize(
    "line",
    [
        "G4 P1\r",
        "G4 P1\r\n",
        "G4\nP1",
        "G4 P1\n\n",
        "M21 X\u00e9",
        b"M21 X\xff",
        "M21?",
        "M21!",
        "M21~",
        "%",
        "X" * 128,  # 129 bytes with "\n": longer than the 128-byte receive buffer
    ],
)
def test_send_line_refuses_bad_lines(line: str | bytes) -> None:
    conn = MirobotConnection()
    with pytest.raises(MirobotUsageError):
        conn.send_line(line)
    assert conn.pending_count == 0
    assert conn.bytes_in_flight == 0


def test_send_line_refuses_wrong_type() -> None:
    with pytest.raises(MirobotUsageError):
        MirobotConnection().send_line(3)  # type: ignore[arg-type]


def test_character_counting() -> None:
    conn = MirobotConnection(rx_buffer_size=128)
    assert conn.fits(128) and not conn.fits(129)
    big = conn.send_line("X" * 127)  # exactly 128 bytes on the wire: allowed
    assert conn.bytes_in_flight == 128
    assert not conn.fits(1) and conn.fits(0)
    # Not refused for not fitting now: pacing is the caller's decision.
    small = conn.send_line("G4 P0")
    assert conn.bytes_in_flight == 134
    feed(conn, [b"ok\r\n"])
    assert conn.pending_lines == (small,) and conn.bytes_in_flight == 6
    assert conn.fits(122) and not conn.fits(123)
    feed(conn, [b"error: Bad number format\r\n"])
    assert conn.bytes_in_flight == 0 and conn.pending_count == 0
    assert big.wire == b"X" * 127 + b"\n"


def test_empty_line_is_a_valid_line() -> None:
    conn = MirobotConnection()
    empty = conn.send_line("")
    assert empty.wire == b"\n"
    assert feed(conn, [b"ok\r\n"]) == [LineAcknowledged(empty, (), None)]


def test_realtime_bytes_do_not_touch_pending_lines() -> None:
    conn = MirobotConnection()
    conn.send_line("M50")
    assert (conn.request_reset(), conn.feed_hold(), conn.cycle_start()) == (b"%", b"!", b"~")
    assert conn.pending_count == 1 and conn.bytes_in_flight == 4


def test_constructor_validates() -> None:
    with pytest.raises(MirobotUsageError):
        MirobotConnection(rx_buffer_size=1)
    with pytest.raises(MirobotUsageError):
        MirobotConnection(max_reply_length=0)
    with pytest.raises(MirobotUsageError):
        MirobotConnection(max_output_lines=0)


# ---- expire_oldest -------------------------------------------------------------------------------


def test_expire_oldest_realigns() -> None:
    conn = MirobotConnection()
    a, b, c = (conn.send_line(x) for x in ("G4 P1", "M50", "M20"))
    conn.receive_data(b"Free memory: 2036\r\n")  # text for a, whose ok was lost
    assert conn.expire_oldest() == a
    assert conn.bytes_in_flight == len(b.wire) + len(c.wire)
    events = feed(conn, [wire(["M50: Unlock each axis.", "ok", "error: Not idle"])])
    assert events == [
        LineAcknowledged(b, ("M50: Unlock each axis.",), None),  # a's text was dropped
        LineRejected(c, "Not idle", None, ()),
    ]
    with pytest.raises(MirobotUsageError):
        conn.expire_oldest()


# ---- banner / reset ------------------------------------------------------------------------------


def test_classic_banner_mid_stream_puts_the_pending_lines_in_doubt() -> None:
    conn = MirobotConnection()
    a = conn.send_line("M21 G90 X10 F2000")
    conn.request_status()
    b, c = conn.send_line("M50"), conn.send_line("M20")
    events = feed(conn, [wire(["Locked status of each axis!", "ok"]), wire(BANNER_CLASSIC)])
    assert events == [
        LineAcknowledged(
            a,
            ("Locked status of each axis!",),
            find_refusal(("Locked status of each axis!",)),
        ),
        ResetDetected((), (b, c)),  # a reset nobody asked for: b and c may run after it
        BannerReceived(tuple(x.strip() for x in BANNER_CLASSIC if x)),
    ]
    assert conn.pending_count == 0
    assert conn.in_doubt_count == 2
    assert conn.bytes_in_flight == len(b.wire) + len(c.wire)  # maybe in the robot's buffer
    assert conn.status_requests_outstanding == 0
    assert not conn.in_banner
    conn.resolve_doubt()  # the host knows no reply can come any more: neither ran
    assert list(conn.events()) == [DoubtResolved((b, c))]
    assert conn.in_doubt_count == 0 and conn.bytes_in_flight == 0
    # After the banner, lines work normally.
    d = conn.send_line("M50")
    assert feed(conn, [b"ok\r\n"]) == [LineAcknowledged(d, (), None)]


def test_a_requested_reset_fails_the_lines_written_before_it() -> None:
    conn = MirobotConnection()
    a = conn.send_line("M50")
    assert conn.request_reset() == b"%"
    b = conn.send_line("M20")  # written after the "%": in doubt
    events = feed(conn, [wire(BANNER_CLASSIC)])
    assert events[0] == ResetDetected((a,), (b,))
    # its head may have been lost right after the "%" (oracle: ~0.35 ms deaf): the "ok" may be
    # its tail's, so whether it ran is unknown
    assert feed(conn, [b"ok\r\n"]) == [
        DoubtResolved(()),
        LineOutcomeUnknown(b, LineAcknowledged(b, (), None)),
    ]
    assert conn.in_doubt_count == 0 and conn.bytes_in_flight == 0


def test_replies_after_a_spontaneous_reset_answer_the_last_lines_in_doubt() -> None:
    """The robot ran the lines it received after resetting: the last ones written; the first of
    those may have been cut by the reset (its reply may be its tail's): its outcome is unknown."""
    conn = MirobotConnection()
    a, b, c = conn.send_line("M50"), conn.send_line("M20"), conn.send_line("M3 S5")
    events = feed(conn, [wire([*BANNER_CLASSIC, "ok", "Pump on", "ok"])])
    assert events[0] == ResetDetected((), (a, b, c))
    assert events[2:] == []  # two replies for three lines: not settled yet
    assert conn.in_doubt_count == 3
    conn.resolve_doubt()
    assert list(conn.events()) == [
        DoubtResolved((a,)),
        LineOutcomeUnknown(b, LineAcknowledged(b, (), None)),
        LineAcknowledged(c, ("Pump on",), None),
    ]
    d = conn.send_line("M50")
    assert feed(conn, [b"ok\r\n"]) == [LineAcknowledged(d, (), None)]
    assert feed(conn, [b"ok\r\n"])[0] == ProtocolViolation("'ok' with no line pending", b"ok")


def test_second_banner_start_inside_a_banner_is_the_same_banner() -> None:
    conn = MirobotConnection()
    conn.receive_data(wire(BANNER_CLASSIC[:3]))
    assert conn.in_banner
    # A line sent while the banner is printed is owed a reply after it: the "based on Grbl"
    # line must not fail it.
    a = conn.send_line("M50")
    events = feed(conn, [wire(BANNER_CLASSIC[3:]), b"ok\r\n"])
    assert events == [
        ResetDetected(()),
        BannerReceived(tuple(x.strip() for x in BANNER_CLASSIC if x)),
        LineAcknowledged(a, (), None),
    ]


def test_2021_banner_then_unlock_feedback() -> None:
    conn = MirobotConnection()
    a = conn.send_line("$X")
    events = feed(conn, [wire([*BANNER_2021, "['$H'|'$X' to unlock]"])])
    assert events == [
        ResetDetected((), (a,)),
        BannerReceived(tuple(x.strip() for x in BANNER_2021 if x)),
        UnsolicitedText(ReplyKind.FEEDBACK, "'$H'|'$X' to unlock"),
    ]


def test_status_ok_and_alarm_inside_a_banner_keep_their_meaning() -> None:
    conn = MirobotConnection()
    conn.receive_data(wire(["Grbl 0.9j ['$' for help]"]))
    a = conn.send_line("M50")
    events = feed(
        conn,
        [wire(["D1: 78", STATUS_LINES[0], "ALARM: Homing fail", "ok", "Using reset pos!"])],
    )
    assert events == [
        ResetDetected(()),
        StatusReceived(parse_status(STATUS_LINES[0]), STATUS_LINES[0]),
        AlarmRaised("Homing fail"),
        LineAcknowledged(a, (), None),
        BannerReceived(("Grbl 0.9j ['$' for help]", "D1: 78", "Using reset pos!")),
    ]


def test_banner_without_end_is_bounded() -> None:
    conn = MirobotConnection()
    n = MirobotConnection.MAX_BANNER_LINES
    lines = ["Grbl 0.9j ['$' for help]"] + [f"line {i}" for i in range(n + 5)]
    events = feed(conn, [wire(lines)])
    assert events[0] == ResetDetected(())
    assert events[1] == BannerReceived(tuple(lines[:n]))
    assert events[2:] == [UnsolicitedText(ReplyKind.TEXT, x) for x in lines[n:]]
    assert not conn.in_banner


def test_lone_banner_end_is_a_reset() -> None:
    conn = MirobotConnection()
    a = conn.send_line("M50")
    assert feed(conn, [b"Using reset pos!\r\n"]) == [
        ResetDetected((), (a,)),
        BannerReceived(("Using reset pos!",)),
    ]


# ---- framing, bounded buffer, EOF ----------------------------------------------------------------


@pytest.mark.parametrize("end", ["\r\n", "\n", "\r", "\n\r", "\r\r\n\n"])
def test_line_ends(end: str) -> None:
    conn = MirobotConnection()
    a, b = conn.send_line("M50"), conn.send_line("M20")
    data = ("M50: Unlock each axis." + end + "ok" + end + "ok" + end).encode()
    assert feed(conn, [data]) == [
        LineAcknowledged(a, ("M50: Unlock each axis.",), None),
        LineAcknowledged(b, (), None),
    ]


def test_overlong_line_without_newline_is_reported_once_and_memory_stays_bounded() -> None:
    conn = MirobotConnection(max_reply_length=512)
    a = conn.send_line("M50")
    garbage = bytes(range(33, 127)) * 20  # no line end anywhere
    events: list[Event] = []
    for _ in range(2000):  # ~3.7 MB
        conn.receive_data(garbage)
        assert conn.buffered_bytes <= 512
        events += drain(conn)
    assert len(events) == 1
    assert isinstance(events[0], ProtocolViolation)
    assert events[0].data == (garbage * 6)[:512]
    assert conn.buffered_bytes == 0
    # The rest of the overlong line is skipped up to the line end; then all is normal again.
    assert feed(conn, [b"more garbage\r\nok\r\n"]) == [LineAcknowledged(a, (), None)]


def test_text_lines_for_one_pending_line_are_capped_and_the_drop_reported_once() -> None:
    conn = MirobotConnection(max_output_lines=3)
    a, b = conn.send_line("M50"), conn.send_line("M20")
    events = feed(conn, [wire([f"text {i}" for i in range(1000)] + ["ok"])])
    assert events == [
        ProtocolViolation(
            "more than 3 text lines for one pending line; dropping the rest until its reply",
            b"text 3",
        ),
        LineAcknowledged(a, ("text 0", "text 1", "text 2"), None),
    ]
    # The next pending line starts afresh (and is reported again if it overflows too).
    events = feed(conn, [wire([f"more {i}" for i in range(5)] + ["error: Not idle"])])
    assert [type(e) for e in events] == [ProtocolViolation, LineRejected]
    assert events[1] == LineRejected(b, "Not idle", None, ("more 0", "more 1", "more 2"))


def test_default_output_cap_is_well_above_the_longest_settings_dump() -> None:
    longest = max(len(format_dump(default_settings(p), p)) for p in PROFILES)
    conn = MirobotConnection()
    assert conn.max_output_lines >= 2 * longest
    a = conn.send_line("$$")
    dump = format_dump(default_settings("2021"), "2021")
    events = feed(conn, [wire([*dump, "ok"])])
    assert events == [LineAcknowledged(a, tuple(dump), None)]


def test_overlong_complete_line_is_a_violation_too() -> None:
    conn = MirobotConnection(max_reply_length=16)
    a = conn.send_line("M50")
    events = feed(conn, [b"x" * 17 + b"\r\n" + b"y" * 16 + b"\r\nok\r\n"])
    assert [type(e) for e in events] == [ProtocolViolation, LineAcknowledged]
    assert events[1] == LineAcknowledged(a, ("y" * 16,), None)


def test_partial_lines_wait_for_their_end() -> None:
    conn = MirobotConnection()
    a = conn.send_line("M50")
    conn.receive_data(b"o")
    assert conn.next_event() is None
    assert conn.buffered_bytes == 1
    conn.receive_data(b"k")
    assert conn.next_event() is None
    conn.receive_data(b"\r")
    assert conn.next_event() == LineAcknowledged(a, (), None)
    conn.receive_data(b"\n")
    assert conn.next_event() is None


def test_eof_after_complete_lines() -> None:
    conn = MirobotConnection()
    a = conn.send_line("M50")
    conn.receive_data(b"ok\r\nALARM: Hard limit\r\n[Reset to")
    conn.receive_data(b"")
    assert drain(conn) == [
        LineAcknowledged(a, (), None),
        AlarmRaised("Hard limit"),
        ProtocolViolation("incomplete line at end of file", b"[Reset to"),
        ConnectionClosed(),
    ]
    assert conn.closed
    conn.receive_data(b"")  # repeated EOF: nothing more
    assert conn.next_event() is None
    with pytest.raises(MirobotUsageError):
        conn.receive_data(b"ok\r\n")


def test_eof_on_clean_boundary() -> None:
    conn = MirobotConnection()
    assert feed(conn, [b"\r\n", b""]) == [ConnectionClosed()]


# ---- the same events however the bytes are split -------------------------------------------------

_VOCABULARY = [
    "ok",
    "error: Alarm lock",
    "Error, E113,Undefined feed rate",
    "in homeing moving...ok",
    "Info, in homing moving...ok",
    "Free memory: 2036",
    "Info, M50: Unlock each axis.",
    "[Caution: Unlocked]",
    "Locked status of each axis!",
    "Soft limit triggered:Z",
    "ALARM: Hard limit",
    "",
    "   ",
    *BANNER_CLASSIC[:4],
    "Using reset pos!",
    *STATUS_LINES,
    *CORRUPTED,
    "x" * 70,  # longer than max_reply_length below
]


@st.composite
def _streams(draw: st.DrawFn) -> bytes:
    parts = draw(st.lists(st.sampled_from(_VOCABULARY), max_size=40))
    ends = draw(st.lists(st.sampled_from(["\r\n", "\n", "\r"]), min_size=len(parts)))
    data = "".join(p + e for p, e in zip(parts, ends, strict=False))
    data += draw(st.sampled_from(["", "o", "Info, partial", "y" * 90]))  # incomplete tail
    return data.encode("ascii")


@settings(max_examples=150)
@given(_streams(), st.lists(st.integers(0, 4000), max_size=30), st.integers(0, 8))
def test_events_do_not_depend_on_how_bytes_are_split(
    data: bytes, points: list[int], n_pending: int
) -> None:
    def run(chunks: Sequence[bytes]) -> list[Event]:
        conn = MirobotConnection(max_reply_length=64)
        for i in range(n_pending):
            conn.send_line(f"G4 P{i}")
        for chunk in chunks:
            conn.receive_data(chunk)
            assert conn.buffered_bytes <= 64
        conn.receive_data(b"")
        return drain(conn)

    whole = run([data])
    assert isinstance(whole[-1], ConnectionClosed)
    assert run([data[i : i + 1] for i in range(len(data))]) == whole
    assert run(split_at(data, points)) == whole


# ---- acknowledgements stay aligned under any interleaving ----------------------------------------

_TEXTS = [
    "Free memory: 2036",
    "M50: Unlock each axis.",
    "Info, M50: Unlock each axis.",
    "Info, M21: Angle mode start.",
    "[Caution: Unlocked]",
    "[Enabled]",
    "Locked status of each axis!",
    "Soft limit triggered:A",
    "GOAL OUT OF WORKSPACE, THERE IS NO VAILD VALUS FOR  THETA3!",
    "There is one angle out of limit!!!",
    "$10=99 (status report mask)",
    # the 2024 family (EVIDENCE-NEWER.md)
    "Info,M21: Angle mode start.",
    "Info,A100,Line Discard",
    "Error,E118,The given location is outside the workspace.",
    "The Cartesian position exceeds the boundary.",
]
_FINALS: list[tuple[str, str, int | None]] = [  # line, kind, code
    ("ok", "ok", None),
    ("in homeing moving...ok", "glued", None),
    ("Info, in homing moving...ok", "glued", None),
    ("error: Undefined feed rate", "error", None),
    ("error: Alarm lock", "error", None),
    ("Error, E113,Undefined feed rate", "error", 113),
    ("Error,E120,Unsupported command", "error", 120),
    ("Info,E102,Invalid statement", "error", 102),  # 2024: no ok after it
    ("Error,E113,Undefined feed rate", "error", 113),
    ("Error,E000,Invalid gcode ID:24", "error", 0),
    ("Info,in homing moving...\nok", "then-ok", None),  # 2024: its ok on its own line
]
_ASYNC = [*STATUS_LINES, *CORRUPTED, "ALARM: Hard limit", "ALARM: Abort during cycle", ""]
_UNSOLICITED = ["[Reset to continue]", "Info, something happened", "Free memory: 2036"]


@dataclass
class _Script:
    """What the robot prints for a batch of lines, and the events that must come out."""

    lines: list[str] = field(default_factory=list)
    expected: list[Any] = field(default_factory=list)  # PendingLine placeholders: int index


def _expected_async(line: str) -> Event | None:
    if not line:
        return None
    if line.startswith("<"):
        try:
            return StatusReceived(parse_status(line), line)
        except MirobotProtocolError as err:
            return StatusCorrupted(line, str(err))
    return AlarmRaised(line.partition(":")[2].strip())


@st.composite
def _batch(draw: st.DrawFn, first_index: int) -> tuple[int, _Script]:
    """n lines, each with a reply script, async lines anywhere, unsolicited text at the end."""
    n = draw(st.integers(0, 6))
    script = _Script()

    def maybe_async() -> None:
        for line in draw(st.lists(st.sampled_from(_ASYNC), max_size=2)):
            script.lines.append(line)
            event = _expected_async(line)
            if event is not None:
                script.expected.append(event)

    for i in range(first_index, first_index + n):
        maybe_async()
        output: list[str] = []
        for text in draw(st.lists(st.sampled_from(_TEXTS), max_size=3)):
            script.lines.append(text)
            output.append(text)
            maybe_async()
        final, kind, code = draw(st.sampled_from(_FINALS))
        script.lines.append(final)
        if kind == "error":
            text = final.split(",", 2)[-1] if code is not None else final.partition(":")[2]
            script.expected.append(("rejected", i, text.strip(), code, tuple(output)))
        else:
            if kind == "glued":
                output.append(final)
            elif kind == "then-ok":
                output.append(final.partition("\n")[0])
            script.expected.append(("acked", i, tuple(output), find_refusal(output)))
    maybe_async()
    for text in draw(st.lists(st.sampled_from(_UNSOLICITED), max_size=2)):
        script.lines.append(text)
        kind_ = ReplyKind.FEEDBACK if text.startswith("[") else ReplyKind.TEXT
        if text.startswith("Info, "):
            script.expected.append(UnsolicitedText(ReplyKind.INFO, text[6:]))
        else:
            script.expected.append(UnsolicitedText(kind_, text.strip("[]")))
    return n, script


@st.composite
def _sessions(draw: st.DrawFn) -> list[tuple[int, _Script]]:
    batches = []
    index = 0
    for _ in range(draw(st.integers(1, 4))):
        n, script = draw(_batch(index))
        batches.append((n, script))
        index += n
    return batches


@settings(max_examples=150)
@given(_sessions(), st.data())
def test_acks_stay_aligned_under_any_interleaving(
    sessions: list[tuple[int, _Script]], data: st.DataObject
) -> None:
    conn = MirobotConnection()
    sent: list[PendingLine] = []
    for n, script in sessions:
        for _ in range(n):
            sent.append(conn.send_line(f"M21 G91 X{len(sent)} F2000"))
        ends = data.draw(
            st.lists(
                st.sampled_from(["\r\n", "\n", "\r", "\r\n\r\n"]),
                min_size=len(script.lines),
                max_size=len(script.lines),
            )
        )
        stream = "".join(x + e for x, e in zip(script.lines, ends, strict=True)).encode()
        points = data.draw(st.lists(st.integers(0, max(len(stream), 1)), max_size=12))
        note(f"stream={stream!r} points={points}")
        events = feed(conn, split_at(stream, points))
        expected: list[Event] = []
        for item in script.expected:
            if isinstance(item, tuple) and item[0] == "acked":
                _, i, output, refusal = item
                expected.append(LineAcknowledged(sent[i], output, refusal))
            elif isinstance(item, tuple):
                _, i, text, code, output = item
                expected.append(LineRejected(sent[i], text, code, output))
            else:
                expected.append(item)
        assert events == expected
        # Exactly one final event per line, in order.
        finals = [e.line for e in events if isinstance(e, LineAcknowledged | LineRejected)]
        assert finals == sent[len(sent) - n :]
        assert conn.pending_count == 0 and conn.bytes_in_flight == 0


# ---- a stateful model ----------------------------------------------------------------------------


class ConnectionModel(RuleBasedStateMachine):
    """The host sends, the robot answers (in order), both at random; the model predicts events."""

    @initialize()
    def setup(self) -> None:
        self.conn = MirobotConnection(rx_buffer_size=64)
        self.pending: list[PendingLine] = []
        self.output: list[str] = []
        self.counter = 0

    def _robot_prints(self, lines: Sequence[str], cut: int) -> list[Event]:
        data = wire(lines)
        return feed(self.conn, split_at(data, [cut % (len(data) + 1)]))

    @rule(length=st.integers(0, 20))
    def send(self, length: int) -> None:
        line = f"G4 P{self.counter}".ljust(length, "0")
        self.counter += 1
        if not self.conn.fits(len(line) + 1):
            return  # the caller waits; nothing is sent
        pending = self.conn.send_line(line)
        note(f"sent {pending}")
        self.pending.append(pending)

    @precondition(lambda self: self.pending)
    @rule(text=st.sampled_from(_TEXTS), cut=st.integers(0, 100))
    def robot_prints_text(self, text: str, cut: int) -> None:
        assert self._robot_prints(["", text], cut) == []
        self.output.append(text)

    @precondition(lambda self: not self.pending)
    @rule(text=st.sampled_from(_UNSOLICITED), cut=st.integers(0, 100))
    def robot_prints_unsolicited(self, text: str, cut: int) -> None:
        events = self._robot_prints([text], cut)
        assert len(events) == 1 and isinstance(events[0], UnsolicitedText)

    @precondition(lambda self: self.pending)
    @rule(glued=st.sampled_from(["", "in homeing moving...ok"]), cut=st.integers(0, 100))
    def robot_acks(self, glued: str, cut: int) -> None:
        line = self.pending.pop(0)
        if glued:
            self.output.append(glued)
        output = tuple(self.output)
        self.output.clear()
        events = self._robot_prints([glued or "ok"], cut)
        assert events == [LineAcknowledged(line, output, find_refusal(output))]

    @precondition(lambda self: self.pending)
    @rule(
        reply=st.sampled_from([("error: Not idle", None), ("Error, E113,Not idle", 113)]),
        cut=st.integers(0, 100),
    )
    def robot_rejects(self, reply: tuple[str, int | None], cut: int) -> None:
        line = self.pending.pop(0)
        output = tuple(self.output)
        self.output.clear()
        assert self._robot_prints([reply[0]], cut) == [
            LineRejected(line, "Not idle", reply[1], output)
        ]

    @rule(line=st.sampled_from(_ASYNC), cut=st.integers(0, 300))
    def robot_async(self, line: str, cut: int) -> None:
        expected = _expected_async(line)
        assert self._robot_prints([line], cut) == ([] if expected is None else [expected])

    @precondition(lambda self: self.pending)
    @rule()
    def host_gives_up_on_oldest(self) -> None:
        assert self.conn.expire_oldest() == self.pending.pop(0)
        self.output.clear()

    @rule(cut=st.integers(0, 600))
    def robot_resets(self, cut: int) -> None:
        failed = tuple(self.pending)
        self.pending.clear()
        self.output.clear()
        assert self._robot_prints(BANNER_CLASSIC, cut) == [
            ResetDetected((), failed),
            BannerReceived(tuple(x.strip() for x in BANNER_CLASSIC if x)),
        ]
        self.conn.resolve_doubt()  # no reply came: none of them ran
        assert list(self.conn.events()) == ([DoubtResolved(failed)] if failed else [])

    @invariant()
    def counts_match(self) -> None:
        if not hasattr(self, "conn"):
            return
        assert self.conn.pending_lines == tuple(self.pending)
        assert self.conn.bytes_in_flight == sum(len(p.wire) for p in self.pending)
        assert self.conn.bytes_in_flight <= 64
        assert self.conn.buffered_bytes == 0


ConnectionModel.TestCase.settings = settings(max_examples=60, stateful_step_count=40, deadline=None)
TestConnectionModel = ConnectionModel.TestCase
