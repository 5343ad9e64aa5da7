"""The tape recorder on its own: events held until the header, then streamed line by line; the
partial line and the end marker at close; bounded memory; link kinds without hosts or paths."""

from __future__ import annotations

import gzip
import json
import tracemalloc
from pathlib import Path

import pytest

from mirobot_async._tapes.format import Marker, Printed, Written, read_tapes
from mirobot_async._tapes.recorder import HEADER_WAIT_BYTES, TapeRecorder, link_kind
from mirobot_async.errors import MirobotUsageError

HEADER = {"id": "recorded test", "source": "device", "link": "serial"}


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines(keepends=True)


def test_events_wait_for_the_header_then_stream(tmp_path: Path) -> None:
    path = tmp_path / "t.jsonl"
    recorder = TapeRecorder(path, HEADER, lambda: {"banner": ["Qinnew"], "family": "classic"})
    recorder.written(b"?")
    recorder.received(b"<Idle,...>\r")
    recorder.received(b"\nok\r\nerr")
    assert path.read_text() == ""  # held: the header is not known yet
    recorder.begin()
    assert len(_lines(path)) == 4  # header, ?, status, ok
    recorder.written(b"G0 X1\n")
    assert len(_lines(path)) == 5  # streamed at once
    recorder.received(b"or: x\r\n")
    recorder.received(b"cut")
    recorder.close()
    recorder.close()  # idempotent
    [tape] = read_tapes(path)
    assert tape.header["clock"] == "wall" and tape.header["family"] == "classic"
    assert tape.header["banner"] == ["Qinnew"] and "started" in tape.header
    kinds = [(type(e).__name__, getattr(e, "data", None)) for e in tape.events]
    assert kinds == [
        ("Written", b"?"),
        ("Printed", b"<Idle,...>\r\n"),
        ("Printed", b"ok\r\n"),
        ("Written", b"G0 X1\n"),
        ("Printed", b"error: x\r\n"),
        ("Printed", b"cut"),
        ("Marker", None),
    ]
    last = tape.events[-2]
    assert isinstance(last, Printed) and last.partial and last.t0 is None
    end = tape.events[-1]
    assert isinstance(end, Marker) and end.fields["end"] == "closed"
    times = [e.t for e in tape.events]
    assert times == sorted(times)


def test_a_tape_is_appended_to_a_file_of_tapes(tmp_path: Path) -> None:
    path = tmp_path / "t.jsonl"
    for end in ("closed", "lost"):
        recorder = TapeRecorder(path, HEADER)
        recorder.written(b"?")
        recorder.close(end)
    tapes = list(read_tapes(path))
    assert [t.events[-1].fields["end"] for t in tapes] == ["closed", "lost"]  # type: ignore[union-attr]


def test_the_header_is_written_early_when_held_events_outgrow_the_bound(tmp_path: Path) -> None:
    path = tmp_path / "t.jsonl"
    recorder = TapeRecorder(path, HEADER)
    line = b"x" * 100 + b"\r\n"
    while not path.read_text():
        recorder.received(line)
        assert recorder.buffered <= HEADER_WAIT_BYTES + 200
    assert recorder.buffered == 0
    recorder.begin()  # the connect ends later: nothing more to write
    recorder.close()
    [tape] = read_tapes(path)
    assert all(e.data == line for e in tape.events if isinstance(e, Printed))


def test_a_simulated_clock_gives_the_instants(tmp_path: Path) -> None:
    path = tmp_path / "t.jsonl"
    recorder = TapeRecorder(path, HEADER)
    now = [12.5]
    recorder.use_clock(lambda: now[0])
    recorder.written(b"?")
    now[0] = 12.75
    recorder.received(b"ok\r\n")
    recorder.close()
    [tape] = read_tapes(path)
    assert tape.header["clock"] == "simulated"
    assert [e.t for e in tape.events] == [12.5, 12.75, 12.75]


def test_memory_stays_bounded_over_many_lines(tmp_path: Path) -> None:
    path = tmp_path / "t.jsonl"
    recorder = TapeRecorder(path, HEADER)
    recorder.begin()
    status = b"<Idle,Angle(ABCDXYZ):0.000,0.000,0.000,0.000,0.000,0.000,0.000,Pump PWM:0>\r\n"
    tracemalloc.start()
    try:
        for k in range(5_000):  # a leak of even 16 bytes a line would show: 72 KB
            recorder.written(b"?")
            recorder.received(status[: k % 50])
            recorder.received(status[k % 50 :])
            assert recorder.buffered == 0
            if k == 500:
                tracemalloc.reset_peak()
                base = tracemalloc.get_traced_memory()[0]
        current, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert current - base < 64 * 1024 and peak - base < 256 * 1024
    recorder.close()
    [tape] = read_tapes(path)
    assert sum(isinstance(e, Written) for e in tape.events) == 5_000
    assert sum(isinstance(e, Printed) and e.data == status for e in tape.events) == 5_000


def test_a_killed_writer_leaves_the_tape_up_to_its_last_whole_line(tmp_path: Path) -> None:
    path = tmp_path / "t.jsonl"
    recorder = TapeRecorder(path, HEADER)
    recorder.begin()
    recorder.written(b"?")
    recorder.received(b"ok\r\n")
    with path.open("a") as file:  # what a process killed in the middle of a write leaves
        file.write('{"t":0.5,"out":"o')
    [tape] = read_tapes(path)
    assert [e.data for e in tape.events if isinstance(e, Written | Printed)] == [b"?", b"ok\r\n"]
    recorder.close()


def test_a_gzip_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "t.jsonl.gz"
    with gzip.open(path, "wt") as file:
        file.write(json.dumps({"tape": 1}) + "\n")
    with pytest.raises(MirobotUsageError, match="gzip"):
        TapeRecorder(path, HEADER)


def test_an_unwritable_file_is_a_usage_error(tmp_path: Path) -> None:
    with pytest.raises(MirobotUsageError, match="cannot be written"):
        TapeRecorder(tmp_path / "missing" / "t.jsonl", HEADER)


@pytest.mark.parametrize(
    ("url", "kind"),
    [
        ("/dev/ttyUSB0", "serial"),
        ("COM3", "serial"),
        ("auto", "serial"),
        ("socket://robot.example:5000", "tcp"),
        ("rfc2217://10.0.0.2:2217", "rfc2217"),
        ("loop://", "loop"),
        ("virtual://3", "virtual"),
        ("spy://user@/home/me/x", "spy"),
    ],
)
def test_the_link_kind_names_no_host_or_path(url: str, kind: str) -> None:
    assert link_kind(url, object()) == kind


def test_the_link_kind_the_transport_says_wins() -> None:
    class Bus:
        link_kind = "bus"

    assert link_kind("/dev/ttyUSB0@03", Bus()) == "bus"
