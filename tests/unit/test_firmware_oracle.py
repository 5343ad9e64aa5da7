"""Behaviours of the firmware model fixed against the oracle (the classic firmware 20191228_2 as
recorded in the firmware tapes); each test quotes what the oracle printed."""

from __future__ import annotations

import math

import pytest
from mirobot_emulator.firmware import Firmware
from mirobot_emulator.firmware._wire import BYTE_SECONDS

STEP_TOLERANCE = 0.1  # status angles are whole motor steps (see test_firmware.py)


def lines(fw: Firmware, data: str, dt: float = 0.0) -> list[str]:
    fw.receive(data.encode("latin-1"))
    fw.advance(dt)
    while (due := fw.input_deadline) is not None:  # bytes in transit, a line being parsed
        fw.advance(due - fw.now)
    text = fw.read_output().decode("latin-1")
    return text.split("\r\n")[:-1] if text else []


def angles(fw: Firmware) -> list[float]:
    """J1..J6 and the rail from a status report."""
    (status,) = lines(fw, "?")
    values = [float(v) for v in status.split("Angle(ABCDXYZ):")[1].split(",C")[0].split(",")]
    a, b, c, d, x, y, z = values
    return [x, y, z, a, b, c, d]


def unlocked(profile: str = "classic") -> Firmware:
    fw = Firmware(profile)
    fw.read_output()
    if profile == "2021":
        lines(fw, "$X\n")
    lines(fw, "M50\n")
    return fw


def test_settings_dump_has_28_and_the_reset_distances() -> None:
    fw = Firmware("classic")
    fw.read_output()
    dump = lines(fw, "$$\n")
    assert "$28=65 (homing pos dir invert mask:01000001)" in dump
    assert dump[dump.index("$146=170.000 (g min travel, mm)") + 1 :] == [
        "$150=45.000 (a reset distance)",
        "$151=45.000 (b reset distance)",
        "$152=0.000 (c reset distance)",
        "$153=0.000 (d reset distance)",
        "$154=45.000 (e reset distance)",
        "$155=45.000 (f reset distance)",
        "$156=45.000 (g reset distance)",
        "ok",
    ]
    assert lines(fw, "$150=10\n") == ["ok"]


def test_status_angles_are_whole_steps() -> None:
    fw = unlocked()
    lines(fw, "M21 G90 X10\n", math.inf)
    (status,) = lines(fw, "?")
    assert status.startswith("<Idle,Angle(ABCDXYZ):0.000,0.000,0.000,0.000,9.995,0.000,0.000,")
    assert "Cartesian coordinate(XYZ RxRyRz):198.934,35.059,181.000,0.000,0.000,9.995," in status


def test_a_reset_does_not_lock() -> None:
    fw = unlocked()
    lines(fw, "%")
    assert lines(fw, "M21 G90 X20 F2000\n", math.inf) == ["ok"]
    assert angles(fw)[0] == pytest.approx(20.007, abs=1e-9)


def test_at_holds_the_lines_until_cycle_start() -> None:
    fw = unlocked()
    assert lines(fw, "G4@P0\n") == []
    assert fw.state == "Idle" and fw.parser_blocked
    assert lines(fw, "~") == ["ok"]


def test_m21_and_m20_resynchronise_the_parser() -> None:
    fw = unlocked()
    assert lines(fw, "M21 G91 X1\n" * 8, math.inf) == ["ok"] * 8
    assert angles(fw)[0] == pytest.approx(1.005, abs=1e-9)  # not 8
    lines(fw, "M21 G90 X0\n", math.inf)
    assert lines(fw, "G91 X1\n" * 8, math.inf) == ["ok"] * 8
    assert angles(fw)[0] == pytest.approx(8.003, abs=1e-9)  # 454 steps: 8 x 56.73 rounded
    lines(fw, "M21 G90 G0 X0 Y30\nM21 G90 G0 X10\n", math.inf)
    assert angles(fw)[:2] == pytest.approx([9.995, 0.0], abs=1e-9)


def test_refusal_texts() -> None:
    fw = unlocked()
    assert lines(fw, "M20 G90 G0 X400 Y0 Z100 A0 B0 C0\n") == [
        "",
        "GOAL OUT OF WORKSPACE, THERE IS NO VAILD VALUS FOR  THETA3!ok",
    ]
    wrist = "M20 G90 G0 X200 Y0 Z150 A0 B100 C0\n"
    assert lines(fw, wrist) == ["", "Soft limit triggered:B", "ok"]
    assert lines(fw, "$20=0\n" + wrist, math.inf) == ["ok", "ok"]  # moves without soft limits
    assert angles(fw)[4] > 36.0


