"""Pure tests of the emulator's fault injection (mirobot_emulator.faults): deterministic by seed."""

from __future__ import annotations

import json
import random
import re
from pathlib import Path

import pytest
from mirobot_emulator.faults import (
    Command,
    Fault,
    FaultFilter,
    FaultSchedule,
    FaultSpecError,
    corrupt_status_line,
    parse_command,
    parse_fault,
)

VECTORS = Path(__file__).resolve().parents[3] / "shared" / "protocol" / "vectors.json"
STATUS = (
    b"<Run,Angle(ABCDXYZ):10.000,19.982,45.005,0.000,90.005,30.001,-20.000,"
    b"Cartesian coordinate(XYZ RxRyRz):-3.985,241.503,190.191,28.916,13.226,1.000,"
    b"Pump PWM:60,Valve PWM:0,Motion_MODE:1>\r\n"
)
# The strict shape of a status line (section 5 of PROTOCOL.md), numbers with 3 decimals.
_NUM = r"-?\d+\.\d{3}"
STRICT_STATUS = re.compile(
    rf"<[A-Za-z]+,Angle\(ABCDXYZ\):{_NUM}(?:,{_NUM}){{5,6}},"
    rf"Cartesian coordinate\(XYZ RxRyRz\):{_NUM}(?:,{_NUM}){{5}},"
    r"Pump PWM:\d+,Valve PWM:\d+(?:,Motion_MODE:\d+)?>"
)


def _status_lines() -> list[bytes]:
    lines = [STATUS]
    if VECTORS.exists():
        data = json.loads(VECTORS.read_text())
        for entry in data.get("status_lines", []):
            line = entry["line"] if isinstance(entry, dict) else entry
            if STRICT_STATUS.fullmatch(line):
                lines.append(line.encode() + b"\r\n")
    return lines


def _is_fragment_duplication(original: bytes, corrupted: bytes) -> bool:
    """corrupted == body[:k] + body[m:] (+ ending) with m < k: a fragment printed twice."""
    body = original.rstrip(b"\r\n")
    cbody = corrupted.rstrip(b"\r\n")
    extra = len(cbody) - len(body)
    if extra <= 0:
        return False
    for k in range(len(body) + 1):
        m = k - extra
        if m >= 0 and body[:k] + body[m:] == cbody:
            return True
    return False


# ----------------------------------------------------------------------------- parsing
@pytest.mark.parametrize(
    ("spec", "expected"),
    [
        ("drop-ok:3", Fault("drop-ok", n=3)),
        ("corrupt-status:1", Fault("corrupt-status", n=1)),
        ("ignore-status:2", Fault("ignore-status", n=2)),
        ("corrupt-status-rate:0.25", Fault("corrupt-status-rate", rate=0.25)),
        (
            "stall:1.5:2",
            Fault("stall", at=1.5, command=Command("stall", value=2.0, text="stall 2")),
        ),
        (
            "hard-limit:0.5",
            Fault(
                "hard-limit", at=0.5, command=Command("hard-limit", count=1, text="hard-limit 1")
            ),
        ),
        (
            "hard-limit:0.5:3",
            Fault(
                "hard-limit", at=0.5, command=Command("hard-limit", count=3, text="hard-limit 3")
            ),
        ),
        ("reset:2", Fault("reset", at=2.0, command=Command("reset", text="reset"))),
        ("close:0", Fault("close", at=0.0, command=Command("close", text="close"))),
    ],
)
def test_parse_fault(spec: str, expected: Fault) -> None:
    assert parse_fault(spec) == expected


@pytest.mark.parametrize(
    "spec",
    [
        "",
        "drop-ok",
        "drop-ok:0",
        "drop-ok:-1",
        "drop-ok:x",
        "drop-ok:1:2",
        "corrupt-status-rate:1.5",
        "corrupt-status-rate:nope",
        "stall:1",
        "stall:-1:2",
        "stall:1:inf",
        "reset",
        "close:soon",
        "explode:1",
    ],
)
def test_parse_fault_rejects(spec: str) -> None:
    with pytest.raises(FaultSpecError):
        parse_fault(spec)


def test_fault_spec_error_is_a_value_error() -> None:
    assert issubclass(FaultSpecError, ValueError)


