"""The chaining rule (:class:`mirobot_async._core.modal.Chaining`): a line whose ``M20``/``M21``
would make the firmware restart it from where the moving arm is is reported; every other program
ends where the same lines sent one at a time (each after the arm stopped) end.

The oracle's measured cases (classic, streamed vs stepped) are checked against the rule, and the
rule's soundness against the emulator's pure firmware model (which models the restart): random
programs the rule passes end at the same motor steps streamed and stepped.
"""

from __future__ import annotations

import copy
import math

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from mirobot_emulator.firmware import Firmware

from mirobot_async._core.line import parse_line
from mirobot_async._core.modal import Chaining, MotionModes
from mirobot_async._core.stream_verdict import first_restart, judge_stream
from mirobot_async._core.validation import (
    ModalState,
    check_program,
    validate_line,
)
from mirobot_async.kinematics import DH_2021, DH_CLASSIC, forward

# Oracle (classic 20191228_2), streamed vs stepped, J1 (or the named joint) in degrees: see the
# Chaining docstring. True: the streamed program ends elsewhere.
ORACLE_CASES: list[tuple[list[str], bool]] = [
    (["M21 G91 G0 X1 F2000"] * 4, True),  # 1.005 vs 4.019
    (["M21 G91 G0 X1 F2000", "G91 G0 X1", "G91 X1", "X1"], False),  # 4.001 both
    (["M21 G90 G0 X10", "M21", "G91 X1"], True),  # 1.005 vs 10.999
    (["M20 G91 G0 X5"] * 3, True),  # X 207.005 vs 217.006
    (["M20 G91 G1 X5 F2000", "M20 G91 G1 X5", "M20 G91 G1 Z-5"], True),
    (["M21 G90 G0 X10 Y5 Z0 A0 B0 C0", "M21 G90 G0 X20 Y10 Z5 A0 B0 C0"], False),
    (["M21 G90 G0 Y20", "M21 G90 G0 X10"], True),  # J2 0 vs 20.004
    (["M21 G90 G0 X10", "M21 G90 G0 X20"], False),
    (
        [
            "M20 G90 G0 X180 Y20 Z160 A0 B0 C0",
            "M20 G90 G0 X190 Y-20 Z150 A0 B0 C0",
            "M20 G90 G1 X200 Y0 Z170 A0 B0 C0 F2000",
        ],
        False,
    ),
    (["M20 G90 G0 X180 Y20 Z160 A0 B0 C0", "M20 G90 G0 Z120"], True),
    (["M21 G90 G0 D20", "M21 G90 G0 X10"], True),  # rail 0 vs 20
    (["M21 G91 X1 F2000", "G90 X5", "G91 X1", "G91 X1"], False),
    (["M21 G91 X1 F2000", "G4 P0", "M21 G91 X1"], False),  # 2.01 both
    (["M21 G90 G0 X30", "M20", "G4 P0", "G91 X1"], True),  # ~0 vs 29.861
    (["M20 G90 G0 X180 Y20 Z160 A0 B0 C0", "G4 P0", "M21", "G91 X1"], False),
    (["M21 G90 G0 A30 C-30", "M20 G90 G0 X202 Y0 Z181 A0 B0 C0"], False),
    (["M21 G91 G0 X1 G21", "G91 G0 X1 G21", "G21 G91 G0 X1 F100"], False),
    (["M21 G90 G0 X5", "M21 G91 G0 Y1"], True),  # J1 0 vs 5.006: omitted axes stay
    (["M20 G90 G0 X180 Y20 Z160 A0 B0 C0", "M21 G91 G0 D5"], True),  # all back to 0
]


@pytest.mark.parametrize(("program", "differs"), ORACLE_CASES)
def test_the_firmwares_measured_cases(program: list[str], differs: bool) -> None:
    assert bool(check_program(program, firmware="classic")) == differs