def test_work_offsets_and_stored_positions() -> None:
    fw = unlocked()
    assert lines(fw, "G10 L2 P1 X5\nM21 G90 G0 X0\n", math.inf) == ["ok", "ok"]
    assert angles(fw)[0] == pytest.approx(5.006, abs=1e-9)
    assert lines(fw, "$#\n")[0] == "[G54:0.000,0.000,0.000,0.000,5.000,0.000,0.000]"
    assert lines(fw, "G10 L2 P1 X0\nG10 L20 P2 Y3\nG55 G0 Y0\nG54\n", math.inf) == ["ok"] * 4
    assert angles(fw)[1] == pytest.approx(-3.0, abs=1e-9)
    assert lines(fw, "G28\n", math.inf) == ["ok"]  # to the G28 position (zero)
    assert angles(fw)[:2] == [0.0, 0.0]
    lines(fw, "M21 G90 G0 X20\nG28.1\nM21 G90 G0 X0\n", math.inf)
    assert lines(fw, "$#\n")[6] == "[G28:0.000,0.000,0.000,0.000,20.000,0.000,0.000]"
    assert lines(fw, "G28\n", math.inf) == ["ok"]
    assert angles(fw)[0] == pytest.approx(20.007, abs=1e-9)
    assert lines(fw, "G92 X5\nM21 G90 G0 X0\n", math.inf) == ["ok", "ok"]
    assert angles(fw)[0] == pytest.approx(15.001, abs=1e-9)
    assert lines(fw, "G92.1\nG49\nG43.1 Z1\n") == ["ok", "ok", "error: Invalid gcode ID:37"]


def test_a_locked_g28_is_refused() -> None:
    fw = Firmware("classic")
    fw.read_output()
    assert lines(fw, "G28\n") == ["", "Locked status of each axis!", "ok"]


def test_a_dwell_reports_idle_and_the_ring_holds_127_bytes() -> None:
    fw = unlocked()
    assert lines(fw, "G4 P2\n") == []
    fw.receive(b"G4P0\n" * 25 + b"G4P")  # 128 bytes while the parser waits
    fw.advance(128 * BYTE_SECONDS)  # every byte has arrived (the dwell goes on)
    assert fw.rx_lost == 1 and fw.state == "Idle"
    assert lines(fw, "", math.inf) == ["ok"] * 26
    assert lines(fw, "\n") == ["error: Invalid gcode ID:28"]  # "G4": the "P" was lost


def test_a_failing_line_still_acts_on_its_m20_m21_m50_on_classic() -> None:
    fw = Firmware("classic")
    fw.read_output()
    assert lines(fw, "M20 Q1\n") == ["error: Unsupported command"]
    assert lines(fw, "?")[0].endswith("Motion_MODE:1>")
    assert lines(fw, "Q1 M21\n") == ["error: Unsupported command"]  # the error comes first
    assert lines(fw, "?")[0].endswith("Motion_MODE:1>")
    assert lines(fw, "M50 Q1\n") == ["M50: Unlock each axis.", "error: Unsupported command"]
    assert lines(fw, "M21 G90 X5\n") == ["ok"]  # unlocked
    assert lines(fw, "M20 G2\n") == ["error: Invalid gcode ID:26"]


def test_small_negative_status_numbers_print_minus_zero() -> None:
    fw = unlocked()
    lines(fw, "M20 G90 G1 X199 Y3 Z167 A0 B0 C0 F1000\n", math.inf)
    (status,) = lines(fw, "?")
    # oracle: ...Cartesian coordinate(XYZ RxRyRz):199.001,3.000,166.975,-0.000,0.003,-0.036,...
    assert ",-0.000,0.003,-0.036," in status


def test_a_reset_ends_the_line_in_progress_with_ok() -> None:
    # oracle: 'M21 G90 X100 F2000', 'M21 G90 X50', 'G4 P5' then % -> 'ALARM: Abort during
    # cycle', 'ok' (the waiting G4), the banner; after a hard limit the waiting line's ok too
    fw = unlocked()
    lines(fw, "M21 G90 X100 F2000\nM21 G90 X50\nG4 P5\n", 1.0)
    assert lines(fw, "%")[:3] == ["ALARM: Abort during cycle", "ok", ""]
    fw = unlocked()
    lines(fw, "$20=0\nM21 G90 X165 F2000\n")
    out = lines(fw, "G4 P0\n", math.inf)
    assert out == ["00010000ALARM: Hard limit", "[Reset to continue]"]
    assert lines(fw, "%")[:2] == ["ok", ""]


