"""Pure tests of the emulator's fault injection (mirobot_emulator._faults): seeded."""

from __future__ import annotations

import contextlib
import json
import math
import os
import random
import re
import selectors
import termios
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from mirobot_emulator._faults import (
    Command,
    Fault,
    FaultFilter,
    FaultSchedule,
    FaultSpecError,
    OutputDelay,
    corrupt_status_line,
    link_commands,
    parse_command,
    parse_fault,
)
from mirobot_emulator.server import ServerOptions, VirtualMirobot

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
        (
            "split-bytes",
            Fault("split-bytes", command=Command("split-bytes", count=1, text="split-bytes on")),
        ),
        (
            "split-bytes:off",
            Fault("split-bytes", command=Command("split-bytes", count=0, text="split-bytes off")),
        ),
        ("delay:20", Fault("delay", command=Command("delay", value=0.02, text="delay 20"))),
        ("delay:0", Fault("delay", command=Command("delay", value=0.0, text="delay 0"))),
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
        "split-bytes:maybe",
        "split-bytes:on:off",
        "delay",
        "delay:-1",
        "delay:x",
        "delay:inf",
        "delay:nan",
        "delay:1:2",
        "delay:1e9",
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
        ("split-bytes", Command("split-bytes", count=1, text="split-bytes on")),
        ("split-bytes on", Command("split-bytes", count=1, text="split-bytes on")),
        ("SPLIT-BYTES OFF", Command("split-bytes", count=0, text="split-bytes off")),
        ("delay 20", Command("delay", value=0.02, text="delay 20")),
        ("delay 0", Command("delay", value=0.0, text="delay 0")),
        ("delay 2.5", Command("delay", value=0.0025, text="delay 2.5")),
        ("stats", Command("stats", text="stats")),
    ],
)
def test_parse_command(line: str, expected: Command) -> None:
    assert parse_command(line) == expected


