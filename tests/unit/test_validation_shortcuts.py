"""The client judges a line once and skips work it can prove unneeded; these tests prove each
shortcut gives the full judgement's answer on many lines:

- :func:`may_differ_by_profile` is False only when both profiles find the same problems
  (the scheduler then does not judge the line twice to learn whether the profile matters);
- :func:`_follow` (what :func:`first_restart` runs) leaves the modal state and chaining exactly
  as the full check does, with the same chaining problem;
- the facts a :class:`ParsedLine` derives at parse time are those of its words;
- a G-code line's verdict, remembered by its text and the modes it is judged from, is the one
  judging it afresh gives.
"""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from mirobot_async._core import acceptance
from mirobot_async._core.line import AXIS_LETTERS, CodeWord, _parse_text, parse_line
from mirobot_async._core.modal import Chaining
from mirobot_async._core.validation import (
    ModalState,
    _check_gcode,
    _follow,
    _judge_gcode,
    _problems,
    line_problems,
    may_differ_by_profile,
)

_WORDS = (
    "M20", "M21", "M21", "M20.5", "M3", "M4", "M5", "M50", "M2", "M30", "M16404",
    "G0", "G00", "G1", "G01", "G2", "G3", "G5", "G4", "G20", "G21", "G90", "G91", "G80", "G1.0",
    "X10", "X-300", "X0000000030", "Y20", "Z-5", "A30", "B-10", "C5", "D10", "D-600", "D2000",
    "R5", "R-1", "F2000", "F0", "P1", "S500", "S1001", "E40", "Q1", "X5", "Y1",
)  # fmt: skip
_SPECIAL = (
    "$H", "$HH", "$H1", "$HE", "$M", "$X", "$$", "$41=10", "$29=1", "$RST=$", "$N0=G0",
    "$J=X10", "$99", "", "(comment)", "G0 X1 (open", "G0X1?", "g1 x1 ; rest", "X1 X2",
    "G0 G1 X1", "G21 M21 X1", "M21 M3 X1",
    "M20 G90 G1 X200 Y0 Z230 A0 B0 C0", "G1 X200 Y0 Z230 A0 B0 C0", "G0 X200 Y0 Z230 A0 B0 C0",
)  # fmt: skip

lines = st.one_of(
    st.lists(st.sampled_from(_WORDS), min_size=1, max_size=6).map(" ".join),
    st.sampled_from(_SPECIAL),
)
modes = st.sampled_from((None, False, True))
motions = st.sampled_from((None, 0, 1, 2, 3, 5))
joints = st.frozensets(st.sampled_from("XYZABCD"))
chains = st.builds(
    Chaining,
    moving=joints,
    stale=joints,
    resync=st.sampled_from((None, "M21 G90 G0 X1")),
    refused=st.booleans(),
)
states = st.builds(ModalState, modes, modes, motions, chains)


def _copy(state: ModalState) -> ModalState:
    return state.copy()


@settings(max_examples=1000, deadline=None)
@given(line=lines, state=states)
def test_a_line_the_profiles_may_not_judge_alike_is_always_flagged(
    line: str, state: ModalState
) -> None:
    parsed = parse_line(line)
    verdicts = [
        line_problems(parsed, firmware=profile, state=_copy(state))
        for profile in ("classic", "2021")
    ]
    if verdicts[0] != verdicts[1]:
        assert may_differ_by_profile(parsed, _copy(state)), verdicts


@settings(max_examples=300, deadline=None)
@given(
    program=st.lists(lines, min_size=1, max_size=8),
    state=states,
    profile=st.sampled_from(("classic", "2021")),
)
def test_following_a_program_for_its_chaining_matches_the_full_check(
    program: list[str], state: ModalState, profile: str
) -> None:
    full, follow = _copy(state), _copy(state)
    for line in program:
        parsed = parse_line(line)
        expected = _problems(parsed, profile, full)[1]
        assert _follow(parsed, profile, follow) == expected
        assert (follow.cartesian, follow.relative, follow.motion, follow.chain) == (
            full.cartesian,
            full.relative,
            full.motion,
            full.chain,
        )


def _first(codes: tuple[CodeWord, ...], letter: str, choices: set[int]) -> int | None:
    return next((w.code for w in codes if w.letter == letter and w.code in choices), None)


@settings(max_examples=300, deadline=None)
@given(line=lines)
def test_the_facts_derived_at_parse_time_are_those_of_the_words(line: str) -> None:
    parsed = parse_line(line)
    codes = tuple(w for w in parsed.words if isinstance(w, CodeWord))
    values = [w for w in parsed.words if not isinstance(w, CodeWord)]
    first: dict[str, float] = {}
    for w in values:
        first.setdefault(w.letter, w.value)
    letters = [w.letter for w in values]
    assert parsed.codes == codes
    assert parsed.g_codes == tuple(w.code for w in codes if w.letter == "G")
    assert parsed.m_codes == tuple(w.code for w in codes if w.letter == "M")
    assert dict(parsed.values) == first
    assert set(parsed.repeated) == {x for x in letters if letters.count(x) > 1}
    assert dict(parsed.axis_words) == {k: first[k] for k in AXIS_LETTERS if k in first}
    assert parsed.motion == _first(codes, "G", {0, 1, 2, 3, 5, 80})
    assert parsed.distance == _first(codes, "G", {90, 91})
    assert parsed.units == _first(codes, "G", {20, 21})
    # the firmware keeps the last M20/M21 of a line (oracle rule, the emulator: 'M20 X1 M21')
    assert parsed.coordinate_mode == _first(codes[::-1], "M", {20, 21})
    assert parsed.has_odd_numbers == any(
        w.lossy or (isinstance(w, CodeWord) and not w.canonical) for w in parsed.words
    )


