"""The one parse of a line (:mod:`mirobot_async._core.line`) and the one validation
(:mod:`mirobot_async._core.validation`).

Every grammar corner asserted here was observed on the firmware oracle (the vendor's firmware
20191228_2 in an AVR simulator, driven as a black box): the line, what the firmware answered and
where the arm went.
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mirobot_async._core import gcode
from mirobot_async._core.line import CodeWord, parse_line, read_number
from mirobot_async._core.validation import check_line, validate_line
from mirobot_async.errors import MirobotUsageError

# (number text, value the firmware moved to, digits dropped that changed it)
NUMBERS = [
    ("0000000030", 0.0, True),  # 8 digits kept, leading zeros count: 0
    ("00000030", 30.0, False),
    ("12.3456789", 12.345678, True),
    ("99999999999", 99999999000.0, True),  # soft limit on the oracle
    ("0000000000040", 0.0, True),  # "X 0 0 0 0 0 0 0 0 0 4 0" moved to 0
    ("+5", 5.0, False),
    ("-.5", -0.5, False),
    ("7.", 7.0, False),
    ("1.0000000000", 1.0, False),
]


@pytest.mark.parametrize(("text", "value", "lossy"), NUMBERS)
def test_numbers_read_as_the_firmware_reads_them(text: str, value: float, lossy: bool) -> None:
    number = read_number(text, 0)
    assert number is not None
    assert number.value == pytest.approx(value, rel=1e-12)
    assert number.lossy is lossy
    assert number.end == len(text)


@pytest.mark.parametrize(
    ("line", "error"),
    [
        ("G0 X.", "Bad number format"),
        ("G0 X--5", "Bad number format"),
        ("G0 X+-3", "Bad number format"),
        ("G0 X1.2.3", "Expected command letter"),
        ("G0 #1", "Expected command letter"),
        ("G0 X1" + "0" * 80, "Line overflow"),
    ],
)
def test_syntax_errors(line: str, error: str) -> None:
    assert parse_line(line).syntax_error == error


def test_no_exponent_e_is_the_valve_word() -> None:
    """``X1e1`` moved the oracle's J1 to 1 (and set the valve PWM to 1)."""
    parsed = parse_line("G0 X1e1")
    assert [str(w) for w in parsed.words] == ["G0", "X1", "E1"]


def test_comments_spaces_and_case() -> None:
    parsed = parse_line("g0 x(c)2 ; rest")  # the oracle moved to 2
    assert parsed.text == "G0X2" and parsed.value("X") == 2.0
    assert parse_line("N10 G0 X3").value("N") == 10.0  # line numbers are accepted


# (word, the command number the firmware executes, refused with 'Invalid gcode ID:23')
CODES = [
    ("M20.001", 20, False),
    ("M16404", 20, False),
    ("M21.004", 21, False),
    ("M20.5", 20, True),
    ("M20.005", 20, True),
    ("M276", 20, True),
    ("M-236", 20, True),
    ("G0.001", 0, False),
    ("G0.5", 0, True),
    ("G0.005", 0, True),
    ("G256", 0, True),
    ("G-256", 0, True),
    ("G00", 0, False),
    ("M03", 3, False),
]


@pytest.mark.parametrize(("text", "code", "refused"), CODES)
def test_command_numbers_as_the_firmware_reads_them(text: str, code: int, refused: bool) -> None:
    word = parse_line(text).words[0]
    assert isinstance(word, CodeWord)
    assert (word.code, word.fraction_error) == (code, refused)
    assert word.canonical is (text in ("G00", "M03"))


def test_parsed_line_properties() -> None:
    parsed = parse_line("M20 G91 G1 X1 Y2 F300 G21")
    assert (parsed.coordinate_mode, parsed.distance, parsed.motion, parsed.units) == (
        20,
        91,
        1,
        21,
    )
    assert dict(parsed.axis_words) == {"X": 1.0, "Y": 2.0} and parsed.may_move
    assert parse_line("G4 P1.5").dwell_seconds == 1.5
    assert not parse_line("G4 P1.5").may_move
    assert parse_line("M30").program_end
    assert parse_line("X1 X2").repeated == ("X",)
    for homing in ("$H", "$HH", "$H8", "$HX"):
        assert parse_line(homing).is_homing and parse_line(homing).may_move
    setting = parse_line("$041=40").dollar
    assert setting is not None and (setting.kind, setting.number, setting.value) == (
        "setting",
        41,
        40.0,
    )
    assert setting.canonical
    odd = parse_line("$41.5=4").dollar
    assert odd is not None and odd.number == 41 and not odd.canonical
    assert parse_line("$N0=G20").dollar.kind == "startup"  # type: ignore[union-attr]


def test_coordinate_word_orders_the_firmware_refuses() -> None:
    """Oracle: ``G21 M21``, ``G20 M20``, ``M21 M3``, ``M21 M50``, ``G90 M21`` -> Modal group
    violation (yet on classic the M20/M21 takes effect); ``M21 G21 ...`` and ``M20 G21`` are
    fine."""
    from mirobot_async._core.acceptance import scan

    for line in ("G21 M21", "G20 M20", "M21 M3 S10", "M21 M5", "M21 M50", "G90 M21", "G0 M20"):
        found = scan(parse_line(line).text, "classic")
        assert found.error == "Modal group violation" and found.coordinate is not None, line
    for line in ("M21 G21 G90 G0 X1", "M20 G21", "M21 G90 G0 X3", "M3 S10", "M3 G91"):
        assert scan(parse_line(line).text, "classic").error is None, line


# ---- one validation: what check flags, send refuses (issue 15 item 3) ---------------------

WORDS = st.sampled_from(
    [
        "G0", "G00", "G1", "G4", "G20", "G21", "G28", "G90", "G91", "G0.5", "M20", "M21",
        "M3", "M4", "M16404", "M20.001", "X10", "X500", "X0000000030", "Y-40", "Z+5", "A400",
        "C.5", "D600", "F2000", "F0", "F-1", "P1", "S2000", "S500", "E65", "E-1", "R5", "T1",
        "I3", "N7", "X", "(c)", ";x", "?", "\u00e9",
    ]
)  # fmt: skip


@settings(max_examples=300)
@given(st.lists(WORDS, max_size=8), st.sampled_from(gcode.FIRMWARE_PROFILES))
def test_what_check_flags_validate_refuses(words: list[str], firmware: str) -> None:
    line = " ".join(words)
    problems = check_line(line, firmware=firmware)
    if problems:
        with pytest.raises(MirobotUsageError) as info:
            validate_line(line, firmware=firmware)
        for problem in problems:
            assert problem in str(info.value)
    else:
        assert validate_line(line, firmware=firmware).source == line


@pytest.mark.parametrize(
    "line",
    ["M3 S2000", "M4 E1001", "M21 G90 X500", "G0 X1" + "0" * 80, "G0 X1 T1", "G0 X0000000030"],
)
def test_validate_refuses_what_check_reports(line: str) -> None:
    assert check_line(line)
    with pytest.raises(MirobotUsageError, match="refused before sending"):
        validate_line(line)


def test_unknown_modes_check_only_what_the_line_states() -> None:
    """For a client on an arm in use: ``X500`` may be mm (M20) or degrees (M21)."""
    from mirobot_async._core.validation import ModalState

    assert check_line("G0 X500", state=ModalState.unknown()) == []
    assert check_line("M21 G90 G0 X500", state=ModalState.unknown()) == [
        "J1=500 is outside -100..160"
    ]
    assert check_line("M3 S2000", state=ModalState.unknown())  # PWM needs no mode
