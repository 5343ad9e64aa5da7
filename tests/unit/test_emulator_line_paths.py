"""The emulator's per-line shortcuts give what the general code gives: a whole line arriving
with room for it enters the ring as the byte-run loop puts it, an idle planner's advance only
moves its clock, and a line whose blocks find free slots is answered as a waiting line would be."""

from __future__ import annotations

import math

from mirobot_emulator.firmware import Firmware
from mirobot_emulator.firmware._linebuffer import RX_CAPACITY, LineBuffer
from mirobot_emulator.motion import Planner


def _arrivals(data: bytes, ring_fill: int) -> tuple[bytes, list[str], int]:
    """What ``arrive`` leaves: the ring, the calls (pumps and realtime bytes) and the lost."""
    rx = LineBuffer()
    rx.put_bytes(b"x" * ring_fill)
    calls: list[str] = []
    rx.arrive(data, lambda: calls.append(f"pump {len(rx)}"), lambda b: calls.append(chr(b)))
    return bytes(rx.ring), calls, rx.lost


def test_a_whole_line_with_room_enters_the_ring_as_the_byte_runs_put_it() -> None:
    # the shortcut's case: one line, its end last, no realtime byte, room for all of it
    assert _arrivals(b"G1 X1\n", 0) == (b"G1 X1\n", ["pump 6"], 0)
    assert _arrivals(b"G1 X1\n", RX_CAPACITY - 6) == (
        b"x" * (RX_CAPACITY - 6) + b"G1 X1\n",
        [f"pump {RX_CAPACITY}"],
        0,
    )
    # not the shortcut's: the byte-run loop decides (the same rules)
    assert _arrivals(b"G1 X1\n", RX_CAPACITY - 5) == (
        b"x" * (RX_CAPACITY - 5) + b"G1 X1",  # the ring full: the line end is lost
        [f"pump {RX_CAPACITY}"],
        1,
    )
    assert _arrivals(b"G1?X1\n", 0) == (b"G1X1\n", ["pump 2", "?", "pump 5"], 0)
    assert _arrivals(b"G1\r\n", 0) == (b"G1\r\n", ["pump 3", "pump 4"], 0)
    assert _arrivals(b"G1 X1", 0) == (b"G1 X1", ["pump 5"], 0)


def test_an_idle_planner_advance_only_moves_its_clock() -> None:
    planner = Planner((0.0,) * 7)
    planner.advance(0.25)
    assert planner.clock == 0.25
    planner.advance(math.inf)  # until nothing runs: the clock stays finite
    assert planner.clock == 0.25
    assert planner.time_to_next_change() is None and not planner.busy


def test_a_line_whose_blocks_fit_is_answered_as_a_waiting_line_would_be() -> None:
    fw = Firmware("classic")
    fw.advance(1.0)
    fw.read_output()
    fw.receive(b"M50\nM21 G91\n")
    fw.advance(1.0)
    assert fw.read_output().endswith(b"ok\r\nok\r\n")
    lines = b"".join(b"G01 X1 F2000\n" for _ in range(20))  # more than the planner holds
    fw.receive(lines)
    fw.advance(0.2)
    replies = fw.read_output().split(b"\r\n")
    assert replies[:-1] == [b"ok"] * (len(replies) - 1)  # a full planner makes the rest wait
    assert fw.planner.state == "run" and len(fw.planner.blocks) == Planner.CAPACITY
    fw.advance(math.inf)
    assert fw.read_output() == b"ok\r\n" * (20 - (len(replies) - 1))
    assert not fw.planner.busy
    assert abs(fw.joints[0] - 20.0) < 0.01
