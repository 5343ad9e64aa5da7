"""Unreachable Cartesian targets and the 2021 profile's composition with classic behaviour: the
pure firmware model against what the oracle printed (the firmware tapes of
``test_diff_workspace`` hold the classic cases byte for byte)."""

from __future__ import annotations

import math

import pytest
from mirobot_emulator.firmware import Firmware

THETA3 = "GOAL OUT OF WORKSPACE, THERE IS NO VAILD VALUS FOR  THETA3!"


def boot(profile: str = "classic") -> Firmware:
    fw = Firmware(profile)
    fw.read_output()
    for line in ["$X"] * (profile == "2021") + ["M50"]:
        send(fw, line)
    return fw


def send(fw: Firmware, line: str) -> list[str]:
    fw.receive(f"{line}\n".encode())
    fw.advance(60.0)
    return fw.read_output().decode().split("\r\n")[:-1]


def test_only_the_shoulder_front_branch() -> None:
    """X50 Y0 Z100 is reachable only over the back (J1 = 180): the firmware has no THETA3."""
    assert send(boot(), "M20 G90 G0 X50 Y0 Z100 A0 B0 C0") == ["", THETA3 + "ok"]


@pytest.mark.parametrize(
    ("before", "expected"),
    [
        ("M20 G90 G0 X100 Y0 Z50 A0 B0 C0", ["", THETA3, "Soft limit triggered:Y", "ok"]),
        ("M20 G90 G0 X200 Y0 Z170 A0 B90 C0", ["", THETA3, "Soft limit triggered:B", "ok"]),
        ("M21 G90 Y80", ["", THETA3 + "ok"]),  # a refused joint line stores nothing
    ],
)
def test_unreachable_target_checks_the_last_target(before: str, expected: list[str]) -> None:
    fw = boot()
    assert send(fw, before)[-2].startswith("Soft limit triggered:")
    assert send(fw, "M20 G90 G1 X300 Y0 Z180 A0 B0 C0 F2000") == expected


def test_joint_line_replaces_the_last_target() -> None:
    fw = boot()
    send(fw, "M20 G90 G0 X100 Y0 Z50 A0 B0 C0")
    assert send(fw, "M21 G90 X10 F2000") == ["ok"]
    assert send(fw, "M20 G90 G0 X300 Y0 Z180 A0 B0 C0") == ["", THETA3 + "ok"]


def test_2021_m20_path_starts_where_queued_motion_ends() -> None:
    """30 chords of a 20 mm circle streamed with M20 on every line: no snap back to where the
    arm was at each parse (that took 43 s and left the circle by 6.9 mm)."""
    fw = boot("2021")
    send(fw, "M20 G90 G0 X202 Y0 Z160 A0 B0 C0")
    chords = [
        f"M20 G90 G1 X{182 + 20 * math.cos(a):.3f} Y{20 * math.sin(a):.3f} Z160 A0 B0 C0 F2000\n"
        for a in (2 * math.pi * i / 30 for i in range(1, 31))
    ]
    start, sent, worst = fw.now, 0, 0.0
    in_flight: list[int] = []
    while sent < len(chords) or fw.planner.busy or in_flight:
        while sent < len(chords) and sum(in_flight) + len(chords[sent]) <= 127:
            fw.receive(chords[sent].encode())
            in_flight.append(len(chords[sent]))
            sent += 1
        fw.advance(0.005)
        del in_flight[: fw.read_output().count(b"ok\r\n")]
        x, y = (float(v) for v in fw.status_line().split("RxRyRz):")[1].split(",")[:2])
        worst = max(worst, abs(math.hypot(x - 182, y) - 20))
    assert fw.now - start < 8.0
    assert worst < 0.5


def test_2021_reset_alarms_only_when_it_interrupts_motion() -> None:
    """As classic (oracle): a reset makes an Alarm only when it interrupts motion, and keeps
    one (the 2021 power-on Alarm survives a reset until ``$X``)."""
    fw = Firmware("2021")
    fw.receive(b"%")
    fw.advance(1.0)
    assert fw.state == "Alarm"
    fw = boot("2021")  # $X, M50
    fw.receive(b"%")
    fw.advance(1.0)
    assert fw.state == "Idle"
    send(fw, "M50")
    fw.receive(b"M21 G90 X30 F2000\n")
    fw.advance(0.3)
    fw.receive(b"%")
    fw.advance(1.0)
    assert fw.state == "Alarm"
