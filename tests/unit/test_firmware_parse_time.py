"""Parse time of lines on the classic model against the firmware oracle's ``-l`` logs
(:mod:`mirobot_emulator.firmware._linecost`): ``M20`` lines by pose, the receive interrupts of
bytes that arrive meanwhile, a block charged only when planned, and what a burst that overflows
the receive ring loses."""

from __future__ import annotations

import itertools

import pytest
from mirobot_emulator.firmware import Firmware
from mirobot_emulator.firmware._wire import Wire

START = "M21 G90 G0 X0 Y0 Z0 A0 B0 C0 F2000"


def _powered(*lines: str) -> Firmware:
    """The classic model after ``M50`` and ``lines``, each answered and the arm at rest."""
    fw = Firmware("classic")
    for line in ("M50", *lines, "G4 P0"):
        fw.receive(line.encode() + b"\n")
        fw.advance(30.0)
    fw.read_output()
    return fw


def _replies(fw: Firmware, data: bytes, until: float = 5.0) -> list[tuple[float, bytes]]:
    """Write ``data`` now; each reply line with its simulated seconds after the write."""
    start = fw.now
    fw.receive(data)
    got: list[tuple[float, bytes]] = []
    while (deadline := fw.next_deadline()) is not None and deadline - start < until:
        fw.advance(max(deadline - fw.now, 1e-7))
        got += [(fw.now - start, line) for line in fw.read_output().splitlines()]
    return got


def _gaps_ms(replies: list[tuple[float, bytes]]) -> list[float]:
    times = [t for t, line in replies if line == b"ok"]
    return [round((b - a) * 1000, 3) for a, b in itertools.pairwise(times)]


@pytest.mark.parametrize(
    ("before", "line", "oracle_ms"),
    [
        (START, "M20", 7.092),
        (START, "M20 G91 G0 X1", 12.670),
        (START, "M20 G91 G1 X1 F2000", 12.826),
        (START, "M20 G91 G0 X1 A1 B1 C1", 13.931),
        ("M21 G90 G0 X0 Y0.529 Z-0.531", "M20 G91 G0 X1", 13.112),
        ("M21 G90 G0 X10 Y10 Z10 A10 B10 C10", "M20", 8.051),
    ],
)
def test_a_cartesian_line_parses_as_long_as_on_the_firmware(
    before: str, line: str, oracle_ms: float
) -> None:
    """Steady ``ok`` to ``ok`` gaps of identical lines once no more bytes arrive (each plans no
    block): within 0.03 ms of the oracle's near the start pose (0.2 ms away from it)."""
    fw = _powered(before)
    gaps = _gaps_ms(_replies(fw, b"\n" + (line + "\n").encode() * 6))
    tolerance = 0.03 if before == START else 0.2
    assert gaps[-1] == pytest.approx(oracle_ms, abs=tolerance)


def test_the_block_is_charged_only_when_planned() -> None:
    """The first ``M20 G91 G0 X1`` of a burst plans a block (0.40 ms), the next ones plan
    nothing (their target rounds to the same steps): oracle 13.03 ms and 12.67 ms of work."""
    plans, nothing = _powered(START), _powered(START)
    ends = plans.motion_ends, nothing.motion_ends
    first = _gaps_ms(_replies(plans, b"\n" + b"M20 G91 G0 X1\n" * 2))
    second = _gaps_ms(_replies(nothing, b"\n" + b"M20 G91 G0 X0\n" * 2))  # the same bytes
    assert (plans.motion_ends - ends[0], nothing.motion_ends - ends[1]) == (1, 0)
    assert first[0] - second[0] == pytest.approx(0.40, abs=1e-6)
    assert first[1] == second[1] == pytest.approx(12.672, abs=1e-6)


@pytest.mark.parametrize(("spaces", "oracle_ms"), [(40, 0.266), (80, 0.529), (120, 0.792)])
def test_bytes_arriving_during_a_parse_delay_it(spaces: int, oracle_ms: float) -> None:
    """Each byte's receive interrupt (oracle: ``M20 G91 G0 X0`` followed by spaces)."""
    bare = _replies(_powered(START), b"\nM20 G91 G0 X0\n\n")
    padded = _replies(_powered(START), b"\nM20 G91 G0 X0\n" + b" " * spaces + b"\n")
    delay = (padded[1][0] - padded[0][0]) - (bare[1][0] - bare[0][0])
    assert delay * 1000 == pytest.approx(oracle_ms, abs=0.01)


@pytest.mark.parametrize(
    ("line", "replies"),
    [
        ("M20 G91 G0 X1", [b"ok"] * 10 + [b"error: Bad number format"]),
        (
            "M20 G91 G1 X1 F2000",
            [b"ok"] * 7 + [b"error: Modal group violation", b"error: Expected command letter"],
        ),
    ],
)
def test_an_overflowing_burst_loses_the_firmwares_bytes(line: str, replies: list[bytes]) -> None:
    """20 lines written at once: the ring fills during the slow parses and the lines that
    remain are the oracle's; the start of a last line stays in the ring, the next line end
    completes it (a ``G4 P0`` with its motion: answered as the motion starts, then J2 1.059)."""
    fw = _powered()
    got = _replies(fw, (line + "\n").encode() * 20, until=1.0)
    assert [text for _t, text in got] == replies
    fw.receive(b"G4 P0\n")
    fw.advance(0.02)  # the parse of the completed M20 line
    assert fw.read_output() == b"ok\r\n" and fw.state == "Run"
    fw.advance(30.0)
    assert fw.status_line().startswith("<Idle,Angle(ABCDXYZ):0.000,0.000,0.000,0.000,0.000,1.059,")


def test_a_dwell_with_motion_answers_as_the_motion_starts() -> None:
    """Oracle: ``M21 G91 G0 X30 G4 P0.2`` answers after the dwell; a ``G4 P0`` then waits for
    the motion (1.57 s on the oracle)."""
    fw = _powered()
    replies = _replies(fw, b"M21 G91 G0 X30 G4 P0.2\nG4 P0\n", until=3.0)
    (dwelt, _), (moved, _) = replies
    assert 0.2 < dwelt < 0.21
    assert 1.4 < moved - dwelt < 1.8


def test_the_wire_counts_arrivals_and_stretches_work() -> None:
    wire = Wire(100e-6)
    wire.send(b"x" * 10, 0.0)
    assert [wire.arrived_by(t * 1e-4) for t in (0, 1, 5, 10, 20)] == [0, 1, 5, 10, 10]
    assert wire.take_due(3.5e-4) == b"xxx"
    assert wire.arrived_by(3.5e-4) == 3
    # 1 ms of work from 0 with 10 bytes arriving meanwhile: each adds 10 us
    assert wire.busy_until(0.0, 1e-3, 0, lambda n: n * 10e-6) == pytest.approx(1.1e-3)


@pytest.mark.parametrize(
    ("line", "oracle_ms"),
    [("M20 G91 G0 X1", [13.469, 12.670]), ("M20 G91 G1 X1 F2000", [13.683, 13.471, 12.826])],
)
def test_a_lost_byte_interrupts_less(line: str, oracle_ms: list[float]) -> None:
    """Oracle, 20 lines written at once: the lines parsed while the ring is full and the
    burst still arrives are slower by the interrupts of the bytes stored, and less of those
    lost (the second ``M20 G91 G0 X1``: 14 stored, 114 lost, 0.799 ms)."""
    got = _replies(_powered(), (line + "\n").encode() * 20, until=1.0)
    assert _gaps_ms(got)[: len(oracle_ms)] == pytest.approx(oracle_ms, abs=0.005)