def test_startup_lines_are_checked_when_stored_and_run_after_a_reset() -> None:
    fw = Firmware("classic")
    fw.read_output()
    assert lines(fw, "$N0=G91\n$G\n")[1] == "[G0 G54 G17 G21 G91 G94 M0 M5 M9 T0 F200. S0.]"
    assert lines(fw, "$N1=Q1\n") == ["error: Unsupported command"]  # not stored
    assert lines(fw, "$N1=M3S100\n") == ["ok"]
    out = lines(fw, "%")
    assert out[-3:] == ["Using reset pos!", "G91ok", "M3S100ok"]  # oracle, after the banner


def test_refused_targets_that_still_move_the_parser() -> None:
    fw = Firmware("classic")
    fw.read_output()
    lines(fw, "G91 X10\nM50\n")  # refused: locked
    lines(fw, "G91 X1\n", math.inf)
    assert angles(fw)[0] == pytest.approx(10.999, abs=1e-9)  # oracle: from 10, not 0
    lines(fw, "G90 X170\n")  # refused: soft limit X, the parser stays at 11
    lines(fw, "G91 X1\n", math.inf)
    assert angles(fw)[0] == pytest.approx(12.004, abs=1e-9)
    unreachable = ["", "GOAL OUT OF WORKSPACE, THERE IS NO VAILD VALUS FOR  THETA3!ok"]
    assert lines(fw, "M20 G91 G0 X500\n") == unreachable
    assert lines(fw, "G91 G0 X-300\n") == unreachable  # from x = 700 or so, not from 200


@pytest.mark.parametrize(
    ("line", "reply"),
    [
        ("G91 M3", "error: Modal group violation"),
        ("M8 M5", "error: Modal group violation"),
        ("M3 M20", "error: Modal group violation"),
        ("G90 M21", "error: Modal group violation"),
        ("M3 G91", "ok"),
        ("M5 M8", "ok"),
        ("G4 P0 M3", "ok"),
        ("F100 M20", "ok"),
        ("M21 G93 G17 G91", "error: Modal group violation"),
        ("M21 G94 N-1", "error: Modal group violation"),
        ("G10 Z3 M21 D7", "error: Invalid gcode ID:28"),
        ("F100 M3 G4 P0", "error: Modal group violation"),
        ("S100 M3 G49", "error: Modal group violation"),
        ("N1 M3 G93", "error: Modal group violation"),
        ("G91 G20 F0 M5 G94", "ok"),
        ("P0 M3 G4", "ok"),
        ("G4 M5", "error: Modal group violation"),
    ],
)
def test_m3_m20_m50_take_the_group_of_the_word_before_them(line: str, reply: str) -> None:
    fw = unlocked()
    assert lines(fw, line + "\n") == [reply]


# Status numbers as the AVR prints them: float32 angle = steps / steps-per-degree, then GRBL's
# float32 scaling (x100, x10, +0.5, truncated). Each pair is (steps, steps per unit, what the
# oracle printed); double-precision rounding prints the last digit one lower for all of them.
FLOAT32_PRINTS = [
    (-1443, 22.22, "-64.942"),
    (318, 56.73, "5.606"),
    (4346, 56.73, "76.609"),
    (5326, 113.33, "46.996"),
    (944, 11.11, "84.969"),
    (7051, 56.73, "124.291"),
]


@pytest.mark.parametrize(("steps", "per_unit", "printed"), FLOAT32_PRINTS)
def test_status_angle_printed_in_float32(steps: int, per_unit: float, printed: str) -> None:
    from mirobot_emulator.firmware._float32 import print_float, step_angle
    from mirobot_emulator.settings import grbl_float

    assert print_float(step_angle(steps, per_unit)) == printed
    assert grbl_float(steps / per_unit) != printed  # the double-precision print differs


def test_float32_print_keeps_grbl_format() -> None:
    from mirobot_emulator.firmware._float32 import print_float

    assert [print_float(v) for v in (0.0, -0.0, -0.0001, 202.0, -10.307, 0.0005)] == [
        "0.000", "0.000", "-0.000", "202.000", "-10.307", "0.001",
    ]  # fmt: skip


def test_status_after_moves_prints_float32_angles() -> None:
    """The oracle printed J5 = ``-64.942`` at -1443 steps (22.22 per degree), where ``M21 G90
    B-64.94`` ends; the double-precision print would be ``-64.941``."""
    fw = Firmware("classic")
    lines(fw, "M50\n")
    lines(fw, "M21 G90 B-64.94 F2000\n", 5.0)
    (status,) = lines(fw, "?")
    assert status.startswith("<Idle,Angle(ABCDXYZ):0.000,-64.942,0.000,0.000,")
