"""The envelope's predictor against the emulator's pure firmware model (issue 13, "Also").

For random lines in the firmware's grammar (odd number forms, modal words, units, base offset
settings, Cartesian paths that need a wrist snap), either the envelope refuses the line, or the
arm ends where the predictor said (up to whole motor steps) and, sampled while it moves, the
tool point never leaves the envelope's box. Runs :class:`mirobot_emulator.firmware.Firmware`
in-process on an explicit clock (no pty, no sleeping).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, event, example, given, settings
from hypothesis import strategies as st

from mirobot_async._safety.envelope import Envelope
from mirobot_async._safety.prediction import MachineState, Prediction, predict
from mirobot_async.kinematics import forward

Firmware = pytest.importorskip("mirobot_emulator.firmware").Firmware
default_settings = pytest.importorskip("mirobot_emulator.settings").default_settings

BOX = {"x": (100.0, 300.0), "y": (-160.0, 160.0), "z": (150.0, 320.0)}
TOOL = (0.0, 60.0, 0.0)
"""A tool sticking out sideways: a wrist snap swings it through a wide arc."""
ENVELOPE = Envelope(x=BOX["x"], y=BOX["y"], z=BOX["z"], tool=TOOL)
_SETTINGS = default_settings("2021")
STEP = np.array([1.0 / _SETTINGS[100 + k] + 0.01 for k in (4, 5, 6, 0, 1, 2)])
"""Joint tolerance (deg), J1..J6: one whole motor step of that axis ($104, $105, $106, $100..$102;
J6 on 2021 is 1/11.356 = 0.088 deg) plus rounding. The firmware adds a relative move to its
parser's position; the client knows only the machine's, in whole steps, from the status."""
RAIL_STEP = 1.0 / _SETTINGS[103] + 0.01
BOX_SLACK = 1.5
"""Tool-point tolerance (mm) while moving: the check samples the path every 2 mm."""
DROPPED = ("Soft limit", "GOAL OUT OF WORKSPACE", "angle out of limit", "Locked status")


def _number(value: float) -> st.SearchStrategy[str]:
    """``value`` written in one of the forms the firmware reads (some of them lossy)."""
    plain = f"{value:.3f}".rstrip("0").rstrip(".")
    forms = [plain, "+" + plain if value >= 0 else plain, f"{value:09.3f}", f"{value:.7f}"]
    if abs(value) >= 1:
        forms.append(f"{round(value):010d}")  # 10 digits: the firmware keeps the first 8
    if 0 < abs(value) < 1:
        forms.append(plain.replace("0.", ".", 1))
    return st.sampled_from(forms)


@st.composite
def lines(draw: st.DrawFn) -> str:
    kind = draw(st.sampled_from(["joint", "cart", "cart", "setting", "modal", "flip"]))
    if kind == "flip":  # a legal joint move that leaves the wrist off the firmware's IK branch
        a = draw(st.sampled_from([30, 60, 90, -45]))
        b = draw(st.sampled_from([-100, -130, -160]))
        return f"M21 G90 G0 G21 X10 Y10 Z10 A{a} B{b} C{draw(st.sampled_from([0, 45, -90]))}"
    if kind == "setting":
        number = draw(st.sampled_from([41, 42, 43, 130, 46, 49]))
        value = draw(st.sampled_from([-20.0, 0.0, 5.0, 15.0, 30.0]))
        form = draw(st.sampled_from(["${n}={v}", "$0{n}={v}"]))
        return form.format(n=number, v=f"{value:g}")
    words: list[str] = []
    modal = {
        "coord": st.sampled_from(["M21", "M021", "M21.001"] if kind == "joint" else ["M20"]),
        "distance": st.sampled_from(["G90", "G91", "G090"]),
        "motion": st.sampled_from(["G0", "G00", "G1", "G01", "G0.001"]),
        "units": st.sampled_from(["G21", "G21", "G21", "G20"]),
    }
    for name in draw(st.permutations(list(modal))):
        if draw(st.integers(0, 4)) > 0:
            words.append(draw(modal[name]))
    if kind == "modal":
        return " ".join(words)
    letters = draw(st.lists(st.sampled_from("XYZABC"), min_size=1, max_size=3, unique=True))
    for letter in letters:
        if kind == "joint" and letter in "AB" and draw(st.integers(0, 3)) == 0:
            value = draw(st.sampled_from([-150.0, -110.0, 120.0]))  # the wrist off the IK branch
        elif kind == "joint":
            value = draw(st.floats(-40, 40))
        elif letter in "XYZ" and draw(st.booleans()):
            value = {"X": 200.0, "Y": 0.0, "Z": 220.0}[letter] + draw(st.floats(-80, 80))
        elif letter in "XYZ":
            value = draw(st.sampled_from([1.0, -2.0, 5.0]))  # a short relative step
        else:
            value = draw(st.floats(-30, 30))
        words.append(letter + draw(_number(round(value, 3))))
    words.append("F" + draw(st.sampled_from(["2000", "1500.0", "03000"])))
    return " ".join(words)


def _run(fw: object, line: str, box_check: bool) -> list[str]:
    """Send one line, run the clock until the arm rests; check the box while it moves."""
    fw.receive(line.encode() + b"\n")  # type: ignore[attr-defined]
    out: list[str] = []
    for _ in range(20000):
        fw.advance(0.02)  # type: ignore[attr-defined]
        out += fw.read_output().decode("latin-1").split("\r\n")  # type: ignore[attr-defined]
        if box_check:
            q = tuple(fw.joints[:6])  # type: ignore[attr-defined]
            x, y, z = forward(q, ENVELOPE.dh, TOOL)[:3]
            for (lo, hi), v, name in zip(BOX.values(), (x, y, z), "xyz", strict=True):
                assert lo - BOX_SLACK <= v <= hi + BOX_SLACK, (line, name, v)
        done = any(r == "ok" or r.startswith(("error", "Error")) for r in out)
        if done and fw.state == "Idle":  # type: ignore[attr-defined]
            return [r for r in out if r]
    raise AssertionError(f"{line!r} did not finish: {out}")


def _boot() -> tuple[object, MachineState]:
    fw = Firmware("2021", homing_seconds=0.0)
    fw.settings[47] = TOOL[1]  # the arm's tool offset is the envelope's
    fw.read_output()
    fw.receive(b"$H\n")
    for _ in range(1000):
        fw.advance(0.05)
        if fw.state == "Idle":
            break
    fw.read_output()
    q = tuple(float(v) for v in fw.joints[:6])
    offset = (fw.settings[41], fw.settings[42], fw.settings[43])
    state = MachineState(
        joints=q,  # type: ignore[arg-type]
        rail=float(fw.joints[6]),
        base_offset=offset,
        gate_lift=fw.settings[49],
        firmware="2021",
    )
    return fw, state


@settings(
    max_examples=80,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(st.lists(lines(), min_size=1, max_size=6))
@example(["C25.5 F2000", "G91 C19 F2000"])  # J6 moves from the parser's 25.5, not the arm's 25.537
def test_refused_or_predicted_exactly(program: list[str]) -> None:
    fw, state = _boot()
    for line in program:
        result = predict(ENVELOPE, line, state)
        if not isinstance(result, Prediction):
            event("refused")
            continue
        replies = _run(fw, line, box_check=result.moves)
        rejected = any(r.startswith(("error", "Error")) for r in replies)
        dropped = any(r.startswith(DROPPED) for r in replies)
        actual = tuple(float(v) for v in fw.joints)  # type: ignore[attr-defined]
        if rejected or dropped:
            event("firmware refused")
            # nothing moved; a dropped move's modal words took effect, a rejected line's not
            assert state.joints is not None
            assert np.allclose(actual[:6], state.joints, atol=STEP), (line, replies)
            if dropped:
                state = replace(state, modes=result.state.modes)
            continue
        event("moved" if result.moves else "still")
        if result.snap is not None:
            event("wrist snap")
        after = result.state
        if after.joints is None:  # a wrist snap that may turn J4/J6 either way: the pose counts
            assert after.pose is not None and result.model_joints is not None, line
            pose = forward(actual[:6], ENVELOPE.dh, ENVELOPE.tool)
            assert np.allclose(pose[:3], after.pose[:3], atol=0.2), (line, pose, after.pose)
        else:
            assert np.allclose(actual[:6], after.joints, atol=STEP), (line, actual, after.joints)
        if after.rail is not None:
            assert abs(actual[6] - after.rail) <= RAIL_STEP, line
        if after.base_offset is not None:
            want = (fw.settings[41], fw.settings[42], fw.settings[43])  # type: ignore[attr-defined]
            assert after.base_offset == want, line
        # the next line starts from where the arm is (whole steps), as the client learns it
        state = replace(after, joints=actual[:6])  # type: ignore[arg-type]
