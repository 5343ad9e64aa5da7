"""The client's verdict on every line against the emulator's pure firmware model.

Validation, mode tracking and the safety envelope must agree with the firmware about whether each
line is accepted and what it leaves behind: a line predicted as run that the firmware refuses
makes every line streamed behind it run from a position nobody predicted. Random lines of the
firmware's grammar (modal words in every order, feed rates and their absence after homing and
resets, refused words, arcs, dwells, program end) are driven through the client's prediction
(:func:`~mirobot_async._core.acceptance.line_fate`, the modes it tracks, ``mirobot check``'s
validation and the envelope's :func:`~mirobot_async._safety.prediction.predict`) and through
:class:`mirobot_emulator.firmware.Firmware` in process on both profiles, with and without
validation: after every line the verdict (``ok`` or an error) and the modes (M20/M21, G90/G91,
the motion code, units, feed rate, G93) must be the same.

``MIROBOT_TEST_SCALE`` scales the line count: CI runs it at 1 on its own (``.ci/run``): at least
:data:`LINES` lines; README's run (scale 0.3) drives 2,000, to stay quick.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from mirobot_async._core.acceptance import line_fate, modes_after_refusal, update_modes
from mirobot_async._core.line import parse_line
from mirobot_async._core.modal import HOMED, Chaining, MotionModes, modes_after
from mirobot_async._core.replies import ReplyKind, classify_line
from mirobot_async._core.validation import ModalState, line_problems
from mirobot_async._safety.envelope import Envelope
from mirobot_async._safety.prediction import MachineState, Prediction, predict
from mirobot_async.kinematics import DH_2021, DH_CLASSIC

Firmware = pytest.importorskip("mirobot_emulator.firmware").Firmware

LINES = 100_000
"""Lines driven at ``MIROBOT_TEST_SCALE=1`` (both profiles together)."""
PROGRAM = 50
"""Lines per example."""
SCALE = float(os.environ.get("MIROBOT_TEST_SCALE", "0.3"))
EXAMPLES = max(10, round(LINES * (SCALE if SCALE >= 1 else SCALE / 15) / PROGRAM / 2))
"""Examples per profile."""

WORDS = (
    # coordinate mode, distance, motion, units, feed mode, plane, dwell, program end
    *("M20", "M21", "M20", "M21", "G90", "G91", "G90", "G91"),
    *("G0", "G1", "G0", "G1", "G2", "G3", "G5", "G80", "G21", "G20", "G93", "G94", "G17"),
    *("G4", "M2", "M30", "M3", "M4", "M5", "M50", "M8", "M9", "G92", "G10", "G54"),
    # feed rates, outputs, dwell and arc words, line numbers, tool
    *("F0", "F100", "F2000", "F0.5", "F-5", "S100", "S0", "E50", "P0", "P0.01", "R5", "R40"),
    *("N5", "N99999999", "T1", "L2", "I5"),
    # axis words (small steps, and absolute targets)
    *("X1", "X-1.5", "Y2", "Z-1", "A3", "B-2", "C1", "D2", "X0", "Y0.5", "X200", "Z230"),
    *("X1", "Y-2", "Z1", "X-1"),
    # refused and odd forms
    *("Q1", "M20.5", "G1.5", "M021", "G01", "X", "M7", "G38"),
)
SPECIAL = ("$H", "%", "", "$X", "M21 G90 G0 X0 Y0 Z0 A0 B0 C0", "G4 P0")


@st.composite
def lines(draw: st.DrawFn) -> str:
    if draw(st.integers(0, 24)) == 0:
        return draw(st.sampled_from(SPECIAL))
    words = draw(st.lists(st.sampled_from(WORDS), min_size=1, max_size=5))
    return " ".join(words)


def _run(fw: object, line: str) -> list[str]:
    """Send one line, run the clock until it is answered and the arm rests; the lines printed."""
    fw.receive(line.encode() + b"\n")  # type: ignore[attr-defined]
    fw.advance(math.inf)  # type: ignore[attr-defined]
    while (due := fw.input_deadline) is not None:  # type: ignore[attr-defined]
        fw.advance(due - fw.now)  # type: ignore[attr-defined]
    fw.advance(math.inf)  # type: ignore[attr-defined]
    text = fw.read_output().decode("latin-1")  # type: ignore[attr-defined]
    return [r for r in text.replace("\r", "\n").split("\n") if r]


def _final(replies: list[str]) -> tuple[bool, str | None]:
    """(accepted, the error text) of a line's final reply."""
    for raw in reversed(replies):
        reply = classify_line(raw)
        if reply.kind is ReplyKind.ERROR:
            return False, reply.text
        if reply.ok:
            return True, None
    raise AssertionError(f"no final reply in {replies}")


