"""The firmware model's transmitter: a ``?`` that arrives while a report is being printed is
merged into it (oracle boundaries, :mod:`mirobot_emulator.firmware._uart`)."""

from __future__ import annotations

import copy

import pytest
from mirobot_emulator.firmware import Firmware
from mirobot_emulator.firmware._uart import ORACLE_BYTE_SECONDS, Transmitter
from mirobot_emulator.server.clock import Simulation

from mirobot_async._client.poller import pipeline_gap


def powered_on(profile: str = "classic") -> Firmware:
    fw = Firmware(profile)
    fw.advance(0.05)
    fw.read_output()
    return fw


def reports(fw: Firmware, data: bytes, paced: bool = True) -> int:
    """How many status reports the firmware prints for ``data`` (its transmitter paced)."""
    fw.uart.byte_seconds = ORACLE_BYTE_SECONDS if paced else 0.0
    fw.receive(data)
    fw.advance(0.2)
    return fw.read_output().count(b"<")


@pytest.mark.parametrize(("gap", "expected"), [(0, 1), (60, 1), (124, 1), (125, 2), (200, 2)])
def test_a_status_request_during_a_175_byte_report_is_merged_as_on_the_firmware(
    gap: int, expected: int
) -> None:
    """Oracle: ``?`` + 124 filtered bytes + ``?`` one report, + 125 two (0.1 ms a byte)."""
    assert reports(powered_on(), b"?" + b" " * gap + b"?") == expected


@pytest.mark.parametrize(("gap", "expected"), [(150, 1), (151, 2)])
def test_a_longer_report_merges_longer_as_on_the_firmware(gap: int, expected: int) -> None:
    """Oracle: a 193-byte report (non-zero angles) merges a ``?`` up to 15.1 ms after."""
    fw = powered_on()
    fw.receive(b"M50\nM21 G90 X-50.5 Y-10.25 Z-5 A-50 B-10 C-50 F3000\n")
    fw.advance(10.0)
    assert len(fw.read_output().split(b"\r\n")[-1]) == 0
    status = fw.status_line()
    assert len(status) + 2 == 193, status
    assert reports(copy.deepcopy(fw), b"?" + b" " * gap + b"?") == expected


def test_unpaced_every_status_request_is_answered() -> None:
    assert reports(powered_on(), b"??", paced=False) == 2
    assert reports(powered_on("2021"), b"???", paced=False) == 3


def test_bytes_printed_before_a_report_delay_it_and_widen_its_window() -> None:
    """A report queued behind other output is handed to the transmit ring later."""
    alone, behind = Transmitter(), Transmitter()
    for uart in (alone, behind):
        uart.byte_seconds = ORACLE_BYTE_SECONDS
    behind.sync(100, 0.0)  # 100 bytes printed just before
    alone.report(175, 0.0)
    behind.report(175, 0.0)
    assert alone.merges(0.012) and not alone.merges(0.013)
    # 100 bytes take 9.35 ms; then the 175-byte report: handed over at 20.3 ms, not 12.6
    assert behind.merges(0.013) and behind.merges(0.020) and not behind.merges(0.021)


def test_a_soft_reset_ends_the_window() -> None:
    uart = Transmitter()
    uart.byte_seconds = ORACLE_BYTE_SECONDS
    uart.report(175, 0.0)
    assert uart.merges(0.001)
    uart.reset()
    assert not uart.merges(0.001)


def test_the_power_on_banner_does_not_hold_back_the_first_report() -> None:
    """The banner was sent before any host opened the port (the server writes it at once):
    right after power-on a report is not queued behind it."""
    fw = Firmware("classic")
    fw.read_output()
    assert reports(fw, b"?" + b" " * 140 + b"?") == 2


@pytest.mark.parametrize(("gap", "expected"), [(200, 1), (400, 1), (500, 2)])
def test_a_report_during_the_reset_banner_waits_for_it(gap: int, expected: int) -> None:
    """After ``%`` the banner keeps the transmitter busy: a ``?`` during the boot is answered
    after it, and merges a later one for longer (oracle: ``%`` + 10 bytes + ``?`` + 400 bytes
    + ``?`` one report, + 500 two)."""
    fw = powered_on()
    assert reports(fw, b"%" + b" " * 10 + b"?" + b" " * gap + b"?") == expected


def test_paced_bytes_reach_the_firmware_at_their_own_instant_however_late_the_loop_woke() -> None:
    """The server's loop woke 10 ms after the first ``?`` crossed the wire, the second crossed
    14 ms after it: the firmware sees the 14 ms (two reports), not 5 ms (one)."""
    fw = powered_on()
    sim = Simulation(fw, 1.0, 0.0, baud=115200)
    assert fw.uart.byte_seconds == pytest.approx(ORACLE_BYTE_SECONDS, rel=1e-3)
    sim.deliver(b"?", 0.0, 0.010)
    sim.deliver(b"?", 0.014, 0.015)
    sim.sync(0.2)
    assert fw.read_output().count(b"<") == 2


@pytest.mark.parametrize(("scale", "baud"), [(0.0, 115200), (0.5, 115200), (1.0, None)])
def test_the_transmitter_is_off_unless_paced_in_real_time_or_faster(
    scale: float, baud: int | None
) -> None:
    fw = powered_on()
    Simulation(fw, scale, 0.0, baud=baud)
    assert fw.uart.byte_seconds == 0.0


@pytest.mark.parametrize(
    ("length", "gap_ms"), [(100, 16.5), (175, 17.56), (190, 18.97), (300, 31.6)]
)
def test_the_client_spaces_pipelined_status_requests_by_one_report_on_the_wire(
    length: int, gap_ms: float
) -> None:
    """The client's pipelined ``?`` (a motion wait) come no sooner than the robot can print a
    report of the last one's length (93.5 us a byte): the next is never merged into it."""
    gap = pipeline_gap(length, 0.0165)
    assert gap == pytest.approx(gap_ms / 1000, abs=1e-5)
    uart = Transmitter()
    uart.byte_seconds = ORACLE_BYTE_SECONDS
    uart.report(length, 0.0)
    assert not uart.merges(gap)  # one report after the first
    uart.report(length, gap)
    assert not uart.merges(2 * gap)  # and after back-to-back ones
