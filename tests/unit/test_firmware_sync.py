"""Lines the firmware holds until queued motion ends, and bursts of resynchronising lines: the
pure firmware model against what the oracle printed (the firmware tapes of
``test_diff_outputs`` and ``test_diff_motion`` hold the same cases byte for byte)."""

from __future__ import annotations

import pytest
from mirobot_emulator.firmware import Firmware

MOVE = "M21 G90 X30 F1000\n"  # 1.57 s on the oracle


def unlocked(*before: str) -> Firmware:
    fw = Firmware("classic")
    fw.read_output()
    for line in ("M50", *before):
        fw.receive(f"{line}\n".encode())
        fw.advance(0.5)
    fw.read_output()
    return fw


def reply_times(fw: Firmware, seconds: float) -> list[float]:
    """When each ``ok`` came, in seconds from now, within ``seconds``."""
    start, times = fw.now, []
    while fw.now - start < seconds:
        fw.advance(0.005)
        times += [fw.now - start] * fw.read_output().count(b"ok\r\n")
    return times


def pwms(fw: Firmware) -> tuple[int, int]:
    status = fw.status_line()
    pump = int(status.split("Pump PWM:")[1].split(",")[0])
    valve = int(status.split("Valve PWM:")[1].split(",")[0])
    return pump, valve


@pytest.mark.parametrize(
    ("before", "line", "during", "after"),
    [
        ((), "M3 S1000", (1000, 0), (1000, 0)),
        (("M3 S1000",), "M3 S500", (1000, 0), (500, 0)),
        (("M3 S1000",), "M5", (1000, 0), (1000, 0)),
        (("M4 E65",), "S500", (0, 65), (500, 65)),
        ((), "M8", (0, 0), (0, 0)),
    ],
)
def test_output_change_waits_for_motion(
    before: tuple[str, ...], line: str, during: tuple[int, int], after: tuple[int, int]
) -> None:
    fw = unlocked(*before)
    fw.receive(f"{MOVE}{line}\n".encode())
    fw.advance(0.2)
    assert fw.read_output() == b"ok\r\n"  # the move's; the line waits
    assert fw.state == "Run" and pwms(fw) == during
    (held,) = reply_times(fw, 2.0)
    assert 1.3 < held < 1.45  # the arm's end (1.57 s after the write)
    assert fw.state == "Idle" and pwms(fw) == after


@pytest.mark.parametrize(
    ("before", "line"),
    [((), "M5"), ((), "S500"), (("M3 S1000",), "M3 S1000"), (("M8",), "M8"), ((), "G92 X0")],
)
def test_unchanged_outputs_answer_at_once(before: tuple[str, ...], line: str) -> None:
    fw = unlocked(*before)
    fw.receive(f"{MOVE}{line}\n".encode())
    fw.advance(0.2)
    assert fw.read_output() == b"ok\r\nok\r\n"
    assert fw.state == "Run"


def test_check_mode_never_waits() -> None:
    fw = unlocked()
    fw.receive(b"$C\n")
    fw.advance(0.5)
    fw.read_output()
    fw.receive(b"M3 S1000\nM8\n")
    fw.advance(0.1)
    assert fw.read_output() == b"ok\r\nok\r\n"


@pytest.mark.parametrize(
    ("line", "count", "j1"),
    [("M21 G91 X1 F3000", 25, 1.040), ("M21 G91 X5 F3000", 25, 5.041)],
)
def test_resynchronising_burst_ends_where_the_firmwares_does(
    line: str, count: int, j1: float
) -> None:
    """A line whose target rounds to the planned steps makes no block, so the 25 lines never
    wait for a planner slot; each reads the arm near its start (oracle: 1.040 and 5.041)."""
    fw = unlocked()
    fw.receive(f"{line}\n".encode() * count)
    assert len(reply_times(fw, 0.1)) == count
    fw.advance(5.0)
    assert fw.state == "Idle"
    assert f"{fw.joints[0]:.3f}" == f"{j1:.3f}"


def test_2021_step_grid_follows_the_device_printout() -> None:
    """The 2021 manual's device printout (vectors.json corrupted_status_lines[0]) lies on the
    classic steps-per-degree grid: commanded to its angles, the 2021 model stops exactly there
    (the manual's own $100..$106 table would stop J1 at 90.016)."""
    import json
    from pathlib import Path

    vectors = json.loads((Path(__file__).parents[1] / "data" / "vectors.json").read_text())
    printed = vectors["corrupted_status_lines"][0]
    device = printed.split("Angle(ABCDXYZ):")[1].split(",Cartesian")[0]
    a, b, c, _rail, x, y, z = (float(v) for v in device.split(","))
    fw = Firmware("2021")
    fw.read_output()
    for line in ("$X", "M50", f"M21 G90 G0 X{x:.0f} Y{y:.0f} Z{z:.0f} A{a:.0f} B{b:.0f} C{c:.0f}"):
        fw.receive(f"{line}\n".encode())
        fw.advance(0.5)
    fw.advance(30.0)
    assert fw.state == "Idle"
    ours = fw.status_line().split("Angle(ABCDXYZ):")[1].split(",Cartesian")[0]
    assert ours == device


SLOW_MOVE = "M21 G90 X30 F300\n"


@pytest.mark.parametrize(
    ("line", "pad", "state"),
    [
        ("M4 E40 S500", 3, "Idle"),
        ("M4 E40 S500", 5, "Run"),
        ("M4 E65", 8, "Idle"),
        ("M4 E65", 9, "Run"),
        ("M3 S500", 7, "Idle"),
        ("M3 S500", 8, "Run"),
        ("M5", 11, "Idle"),
        ("M5", 13, "Run"),
    ],
)
def test_a_status_before_the_held_line_waits_finds_the_move_not_started(
    line: str, pad: int, state: str
) -> None:
    """The move and the held line written at once, then ``pad`` filtered bytes and ``?``: the
    oracle answers ``Idle`` at the start pose while the held line is parsed (GRBL reports before
    it starts the cycle at the line's wait), ``Run`` once it waits (its last ``Idle`` and
    first ``Run`` in 0.1 ms steps: pads 4/5, 8/9, 7/8, 11/12; firmware tapes, test_diff_outputs)."""
    fw = unlocked("M3 S1000")
    fw.receive(f"{SLOW_MOVE}{line}\n".encode() + b" " * pad + b"?")
    fw.advance(0.05)
    out = fw.read_output().split(b"\r\n")
    assert out[0] == b"ok" and out[1].startswith(f"<{state},Angle(ABCDXYZ):0.000,".encode())
    assert b"Pump PWM:1000,Valve PWM:0," in out[1]


def test_the_move_starts_once_the_report_before_it_is_out() -> None:
    """With the transmitter paced as the oracle's, the report printed before the start delays
    the move by its production (oracle: the held line's ``ok`` 12.5 ms later; here 13.0 ms)."""
    from mirobot_emulator.firmware._uart import ORACLE_BYTE_SECONDS

    ends = []
    for pad in (3, 5):
        fw = unlocked("M3 S1000")
        fw.uart.byte_seconds = ORACLE_BYTE_SECONDS
        fw.receive(f"{SLOW_MOVE}M4 E40 S500\n".encode() + b" " * pad + b"?")
        start, out = fw.now, b""
        while out.count(b"ok") < 2:
            fw.advance(0.0001)
            out += fw.read_output()
        ends.append(fw.now - start)
    assert 0.0120 < ends[0] - ends[1] < 0.0135
