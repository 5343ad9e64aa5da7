"""The default-deny predictor: one regression per envelope bypass of issue 13 (items 1-6) and
the bounded sampling of issue 17 (item 1), each against the emulator's pure firmware model
where the arm's behaviour matters (in-process, explicit clock)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from envelope_lines import check_envelope_line

from mirobot_async._core.modal import HOMED, MotionModes
from mirobot_async._safety.envelope import Envelope
from mirobot_async._safety.prediction import EnvelopeRefusal, MachineState, Prediction, predict
from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import DH_2021, forward, forward_many

Firmware = pytest.importorskip("mirobot_emulator.firmware").Firmware

HOME = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
KNOWN = MachineState(joints=HOME, rail=0.0, base_offset=(0.0, 0.0, 0.0), firmware="2021")


def homed(**settings: float) -> object:
    """A 2021 firmware model, homed (joints at 0), with ``settings`` written first."""
    fw = Firmware("2021", homing_seconds=0.0)
    for number, value in settings.items():
        fw.settings[int(number.lstrip("s"))] = value
    run(fw, "$H")
    return fw


def run(fw: object, line: str, *, watch: Envelope | None = None) -> tuple[list[str], float]:
    """Send ``line``, run the clock until the arm rests; the lowest tool z seen on the way."""
    fw.receive(line.encode() + b"\n")  # type: ignore[attr-defined]
    out: list[str] = []
    lowest = float("inf")
    for _ in range(50000):
        fw.advance(0.005)  # type: ignore[attr-defined]
        out += [r for r in fw.read_output().decode().split("\r\n") if r]  # type: ignore[attr-defined]
        if watch is not None:
            q = tuple(fw.joints[:6])  # type: ignore[attr-defined]
            lowest = min(lowest, forward(q, watch.dh, watch.tool)[2])
        final = any(r.endswith("ok") or r.startswith(("error", "Error")) for r in out)
        if final and fw.state == "Idle":  # type: ignore[attr-defined]
            return out, lowest
    raise AssertionError(f"{line!r} did not finish: {out}")


def refused(result: Prediction | EnvelopeRefusal, *words: str) -> str:
    assert isinstance(result, EnvelopeRefusal), result
    for word in words:
        assert word in result.reason, result.reason
    return result.reason


def joints_of(fw: object) -> np.ndarray:
    return np.asarray(fw.joints[:6])  # type: ignore[attr-defined]


# ---- item 1: base offset -----------------------------------------------------------------


def test_base_offset_is_added_to_absolute_cartesian_targets() -> None:
    env = Envelope(x=(None, 230))
    line = "M20 G90 G0 X200 Y0 Z200 A0 B0 C0"
    ok = predict(env, line, KNOWN)
    assert isinstance(ok, Prediction) and ok.state.pose is not None
    # $41=40 does not move, but from then on X200 means x = 240: outside
    setting = predict(env, "$41=40", KNOWN)
    assert isinstance(setting, Prediction) and not setting.moves
    assert setting.state.base_offset == (40.0, 0.0, 0.0)
    refused(predict(env, line, setting.state), "maximum x=230")
    # and the firmware model agrees on where X200 goes with the offset
    fw = homed(s41=40.0)
    run(fw, "M20 G90 G0 X200 Y0 Z200 A0 B0 C0")
    x = forward(tuple(joints_of(fw)), DH_2021)[0]
    assert x == pytest.approx(240.0, abs=0.1)
    wide = Envelope()
    after = predict(wide, line, setting.state)
    assert isinstance(after, Prediction) and after.state.joints is not None
    assert np.allclose(joints_of(fw), after.state.joints, atol=0.05)


def test_unknown_base_offset_refuses_absolute_cartesian_moves() -> None:
    state = MachineState(joints=HOME, base_offset=None, firmware="2021")
    refused(predict(Envelope(), "M20 G90 G0 X200 Y0 Z200", state), "base offset", "$41")
    relative = predict(Envelope(), "M20 G91 G0 X5", state)  # increments need no offset
    assert isinstance(relative, Prediction)


# ---- item 2: homing variants -------------------------------------------------------------


@pytest.mark.parametrize("line", ["$H", "$HH", "$H0", "$H7", "$H8", "$HX", "$HE"])
def test_every_homing_variant_moves_and_forgets_the_position(line: str) -> None:
    got = predict(Envelope(), line, KNOWN)
    assert isinstance(got, Prediction) and got.moves
    assert got.state.joints is None and got.state.modes == HOMED


def test_h8_homes_the_firmware_model() -> None:
    fw = homed()
    run(fw, "M21 G90 G0 X30")
    assert joints_of(fw)[0] == pytest.approx(30, abs=0.05)
    run(fw, "$H8")
    assert joints_of(fw)[0] == pytest.approx(0, abs=0.05)


# ---- item 3: units ------------------------------------------------------------------------


def test_units_unknown_at_connect_refuse_moves_until_stated() -> None:
    state = MachineState(MotionModes.unknown(), HOME, None, 0.0, (0.0, 0.0, 0.0), None, "2021")
    refused(predict(Envelope(), "M21 G90 G0 X10", state), "units")
    stated = predict(Envelope(), "G21", state)
    assert isinstance(stated, Prediction) and stated.state.modes.inches is False
    assert isinstance(predict(Envelope(), "M21 G90 G0 X10", stated.state), Prediction)


def test_inches_scale_every_axis_word_as_the_firmware_does() -> None:
    env = Envelope(joints={1: (-50, 50)})
    inches = MachineState(MotionModes(inches=True), HOME, None, 0.0, (0.0, 0.0, 0.0))
    got = predict(env, "M21 G90 G0 X1", inches)
    assert isinstance(got, Prediction) and got.state.joints is not None
    assert got.state.joints[0] == pytest.approx(25.4)
    refused(predict(env, "M21 G90 G0 X2", inches), "J1 range")  # 50.8 deg
    fw = homed()
    run(fw, "G20")
    run(fw, "M21 G90 G0 X1")
    assert joints_of(fw)[0] == pytest.approx(25.4, abs=0.05)


# ---- items 4 and 5: numbers and M numbers as the firmware reads them ----------------------


def test_numbers_with_more_than_eight_digits_are_refused() -> None:
    reason = refused(predict(Envelope(), "M21 G90 G0 X0000000030", KNOWN), "reads it as 0")
    assert "X0000000030" in reason
    fw = homed()
    run(fw, "M21 G90 G0 X0000000030")
    assert joints_of(fw)[0] == pytest.approx(0, abs=0.05)  # not 30


@pytest.mark.parametrize("word", ["M20.001", "M16404", "M020.0001", "G0.001", "G00000000001"])
def test_odd_command_numbers_are_refused(word: str) -> None:
    refused(predict(Envelope(), f"{word} G90 X200 Y0 Z200", KNOWN), word)


def test_m16404_is_m20_for_the_firmware_model() -> None:
    fw = homed()
    out, _ = run(fw, "M16404")
    assert any("Cartesian" in r for r in out), out


# ---- item 6: the wrist snap before a Cartesian path -----------------------------------------

FLIPPED = (20.0, 5.0, 20.0, 60.0, -160.0, -45.0)
"""A legal joint position whose wrist is not on the firmware's IK branch (|J5| > 90)."""
TOOL = (0.0, 60.0, 0.0)


