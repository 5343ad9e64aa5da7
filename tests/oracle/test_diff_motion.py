"""The power-on lock and every kind of move: replies, and status lines at rest byte for byte
(status lines during motion by format: see :mod:`tests.oracle.harness`)."""

from __future__ import annotations

import pytest

from .harness import Pair, Until
from .per_side import status_on_reply

MOVE = "M21 G90 X10 Y10 Z10 A10 B10 C10 F2000"


def test_locked_at_power_on(pair: Pair) -> None:
    pair.status()
    pair.lines(MOVE, "M20 G90 G0 X200 Y0 Z180 A0 B0 C0", "M21 G91 X5", "G4 P0")
    pair.status()
    pair.lines("M20", "M21 G90 G1 Y- F500")  # a modal M20, then a refused line: Motion_MODE?
    pair.status()
    pair.check()


def test_lock_after_reset(pair: Pair) -> None:
    """Is the lock set again by ``%``? (It is set only at power-on on the oracle.)"""
    pair.lines("M50")
    pair.reset()
    pair.lines("M21 G90 X10 F2000")
    pair.settle()
    pair.status()
    pair.check()


def test_unlock_with_dollar_x(pair: Pair) -> None:
    pair.lines("$X", "M21 G90 X10 F2000")
    pair.settle()
    pair.status()
    pair.check()


def test_unlock_with_m50(pair: Pair) -> None:
    pair.lines("M50", "M50", "M21 G90 X10 F2000")
    pair.settle()
    pair.status()
    pair.check()


# Every seed command (PROTOCOL.md section 6) in its joint and Cartesian, absolute and relative,
# point-to-point and linear forms, each followed by a settle and an exact status at rest.
MOVES: dict[str, list[str]] = {
    "joint-abs": ["M21 G90 X10 Y-10 Z15 A-20 B-25 C30 D5 F2000"],
    "joint-abs-j1-30": ["M21 G90 X30 F2000"],
    "joint-rel": ["M21 G91 X5 Y5 Z-5 A5 B-5 C5 F1500"],
    "joint-g1": ["M21 G90 G1 X20 Y10 F1000"],
    "joint-g0": ["M21 G90 G0 X-20 Z-10"],
    "cart-abs-g0": ["M20 G90 G0 X180 Y20 Z160 A0 B0 C0 F2000"],
    "cart-abs-g1": ["M20 G90 G1 X180 Y20 Z120 A0 B0 C0 F2000"],
    "cart-rel-g0": ["M20 G91 G0 X-10 Y10 Z-10 A5 B0 C0 F2000"],
    "cart-rel-g1": ["M20 G91 G1 X-10 Y10 Z-10 F1000"],
    "cart-g1-fk-digit": ["M20 G90 G1 X199 Y3 Z167 A0 B0 C0 F1000"],
    "cart-orientation": ["M20 G90 G0 X200 Y0 Z170 A10 B-10 C20 F2000"],
    "modal-words": ["G91", "M21", "F1800", "X3", "Y3", "G90", "X0 Y0"],
    "pump-valve": ["M3 S1000", "M3 S0", "M4 E65", "M4 E40", "M3 S500", "M5"],
    "dwell": ["G4 P0.5", "G4 P0"],
    "dwell-with-motion": ["M21 G91 G0 X30 G4 P0.2"],  # answered when its motion starts: Run
    "g10-g28": ["G10 L2 P1 X0", "G28", "G92 X0"],
}


@pytest.mark.parametrize("program", MOVES)
def test_move(pair: Pair, program: str) -> None:
    pair.lines("M50")
    *first, last = MOVES[program]
    pair.lines(*first)
    status_on_reply(pair, (last + "\n").encode(), note="last line")  # ``?`` during the motion
    pair.settle()
    pair.status()
    pair.send("$G\n")
    pair.check()