def test_the_report_names_the_joints_and_the_fix() -> None:
    found = check_program(["M21 G90 G0 Y20", "M21 G90 G0 X10"], firmware="classic")
    assert len(found) == 1
    number, text = found[0]
    assert number == 2
    assert "J2 may still be moving" in text
    assert "State M21 once at the top" in text and "G4 P0" in text


def test_a_2021_cartesian_path_starts_from_the_parser() -> None:
    """On 2021 an ``M20`` ``G1`` is cut from the parser's pose: a whole absolute pose is not
    enough (on classic it is one joint-space block to the IK of the target)."""
    program = ["M21 G90 G0 X10", "M20 G90 G1 X200 Y0 Z170 A0 B0 C0 F2000"]
    assert check_program(program, firmware="classic") == []
    assert len(check_program(program, firmware="2021")) == 1


def test_first_restart_needs_both_profiles_when_unknown() -> None:
    program = ["M21 G90 G0 X10", "M20 G90 G1 X200 Y0 Z170 A0 B0 C0 F2000"]
    assert first_restart(program, firmware=None, state=ModalState()) is None
    assert first_restart(program, firmware="2021", state=ModalState()) is not None
    found = first_restart(["M21 G91 X1"] * 2, firmware=None, state=ModalState())
    assert found is not None and found[:2] == (2, "M21 G91 X1")


_ANY_LINE = st.sampled_from(
    (
        "M21 G90 G0 X10",
        "M21 G91 X1",
        "G91 X1",
        "G90 Y5",
        "M20 G90 G1 X200 Y0 Z170 A0 B0 C0 F2000",
        "M20 G91 G0 X5",
        "M20 G90 G0 Z120",
        "G2 X1 Y1 I1",
        "M21 G90 G0 D20",
        "G4 P0",
        "M20",
        "M21",
        "$H",
        "$HX",
        "M3 S1000",
    )
)


@given(st.lists(_ANY_LINE, max_size=8), st.booleans(), st.sampled_from((None, "classic", "2021")))
def test_a_stream_judged_whole_says_what_each_line_judged_alone_says(
    lines: list[str], moving: bool, firmware: str | None
) -> None:
    """One walk of a stream (when the profile is known, or no line may differ by profile):
    the restart :func:`first_restart` finds on each profile, and for every line it says needs
    no judging again, :func:`validate_line` from that state finds nothing."""
    state = ModalState(chain=Chaining(moving=frozenset("XYZ")) if moving else Chaining())
    parsed = [parse_line(line) for line in lines]
    profiles = ("classic", "2021") if firmware is None else (firmware,)
    each = [first_restart(parsed, firmware=p, state=state) for p in profiles]
    verdict = judge_stream(parsed, firmware=firmware, state=state)
    assert verdict.profiles_disagree == ((each[0] is None) != (each[-1] is None))
    if not verdict.profiles_disagree:
        assert verdict.restart == each[0]
    assert len(verdict.judged_from) <= len(parsed)
    for line, judged_from in zip(parsed, verdict.judged_from, strict=False):
        if judged_from is not None:
            for profile in profiles:
                validate_line(line, firmware=profile, state=copy.copy(judged_from))


def test_a_refused_line_leaves_its_joints_stale_until_a_mode_word_at_rest() -> None:
    modes = MotionModes()
    chain = Chaining().after_refusal(parse_line("M21 G91 G0 X10"))
    assert chain.needs_restart(parse_line("G91 G0 X1"), modes)
    problem = chain.problem(parse_line("G91 G0 X1"), modes)
    assert problem is not None and "refused line" in problem
    restated = chain.after(parse_line("M21"), modes)  # nothing moving: the restart is exact
    assert restated.problem(parse_line("G91 G0 X1"), modes) is None


# ---- soundness against the emulator's firmware model --------------------------------------

_ANGLE = st.integers(-8, 8)
_STEP = st.sampled_from((-4, -3, -2, -1, 1, 2, 3, 4))


