"""The tape format: what reads back, and what a bad file gets (an error naming file and line)."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mirobot_async._tapes.format import (
    Printed,
    Written,
    event_line,
    header_line,
    read_tapes,
    split_tapes,
)
from mirobot_async.errors import MirobotUsageError, TapeFormatError

HEADER = {"id": "unit", "source": "virtual", "clock": "simulated", "link": "virtual"}


def _write(path: Path, lines: list[str], *, compress: bool = False) -> Path:
    text = "".join(lines)
    if compress:
        path.write_bytes(gzip.compress(text.encode()))
    else:
        path.write_text(text)
    return path


@given(
    st.lists(
        st.one_of(
            st.builds(Written, st.floats(0, 1e4), st.binary(min_size=1, max_size=40)),
            st.builds(
                Printed,
                st.floats(0, 1e4),
                st.binary(max_size=80),
                st.one_of(st.none(), st.floats(0, 1e4)),
            ),
        ),
        max_size=30,
    ),
    st.booleans(),
)
def test_every_byte_and_instant_reads_back(
    tmp_path_factory: pytest.TempPathFactory,
    events: list[Written | Printed],
    compress: bool,
) -> None:
    path = tmp_path_factory.mktemp("tape") / "t.jsonl"
    _write(path, [header_line(HEADER), *map(event_line, events)], compress=compress)
    (tape,) = read_tapes(path)
    assert tape.header["id"] == "unit"
    assert len(tape.events) == len(events)
    for got, sent in zip(tape.events, events, strict=True):
        assert type(got) is type(sent)
        assert got.data == sent.data
        assert got.t == pytest.approx(sent.t, abs=1e-7)


def test_a_writer_killed_mid_line_leaves_the_whole_lines(tmp_path: Path) -> None:
    lines = [header_line(HEADER), event_line(Written(0.1, b"?")), '{"t":0.2,"out":"o']
    (tape,) = read_tapes(_write(tmp_path / "cut.jsonl", lines))
    assert [e.data for e in tape.events] == [b"?"]  # type: ignore[union-attr]


@pytest.mark.parametrize(
    ("lines", "line", "problem"),
    [
        (['{"tape":2,"id":"x"}\n'], 1, "unknown tape version 2"),
        (['{"tape":1,"id":"x","colour":"red"}\n'], 1, "unknown header field(s): colour"),
        (['{"tape":1,"id":"x"}\n', '{"t":1,"in":"?"\n'], 2, "invalid JSON"),
        (['{"tape":1,"id":"x"}\n', '{"t":1,"in":"?","speed":3}\n'], 2, "unknown field(s)"),
        (['{"tape":1,"id":"x"}\n', '{"t":"soon","in":"?"}\n'], 2, "t must be a finite number"),
        (['{"tape":1,"id":"x"}\n', '{"t":1,"in":"\\u2603"}\n'], 2, "above U+00FF"),
        (['{"tape":1,"id":"x"}\n', '{"t":1}\n'], 2, "not an event"),
        (['{"t":1,"in":"?"}\n'], 1, "an event before the first header"),
        (["\n"], 1, "no tape header"),
    ],
)
def test_a_bad_tape_names_its_file_and_line(
    tmp_path: Path, lines: list[str], line: int, problem: str
) -> None:
    path = _write(tmp_path / "bad.jsonl", lines)
    with pytest.raises(TapeFormatError) as caught:
        list(read_tapes(path))
    assert caught.value.path == str(path)
    assert caught.value.line == line
    assert problem in caught.value.problem
    assert str(caught.value).startswith(f"{path}:{line}: bad tape: ")
    assert isinstance(caught.value, MirobotUsageError)


def test_a_truncated_gzip_file_is_a_bad_tape(tmp_path: Path) -> None:
    lines = [header_line(HEADER)] + [event_line(Written(k / 10, b"G0 X1\n")) for k in range(500)]
    data = gzip.compress("".join(lines).encode())
    path = tmp_path / "cut.jsonl.gz"
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(TapeFormatError, match="unreadable"):
        list(read_tapes(path))


def test_a_missing_file_is_a_bad_tape(tmp_path: Path) -> None:
    with pytest.raises(TapeFormatError, match="no such file"):
        split_tapes(tmp_path / "absent.jsonl")


def test_a_header_is_checked_as_it_is_written() -> None:
    with pytest.raises(ValueError, match="unknown header field"):
        header_line({"id": "x", "hostname": "lab-pc"})
    assert json.loads(header_line(HEADER))["tape"] == 1