# Lines written in one burst: M21/M20 resynchronise the parser to the machine position, so a
# relative line parsed while the arm moves depends on the instant. In one burst every line is
# parsed within a few milliseconds of the first (less than one motor step of travel), so the
# outcome is deterministic on both sides.
BURSTS: dict[str, list[str]] = {
    "joint-rel-twice": ["M21 G91 X5 Y5 Z-5 A5 B-5 C5 F1500", "M21 G91 X5 Y5 Z-5 A5 B-5 C5"],
    "m21-resync": ["M21 G91 X1 F2000"] * 8,
    "m20-after-m21": ["M21 G90 X10 F2000", "M20 G91 G0 X5"],
    "g91-without-m21": ["M21 G91 X1 F2000", "X1", "X1", "X1"],
    "cart-rel-g1-twice": ["M20 G91 G1 X-10 Y10 Z-10 F1000", "M20 G91 G1 Z10"],
    # more lines than the planner holds: a line whose target rounds to the steps already
    # planned makes no block (GRBL drops it), so the later lines never wait for a slot and
    # each is resynchronised near the start (oracle: J1 1.040, 5.041, 0.159)
    "m21-resync-25": ["M21 G91 X1 F3000"] * 25,
    "m21-resync-25-x5": ["M21 G91 X5 F3000"] * 25,
    "m21-resync-30-slow": ["M21 G91 X0.1 F500"] * 30,
    "m21-resync-25-two-axes": ["M21 G91 Y2 Z1 F2000"] * 25,
}


@pytest.mark.parametrize("program", BURSTS)
def test_burst(pair: Pair, program: str) -> None:
    pair.lines("M50")
    pair.send("".join(line + "\n" for line in BURSTS[program]))
    pair.settle()
    pair.status()
    pair.check()


# Cartesian lines parse slower (about 13 ms) than their bytes arrive: the receive ring fills
# and drops bytes, so the reply is read until one wall second of silence. The ring keeps the
# start of a line whose end was lost: the first ``G4 P0`` completes it (oracle: into ``M20 G91
# G0 X1 G4 P0``, answered as its motion starts), the second waits for the motion to end.
OVERFLOWING_BURSTS: dict[str, list[str]] = {
    "m20-rel-g0-20": ["M20 G91 G0 X1"] * 20,
    "m20-rel-g1-20": ["M20 G91 G1 X1 F2000"] * 20,
}


@pytest.mark.parametrize("program", OVERFLOWING_BURSTS)
def test_overflowing_burst(pair: Pair, program: str) -> None:
    pair.lines("M50")
    pair.send("".join(line + "\n" for line in OVERFLOWING_BURSTS[program]), Until(quiet=1.0))
    pair.settle()
    pair.settle()
    pair.status()
    pair.check()


UNREACHABLE: dict[str, list[str]] = {
    "joint-soft-limit": ["M21 G90 X170 F2000"],
    "joint-soft-limit-each": [
        "M21 G90 Y80",
        "M21 G90 Z-180",
        "M21 G90 A400",
        "M21 G90 B50",
        "M21 G90 C-400",
        "M21 G90 D2000",
    ],
    "cart-too-far-g0": ["M20 G90 G0 X400 Y0 Z180 A0 B0 C0"],
    "cart-too-far-g1": ["M20 G90 G1 X400 Y0 Z180 A0 B0 C0 F2000"],
    "cart-wrist-out": ["M20 G90 G0 X200 Y0 Z170 A0 B60 C0"],
    "cart-wrist-out-soft-off": ["$20=0", "M20 G90 G0 X200 Y0 Z170 A0 B60 C0"],
    "back-in-range": ["M21 G90 X170 F2000", "M21 G90 X150"],
    # wrist centre behind the shoulder: the firmware solves J2 mirrored (beyond -30: Y), the
    # textbook branch would need J5 beyond 36 (B)
    "cart-near-base-axis": ["M20 G90 G0 X1 Y5 Z182 A0 B0 C0"],
    "cart-on-base-axis-g1": ["M20 G90 G1 X0 Y0 Z182 A0 B0 C0 F2000"],
}


@pytest.mark.parametrize("program", UNREACHABLE)
def test_unreachable(pair: Pair, program: str) -> None:
    pair.lines("M50")
    pair.lines(*UNREACHABLE[program])
    pair.settle()
    pair.status()
    pair.check()


@pytest.mark.parametrize(
    "move",
    [
        "M21 G90 X165 F2000",  # J1 past 160.5: stops at 160.515
        "M21 G90 X165 Y75 F2000",  # J2 closes first (70.502), J1 where its steps are then
        "M21 G90 G0 Z65",  # J3 at its high end, rapid
    ],
)
def test_hard_limit(pair: Pair, move: str) -> None:
    """Soft limits off, driven past the oracle harness's range-end switches (0.5 degrees
    outside the factory ranges; placement is the harness's assumption), then what the alarm
    allows."""
    pair.lines("$20=0", "M50", move)
    pair.send("G4 P0\n", Until(text=b"[Reset to continue]\r\n"))  # the alarm, no ok
    for line in ("M21 G90 X0\n", "$X\n", "?"):  # the oracle takes nothing but % now
        pair.send(line, Until(quiet=0.3))
    pair.reset()
    pair.status()
    pair.check()