def test_wrist_snap_is_predicted_and_checked() -> None:
    start_z = forward(FLIPPED, DH_2021, TOOL)[2]
    env = Envelope(z=(start_z - 20.0, None), tool=TOOL)
    state = MachineState(joints=FLIPPED, rail=0.0, base_offset=(0.0, 0.0, 0.0), firmware="2021")
    move = predict(env, "M21 G90 G0 X20 Y5 Z20 A60 B-160 C-45", state)
    assert isinstance(move, Prediction)
    reason = refused(predict(env, "M20 G91 G1 X1 F500", move.state), "wrist snap")
    assert "minimum z" in reason
    # With room below, the snap is predicted: the end matches the firmware model's.
    loose = Envelope(tool=TOOL)
    got = predict(loose, "M20 G91 G1 X1 F500", move.state)
    assert isinstance(got, Prediction) and got.snap is not None and got.model_joints is not None
    # J4/J6 of the flip are half a turn away: the firmware may turn them either way, so the
    # predicted joints are left to a status report; the pose is exact
    assert got.state.joints is None and got.state.pose is not None
    fw = homed(s47=TOOL[1])
    run(fw, "M21 G90 G0 X20 Y5 Z20 A60 B-160 C-45")
    _, lowest = run(fw, "M20 G91 G1 X1 F500", watch=loose)
    assert lowest < start_z - 20.0  # the firmware really swings the tool down
    end = joints_of(fw)
    assert np.allclose(forward(tuple(end), DH_2021, TOOL), got.state.pose, atol=0.2)
    turns = (end - np.asarray(got.model_joints)) / 360.0
    assert np.allclose(turns, np.round(turns), atol=0.001)  # equal up to whole turns
    # the snap the firmware model made: the predicted one, J4/J6 turned the way it turned them
    snap = np.asarray(got.snap) + np.round(turns) * 360.0
    snap_path = forward_many(np.linspace(FLIPPED, snap, 200), DH_2021, TOOL)[:, 2]
    assert float(snap_path.min()) == pytest.approx(lowest, abs=2.0)