@pytest.mark.parametrize(
    ("line", "expected"),
    [
        ("drop-ok", Command("drop-ok", count=1, text="drop-ok")),
        ("  DROP-OK   2 \n", Command("drop-ok", count=2, text="drop-ok 2")),
        ("corrupt-status 3", Command("corrupt-status", count=3, text="corrupt-status 3")),
        ("ignore-status", Command("ignore-status", count=1, text="ignore-status")),
        ("stall 0.25", Command("stall", value=0.25, text="stall 0.25")),
        ("hard-limit", Command("hard-limit", count=1, text="hard-limit")),
        ("hard-limit 2", Command("hard-limit", count=2, text="hard-limit 2")),
        ("reset", Command("reset", text="reset")),
        ("close", Command("close", text="close")),
        ("time-scale 0", Command("time-scale", value=0.0, text="time-scale 0")),
        ("time-scale 12.5", Command("time-scale", value=12.5, text="time-scale 12.5")),
    ],
)
def test_parse_command(line: str, expected: Command) -> None:
    assert parse_command(line) == expected


@pytest.mark.parametrize(
    "line",
    ["", "   ", "fly", "drop-ok 0", "drop-ok 1 2", "stall", "stall -1", "reset now", "time-scale"],
)
def test_parse_command_rejects(line: str) -> None:
    with pytest.raises(FaultSpecError):
        parse_command(line)


# ----------------------------------------------------------------------------- drop-ok
def _run_lines(flt: FaultFilter, lines: list[bytes]) -> list[bytes]:
    out = []
    for line in lines:
        kept = flt.output_line(line)
        if kept is not None:
            out.append(kept)
    return out


def test_drop_ok_n_drops_exactly_the_nth_ok_line() -> None:
    flt = FaultFilter([parse_fault("drop-ok:2"), parse_fault("drop-ok:4")])
    info = b"Info, M50: Unlock each axis.\r\n"
    lines = [b"ok\r\n", info, b"ok\r\n", b"ok\r\n", STATUS, b"ok\r\n", b"ok\r\n"]
    out = _run_lines(flt, lines)
    assert out == [b"ok\r\n", info, b"ok\r\n", STATUS, b"ok\r\n"]
    assert flt.oks_seen == 5
    assert flt.dropped_oks == 2


def test_glued_ok_is_not_an_ok_line() -> None:
    flt = FaultFilter([parse_fault("drop-ok:1")])
    assert flt.output_line(b"in homeing moving...ok\r\n") == b"in homeing moving...ok\r\n"
    assert flt.output_line(b"ok\r\n") is None
    assert flt.output_line(b"ok\r\n") == b"ok\r\n"


def test_drop_ok_command_drops_the_next_n() -> None:
    flt = FaultFilter()
    assert flt.output_line(b"ok\r\n") == b"ok\r\n"
    assert flt.apply(parse_command("drop-ok 2"))
    assert flt.output_line(b"[Caution: Unlocked]\r\n") == b"[Caution: Unlocked]\r\n"
    assert flt.output_line(b"ok\r\n") is None
    assert flt.output_line(b"ok\r\n") is None
    assert flt.output_line(b"ok\r\n") == b"ok\r\n"


def test_apply_refuses_commands_that_are_not_data_faults() -> None:
    flt = FaultFilter()
    for line in ("reset", "close", "stall 1", "hard-limit", "time-scale 2"):
        assert not flt.apply(parse_command(line))


def test_lines_without_faults_pass_unchanged() -> None:
    flt = FaultFilter()
    lines = [b"\r\n", b"ok\r\n", STATUS, b"error: Bad number format\r\n", b"ok\n", b"ok"]
    assert _run_lines(flt, lines) == lines


# ----------------------------------------------------------------------------- corruption
def test_corrupt_status_n_corrupts_only_the_nth_status_line() -> None:
    flt = FaultFilter([parse_fault("corrupt-status:2")], seed=7)
    first = flt.output_line(STATUS)
    assert flt.output_line(b"ok\r\n") == b"ok\r\n"
    second = flt.output_line(STATUS)
    third = flt.output_line(STATUS)
    assert first == STATUS
    assert third == STATUS
    assert second is not None
    assert second != STATUS
    assert second.endswith(b"\r\n")
    assert flt.corrupted_status_lines == 1
    assert flt.status_lines_seen == 3


def test_corrupt_status_command_corrupts_the_next_n() -> None:
    flt = FaultFilter(seed=1)
    assert flt.apply(parse_command("corrupt-status 2"))
    out = [flt.output_line(STATUS) for _ in range(3)]
    assert out[0] != STATUS
    assert out[1] != STATUS
    assert out[2] == STATUS


@pytest.mark.parametrize("seed", range(40))
def test_corruption_duplicates_a_fragment_and_is_unparsable(seed: int) -> None:
    rng = random.Random(seed)
    for line in _status_lines():
        corrupted = corrupt_status_line(line, rng)
        assert corrupted.endswith(b"\r\n")
        assert _is_fragment_duplication(line, corrupted), corrupted
        # A digit glued to letters: e.g. "13.226esian coordinate(...)"
        assert re.search(rb"\d[A-Za-z_]", corrupted), corrupted
        assert STRICT_STATUS.fullmatch(corrupted.rstrip(b"\r\n").decode()) is None


