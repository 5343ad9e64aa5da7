"""The emulator's per-line shortcuts give what the general code gives: a line read in one pass
has the words (and the status) of the word-by-word reading, a whole line arriving with room for
it enters the ring as the byte-run loop puts it, an idle planner's advance only moves its clock,
and a line whose blocks find free slots is answered as a waiting line would be."""

from __future__ import annotations

import math
import random

from mirobot_emulator.firmware import Firmware
from mirobot_emulator.firmware.linebuffer import RX_CAPACITY, LineBuffer
from mirobot_emulator.firmware.scanner import GBlock, _Groups, _scan, _scan_by_position
from mirobot_emulator.motion import Planner

_LETTERS = "GMXYZFSEABCDNPIJKRLT"
_NUMBERS = ["", "-", "+", "0", "-0", "1", "21", "20", "90", "91", "3", "4", "5", "92.1",
            "0.5", "1.", "-.", ".25", "-0.000", "123456789.5", "00000000012.3", "7.999999999",
            "43.1", "28.1", "0.001", "255.999", "256"]  # fmt: skip


def test_a_line_read_in_one_pass_has_the_words_of_the_word_by_word_reading() -> None:
    rng = random.Random(11)
    for _ in range(20000):
        words = []
        for _ in range(rng.randint(1, 6)):
            number = rng.choice(_NUMBERS)
            if rng.random() < 0.3:
                number = f"{rng.uniform(-500, 500):.{rng.randint(0, 9)}f}"
            words.append(rng.choice(_LETTERS) + number)
        line = "".join(words)
        for profile in ("classic", "2021"):
            fast, fast_status = _scan(line, profile)
            slow, slow_status = _scan_by_position(line, profile, GBlock(), _Groups())
            assert fast_status == slow_status, line
            assert vars(fast) == vars(slow), line
            for letter, value in fast.words.items():  # signed zeros alike
                assert math.copysign(1.0, value) == math.copysign(1.0, slow.words[letter])


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
