"""The facts the client tracks are read from the one parse of a line (``ParsedLine``), so every
reader agrees: the condition (alarm, base offset), the bus ledger (what fills the planner) and
the probe (settings listing) no longer re-read lines with regexes of their own."""

from __future__ import annotations

import pytest

from mirobot_async._core.line import parse_line
from mirobot_async._core.replies import parse_setting_line
from mirobot_async.bus._ledger import forwarded_line


@pytest.mark.parametrize(
    ("line", "changes"),
    [
        ("$41=10", True),
        ("$041=1", True),
        ("$43.4=1", True),
        ("$RST=$", True),
        ("$RST=*", True),
        ("$41=", True),  # not classified: conservatively, it may
        ("$44=1", False),
        ("$4=1", False),
        ("$$", False),
        ("G0 X41", False),
        ("($41=1)", False),
    ],
)
def test_which_lines_may_change_the_base_offset(line: str, changes: bool) -> None:
    assert parse_line(line).changes_base_offset is changes


@pytest.mark.parametrize(
    ("line", "moves"),
    [
        ("G0 X10", True),
        ("g1 z-5 f200", True),
        ("G04 P1", True),
        ("G4P0", True),
        ("M21 D10", True),
        ("G0 (X10)", False),
        ("G0 ; X10", False),
        ("M3 S1000", False),
        ("$H", False),
        ("$J=X10", False),
        ("G90", False),
        ("", False),
    ],
)
def test_what_may_fill_the_planner_is_read_from_the_parse(line: str, moves: bool) -> None:
    assert parse_line(line).queues_motion is moves
    assert forwarded_line(line, 1).moves is moves


@pytest.mark.parametrize(
    ("line", "setting"),
    [
        ("$110=1800.000 (x max rate)", (110, 1800.0)),
        ("$10=99", (10, 99.0)),
        ("$29=127.000(D1)", (29, 127.0)),
        ("  $0=10\r\n", (0, 10.0)),
        ("$N0=", None),
        ("ok", None),
        ("$1x=3", None),
    ],
)
def test_one_reading_of_a_settings_listing(line: str, setting: tuple[int, float] | None) -> None:
    assert parse_setting_line(line) == setting
    assert parse_setting_line(line.encode()) == setting