def test_corruption_is_unparsable_for_the_client_parser() -> None:
    replies = pytest.importorskip("mirobot_async.replies")
    errors = pytest.importorskip("mirobot_async.errors")
    rng = random.Random(3)
    for line in _status_lines():
        text = line.rstrip(b"\r\n").decode()
        replies.parse_status(text)  # the original parses
        for _ in range(50):
            corrupted = corrupt_status_line(line, rng).rstrip(b"\r\n").decode()
            with pytest.raises(errors.MirobotProtocolError):
                replies.parse_status(corrupted)


def test_corruption_is_deterministic_by_seed() -> None:
    def run(seed: int) -> list[bytes | None]:
        flt = FaultFilter([parse_fault("corrupt-status-rate:0.5")], seed=seed)
        return [flt.output_line(STATUS) for _ in range(200)]

    assert run(11) == run(11)
    assert run(11) != run(12)


def test_corruption_leaves_lines_without_header_or_number_alone() -> None:
    rng = random.Random(0)
    for line in (b"<>\r\n", b"<Idle>\r\n", b"<1.000>\r\n", b"ok\r\n"):
        assert corrupt_status_line(line, rng) == line


def test_corrupt_status_rate_bounds_and_frequency() -> None:
    never = FaultFilter([parse_fault("corrupt-status-rate:0")], seed=5)
    assert all(never.output_line(STATUS) == STATUS for _ in range(100))
    always = FaultFilter([parse_fault("corrupt-status-rate:1")], seed=5)
    assert all(always.output_line(STATUS) != STATUS for _ in range(100))
    some = FaultFilter([parse_fault("corrupt-status-rate:0.3")], seed=5)
    corrupted = sum(some.output_line(STATUS) != STATUS for _ in range(2000))
    assert 500 <= corrupted <= 700
    assert some.corrupted_status_lines == corrupted


def test_rate_does_not_touch_other_lines() -> None:
    flt = FaultFilter([parse_fault("corrupt-status-rate:1")], seed=5)
    assert flt.output_line(b"ok\r\n") == b"ok\r\n"
    assert flt.output_line(b"Qinnew Robot 20210516\r\n") == b"Qinnew Robot 20210516\r\n"


# ----------------------------------------------------------------------------- ignore-status
def test_ignore_status_n_removes_the_nth_question_mark_across_chunks() -> None:
    flt = FaultFilter([parse_fault("ignore-status:3")])
    assert flt.input_bytes(b"?") == b"?"
    assert flt.input_bytes(b"G0 X1?\n") == b"G0 X1?\n"
    assert flt.input_bytes(b"(why?)?") == b"(why)?"
    assert flt.input_bytes(b"??") == b"??"
    assert flt.status_requests_seen == 6
    assert flt.ignored_status_requests == 1


def test_ignore_status_command_ignores_the_next_n() -> None:
    flt = FaultFilter()
    assert flt.input_bytes(b"?M50\n") == b"?M50\n"
    assert flt.apply(parse_command("ignore-status 2"))
    assert flt.input_bytes(b"?!?~?") == b"!~?"
    assert flt.input_bytes(b"?") == b"?"
    assert flt.ignored_status_requests == 2


def test_input_without_question_marks_is_untouched() -> None:
    flt = FaultFilter([parse_fault("ignore-status:1")])
    data = bytes(range(256)).replace(b"?", b"")
    assert flt.input_bytes(data) == data
    assert flt.input_bytes(b"") == b""


# ----------------------------------------------------------------------------- schedule
def test_schedule_orders_timed_faults_and_ignores_counted_ones() -> None:
    faults = [
        parse_fault("close:3"),
        parse_fault("drop-ok:1"),
        parse_fault("stall:1:0.5"),
        parse_fault("reset:1"),
        parse_fault("hard-limit:2:2"),
    ]
    schedule = FaultSchedule(faults)
    assert schedule.next_time() == 1.0
    assert schedule.due(0.99) == []
    assert [c.kind for c in schedule.due(1.0)] == ["stall", "reset"]
    assert schedule.next_time() == 2.0
    due = schedule.due(10.0)
    assert [c.kind for c in due] == ["hard-limit", "close"]
    assert due[0].count == 2
    assert schedule.next_time() is None
    assert schedule.due(100.0) == []


def test_empty_schedule() -> None:
    schedule = FaultSchedule()
    assert schedule.next_time() is None
    assert schedule.due(1e9) == []
