"""The firmware model survives settings that change its step grid or zero a feed: every line
still gets its reply and the model never fails inside (random floods found both)."""

from __future__ import annotations

import math

import pytest
from mirobot_emulator.firmware import Firmware

PROFILES = ("classic", "2021", "2024")


def send(fw: Firmware, data: str, dt: float = 0.0) -> list[str]:
    """Send ``data``, run the clock ``dt`` seconds, return the printed lines."""
    fw.receive(data.encode())
    fw.advance(dt)
    while (due := fw.input_deadline) is not None:
        fw.advance(due - fw.now)
    return fw.read_output().decode("latin-1").split("\r\n")[:-1]


def unlocked(profile: str) -> Firmware:
    fw = Firmware(profile)
    fw.read_output()
    assert send(fw, "$X\nM50\n")[-1] == "ok"
    return fw


@pytest.mark.parametrize("profile", PROFILES)
def test_a_move_after_the_step_grid_returns_starts_where_the_arm_is(profile: str) -> None:
    """With ``$100=0`` the model has no step grid (an ideal machine): J1 stops at exactly 1.0.
    ``$RST=$`` brings the grid back: the next move starts from the nearest whole step."""
    fw = unlocked(profile)
    assert send(fw, "$100=0\n")[-1] == "ok"
    assert send(fw, "M21 G90 G0 X1\n", math.inf)[-1] == "ok"
    send(fw, "$RST=$\n", 1.0)
    assert send(fw, "$X\nM50\nM21 G90 G0 X5\n", math.inf)[-1] == "ok"
    assert send(fw, "M21 G91 G0 X1\n", math.inf)[-1] == "ok"
    report = send(fw, "?")[-1]
    assert report.startswith("<Idle,Angle(ABCDXYZ):"), report


@pytest.mark.parametrize("profile", PROFILES)
def test_homing_with_a_homing_feed_of_zero_is_answered(profile: str) -> None:
    """``$24=0`` (homing feed): homing is answered and the return move crawls (ASSUMED)."""
    fw = Firmware(profile)
    fw.read_output()
    assert send(fw, "$24=0\n")[-1] == "ok"
    out = send(fw, "$H\n", 120.0)
    assert out and out[-1].endswith("ok"), out
    assert send(fw, "?")[-1].startswith("<"), "the model still answers"


@pytest.mark.parametrize("setting", ["$31=0", "$33=0"])
def test_a_geometry_the_ik_cannot_solve_refuses_cartesian_moves(setting: str) -> None:
    """2021: ``$31=0`` (A2 = 0; ``mirobot check`` accepts it) left the IK raising inside the
    model on the next Cartesian move: no reply on a pty, and in process the line was reported
    lost although it ran. It is refused as unreachable ("ok" but dropped), and the arm goes on."""
    fw = unlocked("2021")
    assert send(fw, f"{setting}\n")[-1] == "ok"
    for line in ("M20 G90 G0 X200 Y0 Z200", "M20 G91 G1 X1 F100"):
        replies = send(fw, line + "\n", math.inf)
        assert replies[-1].startswith("GOAL OUT OF WORKSPACE") and replies[-1].endswith("ok")
    assert send(fw, "M21 G91 G0 X1\n", math.inf)[-1] == "ok"  # joint moves still run