# The joints a line reads, sets and moves, written plainly over every frame and distance mode
# the line may run in (the module computes them with shortcuts for the known cases).
_ALL = frozenset("XYZABCD")
_ARM = frozenset("XYZABC")


def _frames(mode: bool | None) -> tuple[bool, ...]:
    return (True, False) if mode is None else (mode,)


def _plain_reads(axes: frozenset[str], cartesian: bool | None, relative: bool | None,
                 motion: int | None, firmware: str | None) -> frozenset[str]:  # fmt: skip
    read: set[str] = set()
    for frame in _frames(cartesian):
        for adds in _frames(relative):
            if adds:
                read |= _ALL
            elif not frame:
                read |= _ALL - axes
            else:
                read |= {"D"} - axes
                if axes & _ARM != _ARM or (firmware != "classic" and motion != 0):
                    read |= _ARM
    return frozenset(read) if axes else frozenset()


@settings(max_examples=600, deadline=None)
@given(
    line=lines,
    cartesian=modes,
    relative=modes,
    motion=motions,
    firmware=st.sampled_from((None, "classic", "2021")),
)
def test_the_joints_a_line_reads_and_moves_are_those_of_every_mode_it_may_run_in(
    line: str, cartesian: bool | None, relative: bool | None, motion: int | None,
    firmware: str | None,
) -> None:  # fmt: skip
    from mirobot_async._core import modal

    parsed = parse_line(line)
    if parsed.kind != "gcode" or parsed.syntax_error is not None:
        return
    axes = frozenset(parsed.axis_words)
    assert modal._reads(parsed, cartesian, relative, motion, firmware) == _plain_reads(
        axes, cartesian, relative, motion, firmware
    )
    moved: set[str] = set()
    for frame in _frames(cartesian):
        moved |= ({"D"} & axes) | (_ARM if axes & _ARM else set()) if frame else axes
    assert modal._moves(parsed, cartesian) == (frozenset(moved) if axes else frozenset())
    written: frozenset[str] = frozenset()
    if relative is False and cartesian is not None:
        arm = _ARM if axes >= _ARM else frozenset()
        written = axes if not cartesian else frozenset(({"D"} & axes) | arm)
    assert modal._writes(parsed, cartesian, relative) == written


numbers = st.from_regex(r"\A[+-]?[0-9]{0,11}(\.[0-9]{0,11})?\Z").filter(
    lambda text: any(char.isdigit() for char in text)
)


@settings(max_examples=600, deadline=None)
@given(letter=st.sampled_from("XYZABCDFPSRGM"), number=numbers)
def test_a_word_in_a_line_is_read_as_read_number_reads_it(letter: str, number: str) -> None:
    from mirobot_async._core.line import read_number

    (word,) = parse_line(f"{letter}{number}").words
    expected = read_number(number, 0)
    assert expected is not None
    assert (word.letter, word.text, word.lossy) == (letter, number, expected.lossy)
    assert word.value == expected.value or (
        word.value != word.value and expected.value != expected.value
    )
    assert str(word.value) == str(expected.value)  # the sign of a zero too


@settings(max_examples=1000, deadline=None)
@given(line=lines, state=states, profile=st.sampled_from(("classic", "2021")))
def test_a_remembered_gcode_verdict_is_the_fresh_one(
    line: str, state: ModalState, profile: str
) -> None:
    parsed = parse_line(line)
    if parsed.kind != "gcode":
        return
    fresh, fresh_problems = _copy(state), list[str]()
    _judge_gcode(parsed, profile, fresh, fresh_problems)
    for _ in range(2):  # computed, then remembered
        remembered, problems = _copy(state), list[str]()
        _check_gcode(parsed, profile, remembered, problems)
        assert problems == fresh_problems
        assert remembered == fresh


@settings(max_examples=500, deadline=None)
@given(line=lines)
def test_a_remembered_parse_is_the_fresh_one(line: str) -> None:
    fresh = _parse_text.__wrapped__(line)
    for _ in range(2):  # computed, then remembered
        assert parse_line(line) == fresh


@settings(max_examples=500, deadline=None)
@given(line=lines, firmware=st.sampled_from(("classic", "2021")))
def test_a_remembered_scan_is_the_fresh_one(line: str, firmware: str) -> None:
    text = parse_line(line).text
    fresh = acceptance.scan.__wrapped__(text, firmware)
    for _ in range(2):  # computed, then remembered
        assert acceptance.scan(text, firmware) == fresh
