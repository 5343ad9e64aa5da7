"""The receive path takes bytes in runs (one line or one ring-full at a time) for speed: fed all
at once or byte by byte, the firmware prints the same and loses the same bytes."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
from mirobot_emulator.firmware import Firmware

PIECES = st.sampled_from(
    [
        b"G90\n",
        b"M21 G91 G1 X0.5 F2000\n",
        b"G4 P0.2\n",  # the parser waits for the planner: the ring fills, bytes are lost
        b"M3 S500\r\n",
        b"(comment) G91 ; tail\n",
        b"x" * 85 + b"\n",  # an overflowing line
        b"G21" + b" " * 100 + b"\n",
        b"?",
        b"!",
        b"~",
        b"@",
        b"\r",
        b"Q1\n",
    ]
)


def _fed(data: bytes, one_by_one: bool) -> tuple[bytes, int, int]:
    fw = Firmware("classic", homing_seconds=0.0)
    fw.receive(b"M50\n")
    fw.advance(0.01)
    fw.read_output()
    if one_by_one:
        for byte in data:
            fw.receive(bytes([byte]))
    else:
        fw.receive(data)
    out = fw.read_output()
    fw.advance(5.0)
    return out + fw.read_output(), fw.rx_lost, fw.rx_free


@settings(max_examples=60, deadline=None)
@given(st.lists(PIECES, max_size=25))
def test_a_chunk_acts_as_its_bytes_one_by_one(pieces: list[bytes]) -> None:
    data = b"".join(pieces)
    assert _fed(data, one_by_one=False) == _fed(data, one_by_one=True)


def test_bytes_are_lost_while_the_parser_waits() -> None:
    data = b"G4 P0.5\n" + b"G90\n" * 40
    whole, lost, _ = _fed(data, one_by_one=False)
    assert lost == len(data) - len(b"G4 P0.5\n") - 127
    assert (whole, lost) == _fed(data, one_by_one=True)[:2]