# ---- issue 17 item 1: bounded sampling ----------------------------------------------------


@pytest.mark.parametrize(
    "line",
    [
        "M20 G90 G1 A300000 F100",
        "M20 G90 G1 A99999999 F100",
        "M20 G90 G1 A99999999999 F100",
        "M20 G91 G1 X" + "9" * 70,
        "M21 G90 G1 X300000 F100",
    ],
)
def test_absurd_values_are_refused_quickly(line: str) -> None:
    env = Envelope(z=(0, None))
    state = MachineState(joints=HOME, pose=forward(HOME, DH_2021), base_offset=(0.0, 0.0, 0.0))
    t0 = time.process_time()  # CPU time: other processes on a loaded machine do not count
    result = predict(env, line, state)
    assert time.process_time() - t0 < 0.1
    assert isinstance(result, EnvelopeRefusal)


def _best_of(runs: int, check: object) -> float:
    """The best of ``runs`` CPU times of this thread (other processes' load does not count)."""
    best = float("inf")
    for _ in range(runs):
        t0 = time.thread_time()
        check()  # type: ignore[operator]
        best = min(best, time.thread_time() - t0)
    return best


def test_checking_the_largest_line_takes_under_10_ms() -> None:
    """The worst lines the client accepts (80 bytes): the longest path the sample cap allows,
    an arc, and a joint move across every range, each with a box to check."""
    env = Envelope(x=(-400, 400), y=(-400, 400), z=(-400, 600))
    start = (-60.0, 20.0, -10.0, 0.0, -60.0, 0.0)
    state = MachineState(joints=start, rail=0.0, base_offset=(0.0, 0.0, 0.0), firmware="2021")
    lines = [
        "M20 G90 G1 X180.0000 Y180.0000 Z120.0000 A30.0000 B-20.0000 C90.0000 F2000.000",
        "M20 G90 G2 X250.000 Y0.000 Z150.000 R150.0000 F2000.0000 A10.000 B10.000 C1.00",
        "M21 G90 G0 X160.000 Y70.000 Z-170.000 A-350.000 B-205.000 C360.000 D500.00000",
    ]
    for line in lines:
        assert len(line.replace(" ", "")) <= 80

        def check(line: str = line) -> None:
            predict(env, line, state)

        assert _best_of(5, check) < 0.010, line


def test_envelope_check_line_raises_usage_errors_only() -> None:
    env = Envelope(z=(0, None))
    for line in ("M20 G90 G1 A99999999999 F100", "M20 G90 G1 A300000 F100"):
        with pytest.raises(MirobotUsageError):
            check_envelope_line(env, line, HOME)
