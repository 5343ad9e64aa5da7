"""Realtime bytes, line framing and flow control: byte for byte."""

from __future__ import annotations

import pytest

from .harness import Pair, Until

LONG_MOVE = "M21 G90 X60 Y30 F1000"


def test_feed_hold_and_resume(pair: Pair) -> None:
    pair.lines("M50", LONG_MOVE)
    pair.send(b"!", Until(quiet=0.3))
    pair.status(moving=True)
    # held (Hold, standing still); where it stopped depends on the instant `!` arrived
    pair.send(b"?", Until(statuses=1, quiet=0.2), moving=True)
    pair.send(b"~", Until(quiet=0.1))
    pair.status(moving=True)
    pair.settle()
    pair.status()
    pair.check()


def test_reset_during_motion(pair: Pair) -> None:
    """Where the abort stops the arm depends on the instant: statuses before the final one are
    compared by format."""
    pair.lines("M50", LONG_MOVE)
    pair.status(moving=True)
    pair.reset()
    pair.status(moving=True)
    pair.lines("M21 G90 X0 Y0 Z0 A0 B0 C0 F2000", "$X", "M21 G90 X0 Y0 Z0 A0 B0 C0 F2000")
    pair.settle()
    pair.status()
    pair.check()


def test_reset_keeps_the_alarm(pair: Pair) -> None:
    """A second ``%`` after the abort's Alarm: still Alarm (GRBL keeps its state); where the
    abort stopped the arm depends on the instant, so statuses are compared by format."""
    pair.lines("M50", LONG_MOVE)
    pair.reset()
    pair.reset()
    pair.status(moving=True)
    pair.lines("$X")
    pair.reset()
    pair.status(moving=True)
    pair.check()


def filler(length: int) -> str:
    """A valid line of exactly ``length`` characters (before its newline), mostly spaces."""
    head = "M21 G90 X1 F2000"
    return head + " " * (length - len(head) - 2) + "Y1"


@pytest.mark.parametrize("length", [79, 80, 81, 200])
def test_long_line(pair: Pair, length: int) -> None:
    pair.lines("M50")
    line = "M21 G90 X1 Y" + "0" * (length - 13) + "2"
    assert len(line) == length
    pair.send(line + "\n", Until(terminals=1, quiet=0.3))
    pair.lines("G4 P0")
    pair.status()
    pair.check()


@pytest.mark.parametrize("length", [79, 80, 81])
def test_long_line_with_spaces(pair: Pair, length: int) -> None:
    """Spaces are filtered before the buffer: only the remaining characters count."""
    pair.lines("M50")
    line = filler(length)
    assert len(line) == length
    pair.send(line + "\n", Until(terminals=1, quiet=0.3))
    pair.lines("G4 P0")
    pair.status()
    pair.check()


def test_line_endings(pair: Pair) -> None:
    pair.send("M50\r\n", Until(terminals=2))
    pair.send("M21 G90 X5 F2000\r\n", Until(terminals=2))
    pair.send("G4 P0\r", Until(terminals=1))
    pair.send("\n\n", Until(terminals=2))
    pair.send("\r", Until(terminals=1))
    pair.settle()
    pair.status()
    pair.check()


@pytest.mark.parametrize("byte", [b"?", b"!", b"~", b"@", b"\x18", b"%"])
def test_realtime_byte_mid_line(pair: Pair, byte: bytes) -> None:
    pair.lines("M50")
    # `!` and `@` hold the oracle's parser until `~`: wait for silence, not for an ok
    until = Until(text=b"Using reset pos!\r\n", quiet=0.1) if byte == b"%" else Until(quiet=0.3)
    pair.send(b"M21 G90 " + byte + b"X5 F2000\n", until)
    if byte in b"!@":
        pair.status()  # held by `!` (Hold) or `@` (Door): at rest, exact
    pair.send(b"~", Until(quiet=0.3))
    pair.settle()
    pair.status()
    pair.check()


def test_burst_fills_receive_buffer(pair: Pair) -> None:
    """Ten short lines (about 130 bytes) written at once, unlocked: the ``ok`` count and the end
    position show whether bytes were lost or lines refused."""
    pair.lines("M50")
    burst = "".join(f"M21 G91 X{i % 2 + 1}\n" for i in range(12))
    assert len(burst) > 128
    pair.send(burst, Until(terminals=12), timeout=30)
    pair.settle()
    pair.status()
    pair.check()


def test_burst_fills_planner(pair: Pair) -> None:
    """40 joint moves (about 800 bytes, far more than the receive buffer and the planner hold)
    written at once: the receive ring overflows and drops bytes (the oracle answers 25 lines),
    so the reply is read until one wall second of silence."""
    pair.lines("M50")
    burst = "".join(f"M21 G90 X{i % 3} Y{i % 2} F2000\n" for i in range(40))
    pair.send(burst, Until(quiet=1.0), timeout=60)
    pair.settle()
    pair.status()
    pair.check()


def test_stream_fills_planner(pair: Pair) -> None:
    """30 short joint moves streamed with character counting (more than the planner holds):
    every line answered, same end."""
    pair.lines("M50")
    pair.stream([f"M21 G90 X{i % 3} Y{i % 2} F2000" for i in range(30)])
    pair.settle()
    pair.status()
    pair.check()