def _firmware_modes(fw: object) -> MotionModes:
    m = fw._m.modal  # type: ignore[attr-defined]
    return MotionModes(
        m.cart_mode, m.distance == 91, m.motion, m.units == 20, m.feed, m.feed_mode == 93
    )


def _same_modes(client: MotionModes, firmware: MotionModes, where: str) -> None:
    for name in ("cartesian", "relative", "motion", "inches", "inverse_time"):
        assert getattr(client, name) == getattr(firmware, name), (where, name, client, firmware)
    assert client.feed is not None and firmware.feed is not None, (where, client)
    assert (client.feed == 0) == (firmware.feed == 0), (where, client, firmware)
    assert math.isclose(client.feed, firmware.feed, rel_tol=1e-9), (where, client, firmware)


@dataclass
class Counts:
    lines: int = 0
    unknown: int = 0
    envelope_passed: int = 0
    verdicts: dict[str, int] = field(default_factory=dict)


def _drive(profile: str, program: list[str], validate: bool, counts: Counts) -> None:
    fw = Firmware(profile, homing_seconds=0.0)
    fw.read_output()
    assert _final(_run(fw, "$H"))[0]
    modes = HOMED
    envelope = Envelope(dh=DH_CLASSIC if profile == "classic" else DH_2021)
    for number, line in enumerate(program, start=1):
        where = f"{profile} line {number} {line!r} after {program[: number - 1]!r}"
        counts.lines += 1
        if line == "%":
            fw.reset()
            fw.advance(math.inf)
            fw.read_output()
            modes = MotionModes()  # power-on modes, feed 200
            _same_modes(modes, _firmware_modes(fw), where)
            continue
        parsed = parse_line(line)
        fate = line_fate(parsed, modes, profile)
        if validate and line_problems(
            parsed, firmware=profile, state=ModalState.of(modes, Chaining())
        ):
            refused = "refused before sending"
            counts.verdicts[refused] = counts.verdicts.get(refused, 0) + 1
            _same_modes(modes, _firmware_modes(fw), where)  # nothing was sent
            continue
        prediction = None
        if not validate and parsed.kind == "gcode":
            q = tuple(float(v) for v in fw.joints)
            state = MachineState(
                modes=modes, joints=q[:6], rail=q[6], base_offset=(0.0, 0.0, 0.0),  # type: ignore[arg-type]
                gate_lift=30.0, firmware=profile,
            )  # fmt: skip
            prediction = predict(envelope, parsed, state)
        accepted, error = _final(_run(fw, line))
        key = "ok" if accepted else f"error: {error}"
        counts.verdicts[key] = counts.verdicts.get(key, 0) + 1
        if fate.accepted is None:  # the client could not know: the reply tells it
            counts.unknown += 1
            event(f"verdict unknown: {fate.why}")
            after = modes_after(parsed, modes)
            modes = after if accepted else modes_after_refusal(parsed, modes, profile, error)
        else:
            assert fate.accepted == accepted, (where, fate, error)
            assert not validate or accepted, (where, error)
            modes = update_modes(parsed, modes, profile)
        if isinstance(prediction, Prediction):
            counts.envelope_passed += 1
            assert accepted, (where, "the envelope let through a line the firmware refuses", error)
            assert prediction.state.modes == modes, (where, prediction.state.modes, modes)
        _same_modes(modes, _firmware_modes(fw), where)


@pytest.mark.timeout(900)  # 50,000 lines a profile at MIROBOT_TEST_SCALE=1: about 90 s
@pytest.mark.parametrize("profile", ["classic", "2021"])
def test_the_client_predicts_every_verdict_and_the_modes_left(profile: str) -> None:
    counts = Counts()

    @settings(
        max_examples=EXAMPLES,
        deadline=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )
    @given(
        program=st.lists(lines(), min_size=PROGRAM, max_size=PROGRAM),
        validate=st.booleans(),
    )
    def drive(program: list[str], validate: bool) -> None:
        _drive(profile, program, validate, counts)

    drive()
    assert counts.lines >= EXAMPLES * PROGRAM
    assert counts.unknown <= counts.lines // 50, counts  # (absolute arcs, I/J arcs: rare)
    assert counts.verdicts.get("ok", 0) > counts.lines // 10, counts
    print(f"{profile}: {counts}")