@st.composite
def _line(draw: st.DrawFn, profile: str) -> tuple[bool, str]:
    cartesian, relative = draw(st.booleans()), draw(st.booleans())
    motion = draw(st.sampled_from(("G0", "G1 F2000")))
    if not cartesian:
        axes = sorted(draw(st.lists(st.sampled_from("XYZD"), min_size=1, max_size=3, unique=True)))
        words = " ".join(f"{a}{draw(_STEP if relative else _ANGLE)}" for a in axes)
    elif relative:
        axes = sorted(draw(st.lists(st.sampled_from("XYZ"), min_size=1, max_size=3, unique=True)))
        words = " ".join(f"{a}{draw(_STEP) * 2}" for a in axes)
    else:
        joints = (draw(_ANGLE), draw(_ANGLE), draw(_ANGLE), 0.0, 0.0, 0.0)
        pose = forward(joints, DH_2021 if profile == "2021" else DH_CLASSIC)
        letters = "XYZABC" if draw(st.integers(0, 3)) else draw(st.sampled_from(("XY", "Z")))
        words = " ".join(f"{a}{v:.3f}" for a, v in zip("XYZABC", pose, strict=True) if a in letters)
    return cartesian, f"{'G91' if relative else 'G90'} {motion} {words}"


@st.composite
def _program(draw: st.DrawFn, profile: str) -> list[str]:
    lines: list[str] = []
    mode: bool | None = None
    repeat = draw(st.booleans())
    for _ in range(draw(st.integers(2, 5))):
        kind = draw(st.integers(0, 7))
        if lines and kind == 0:
            lines.append("G4 P0")
        elif lines and kind == 1:
            lines.append(draw(st.sampled_from(("M20", "M21"))))
            mode = lines[-1] == "M20"
            continue
        cartesian, body = draw(_line(profile))
        stated = repeat or mode is not cartesian
        lines.append(f"{'M20' if cartesian else 'M21'} {body}" if stated else body)
        mode = cartesian
    return lines


def _run(profile: str, program: list[str], streamed: bool) -> tuple[int, ...] | None:
    """Where the model's arm ends (motor steps), or None if a line failed on the way."""
    fw = Firmware(profile)
    fw.read_output()
    fw.receive(b"M50\n$X\n" if profile == "classic" else b"M50\n")
    _finish(fw)
    if fw.read_output().count(b"rror"):
        return None
    if streamed:
        data = "".join(line + "\n" for line in program).encode()
        fw.receive(data)  # all within the receive buffer: parsed while the arm moves
    else:
        for line in program:
            fw.receive(line.encode() + b"\n")
            _finish(fw)
    _finish(fw)
    output = fw.read_output()
    if b"rror" in output or b"LIMIT" in output.upper() or b"out of" in output:
        return None
    return tuple(round(q * 1000) for q in fw.joints)


def _finish(fw: Firmware) -> None:
    for _ in range(100_000):
        deadline = fw.next_deadline()
        if deadline is None:
            return
        fw.advance(max(deadline - fw.now, 1e-4))
    raise AssertionError("the model never came to rest")


@pytest.mark.parametrize("profile", ["classic", "2021"])
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_programs_the_rule_passes_end_where_stepped_ones_do(
    profile: str, data: st.DataObject
) -> None:
    program = data.draw(_program(profile))
    if sum(len(line) + 1 for line in program) > 120:
        return  # a single burst must fit the receive buffer
    reported = bool(check_program(program, firmware=profile))
    streamed, stepped = _run(profile, program, True), _run(profile, program, False)
    if streamed is None or stepped is None:
        event("a line failed")
        return
    same = all(math.isclose(a, b, abs_tol=60) for a, b in zip(streamed, stepped, strict=True))
    event(f"reported={reported} same={same}")
    if not reported:
        assert same, f"{program}: streamed {streamed} vs stepped {stepped}"