@pytest.mark.parametrize(
    "line",
    [
        "",
        "   ",
        "fly",
        "drop-ok 0",
        "drop-ok 1 2",
        "stall",
        "stall -1",
        "reset now",
        "time-scale",
        "split-bytes maybe",
        "split-bytes on off",
        "delay",
        "delay -5",
        "delay nan",
        "delay 1 2",
        "stats now",
    ],
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
    for line in (
        "reset",
        "close",
        "stall 1",
        "hard-limit",
        "time-scale 2",
        "split-bytes",
        "delay 5",
    ):
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
    replies = pytest.importorskip("mirobot_async._core.replies")
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


def test_schedule_ignores_link_faults_and_link_commands_lists_them_in_order() -> None:
    faults = [
        parse_fault("delay:20"),
        parse_fault("reset:1"),
        parse_fault("split-bytes"),
        parse_fault("drop-ok:1"),
    ]
    schedule = FaultSchedule(faults)
    assert [c.kind for c in schedule.due(100.0)] == ["reset"]
    assert link_commands(faults) == [
        Command("delay", value=0.02, text="delay 20"),
        Command("split-bytes", count=1, text="split-bytes on"),
    ]
    assert link_commands([parse_fault("stall:1:1")]) == []


# ----------------------------------------------------------------------------- delay
def test_delay_holds_each_chunk_for_the_delay() -> None:
    delay = OutputDelay(0.02)
    delay.push(b"ok\r\n", 1.0)
    delay.push(STATUS, 1.005)
    assert len(delay) == 4 + len(STATUS)
    assert delay.next_time() == pytest.approx(1.02)
    assert delay.pop(1.0199) == b""
    assert delay.pop(1.02) == b"ok\r\n"
    assert delay.next_time() == pytest.approx(1.025)
    assert delay.pop(1.024) == b""
    assert delay.pop(5.0) == STATUS
    assert delay.next_time() is None
    assert len(delay) == 0


def test_delay_zero_passes_through() -> None:
    delay = OutputDelay()
    assert delay.delay == 0.0
    delay.push(b"ok\r\n", 3.0)
    assert delay.pop(3.0) == b"ok\r\n"
    delay.push(b"", 3.0)
    assert delay.next_time() is None


def test_lowering_the_delay_never_reorders() -> None:
    delay = OutputDelay(0.5)
    delay.push(b"first\r\n", 0.0)  # due at 0.5
    delay.delay = 0.0
    delay.push(b"second\r\n", 0.1)  # would be due at 0.1: waits for "first"
    assert delay.pop(0.2) == b""
    assert delay.pop(0.5) == b"first\r\nsecond\r\n"
    delay.push(b"third\r\n", 0.6)  # nothing waits: due at once
    assert delay.pop(0.6) == b"third\r\n"


def test_delay_clear_forgets_everything() -> None:
    delay = OutputDelay(10.0)
    delay.push(b"ok\r\n", 0.0)
    delay.clear()
    assert delay.pop(100.0) == b""
    delay.delay = 0.0
    delay.push(b"ok\r\n", 1.0)  # not held behind the cleared chunk's release time
    assert delay.pop(1.0) == b"ok\r\n"


@pytest.mark.parametrize("bad", [-0.001, math.inf, math.nan])
def test_delay_rejects_bad_values(bad: float) -> None:
    with pytest.raises(ValueError):
        OutputDelay(bad)
    delay = OutputDelay()
    with pytest.raises(ValueError):
        delay.delay = bad


# ----------------------------------------------------------------------------- link faults, served
# The link faults act in the pty server (mirobot_emulator.server); served here in a thread of the
# test process and read with plain os.read on the port.


def _read_until(fd: int, done: Callable[[bytes], bool], timeout: float = 10.0) -> list[bytes]:
    """Read chunks from ``fd`` until ``done(everything)``; return the chunks as read."""
    chunks: list[bytes] = []
    data = b""
    deadline = time.monotonic() + timeout
    with selectors.DefaultSelector() as selector:
        selector.register(fd, selectors.EVENT_READ)
        while not done(data):
            left = deadline - time.monotonic()
            assert left > 0, f"timed out; read so far: {data!r}"
            if selector.select(left):
                chunk = os.read(fd, 4096)
                chunks.append(chunk)
                data += chunk
    return chunks


@contextlib.contextmanager
def _served(*faults: str) -> Iterator[tuple[VirtualMirobot, int]]:
    options = ServerOptions(
        firmware="classic", time_scale=0, faults=tuple(map(parse_fault, faults))
    )
    with VirtualMirobot(options) as robot:
        fd = os.open(robot.path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            # Opened as pyserial does: configure the port, then flush the power-on banner.
            termios.tcsetattr(fd, termios.TCSANOW, termios.tcgetattr(fd))
            termios.tcflush(fd, termios.TCIFLUSH)
            yield robot, fd
        finally:
            os.close(fd)


def _settings_dump_done(data: bytes) -> bool:
    return data.endswith(b"ok\r\n") and data.count(b"\n") > 20


def test_split_bytes_serves_single_byte_reads() -> None:
    with _served() as (_, fd):
        os.write(fd, b"$$\n")
        whole = b"".join(_read_until(fd, _settings_dump_done))
    with _served("split-bytes") as (robot, fd):
        os.write(fd, b"$$\n")
        chunks = _read_until(fd, _settings_dump_done)
        assert b"".join(chunks) == whole  # the same bytes, only cut differently
        # one write per byte; reads see them apart unless this (loaded) reader falls behind
        assert robot.server.split_writes >= 0.9 * len(whole)
        # a reader waiting wakes on the first byte (a loaded one may see later bytes together)
        assert any(len(chunk) == 1 for chunk in chunks), [len(c) for c in chunks]
        # turned off from the control channel: whole lines again
        assert robot.command("split-bytes off") == "ack split-bytes off"
        written = robot.server.split_writes
        os.write(fd, b"$$\n")
        assert b"".join(_read_until(fd, _settings_dump_done)) == whole
        assert robot.server.split_writes == written


def test_split_bytes_from_the_control_channel() -> None:
    with _served() as (robot, fd):
        assert robot.command("split-bytes") == "ack split-bytes on"
        os.write(fd, b"\n" * 50)
        chunks = _read_until(fd, lambda data: data.count(b"ok\r\n") == 50)
        assert b"".join(chunks) == b"ok\r\n" * 50
        assert robot.server.split_writes >= 0.9 * 200  # one write per byte
        # (how the reads come out depends on when this process is scheduled: under load the
        # pty hands over several single-byte writes at once, so the chunks are not checked)


def test_delay_holds_every_reply_and_keeps_the_order() -> None:
    with _served("delay:300") as (robot, fd):
        start = time.monotonic()
        os.write(fd, b"M3 S5\n?\nM99\n")
        data = b"".join(_read_until(fd, lambda d: d.count(b"\n") >= 4))
        assert time.monotonic() - start >= 0.29
        lines = data.split(b"\r\n")
        assert lines[0] == b"ok"
        assert lines[1].startswith(b"<Idle,") and b"Pump PWM:5," in lines[1]
        assert lines[2:] == [b"ok", b"error: Unsupported command", b""]
        # changed from the control channel: a long delay, then none (a reply held for the
        # long one would come after 10 s, far past the bound below even on a loaded machine)
        assert robot.command("delay 10000") == "ack delay 10000"
        assert robot.command("delay 0") == "ack delay 0"
        start = time.monotonic()
        os.write(fd, b"\n")
        assert b"".join(_read_until(fd, lambda d: d.endswith(b"ok\r\n"))) == b"ok\r\n"
        assert time.monotonic() - start < 5.0  # not held for the 10 s delay


def _stats(robot: VirtualMirobot) -> dict[str, int]:
    answer = robot.command("stats")
    assert answer.startswith("ack stats ")
    return {name: int(value) for name, value in (w.split("=") for w in answer.split()[2:])}


def test_stats_counts_what_crossed_the_wire() -> None:
    with _served("drop-ok:1", "corrupt-status:2") as (robot, fd):
        before = _stats(robot)
        assert before["bytes_in"] == before["lines_in"] == 0
        assert before["bytes_out"] > 0  # the power-on banner
        os.write(fd, b"M3 S1\n?\nM3 S2\n?")
        data = b"".join(_read_until(fd, lambda d: d.count(b"ok\r\n") == 2 and d.count(b">") == 2))
        stats = _stats(robot)
        assert stats["bytes_in"] == 15
        assert stats["lines_in"] == 3
        assert stats["status_requests_in"] == 2
        assert stats["resets_in"] == 0
        assert stats["bytes_out"] == before["bytes_out"] + len(data)
        assert stats["oks_seen"] == 3
        assert stats["dropped_oks"] == 1
        assert stats["status_lines"] == 2
        assert stats["corrupted_status"] == 1
        assert stats["ignored_status"] == stats["split_writes"] == 0
        assert stats["ports_opened"] == 1  # our open
