"""The firmware model's transmitter: a ``?`` that arrives while a report is being printed is
merged into it (oracle boundaries, :mod:`mirobot_emulator.firmware.uart`)."""

from __future__ import annotations

import copy

import pytest
from mirobot_emulator.firmware import Firmware
from mirobot_emulator.firmware.uart import ORACLE_BYTE_SECONDS, Transmitter


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
def test_a_status_request_during_a_175_byte_report_is_merged_as_on_the_oracle(
    gap: int, expected: int
) -> None:
    """Oracle: ``?`` + 124 filtered bytes + ``?`` one report, + 125 two (0.1 ms a byte)."""
    assert reports(powered_on(), b"?" + b" " * gap + b"?") == expected


@pytest.mark.parametrize(("gap", "expected"), [(150, 1), (151, 2)])
def test_a_longer_report_merges_longer_as_on_the_oracle(gap: int, expected: int) -> None:
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
