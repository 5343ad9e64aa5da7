"""The bus model served on a real pty by the emulator's server, in place of one Firmware
(what ``mirobot-emulator --bus N`` will do), driven with pyserial as the vendor SDKs do."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest
import serial
from mirobot_emulator.bus import Bus

background = pytest.importorskip("mirobot_emulator.server.background")
server_options = pytest.importorskip("mirobot_emulator.server.options")

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(scope="module")
def bus_port() -> Iterator[serial.Serial]:
    options = server_options.ServerOptions(time_scale=1.0)
    with background.VirtualMirobot(options, firmware_factory=lambda: Bus(4)) as robot:
        port = serial.serial_for_url(robot.path, 38400, timeout=2.0)
        try:
            yield port
        finally:
            port.close()


def request(port: serial.Serial, line: bytes, lines: int) -> tuple[list[bytes], float]:
    """Write ``line``; read ``lines`` reply lines; return them and the first byte's delay."""
    port.reset_input_buffer()
    started = time.monotonic()
    port.write(line)
    first = port.read(1)
    delay = time.monotonic() - started
    data = first + b"".join(port.readline() for _ in range(lines))
    return data.split(b"\r\n")[:lines], delay


def test_each_address_answers_for_itself(bus_port: serial.Serial) -> None:
    for address in (1, 2, 3, 4):
        bus_port.write(f"@{address}o150=arm{address}\r\n".encode())
        assert bus_port.readline() == b"ok\r\n"
    for address in (1, 2, 3, 4):
        reply, delay = request(bus_port, f"@0{address}o150?\r\n".encode(), 1)
        assert reply == [f"arm{address}".encode()]
        assert delay < 0.5  # the model's is ~4 ms; the wall clock of a loaded machine varies


def test_status_and_version_through_the_controller(bus_port: serial.Serial) -> None:
    reply, _ = request(bus_port, b"@3?\r\n", 3)
    assert reply[0].startswith(b"<") and reply[1:] == [b"ok", b"ok"]
    reply, _ = request(bus_port, b"@2$V\r\n", 3)
    assert reply == [b"EXbox 20210410", b"Mirobot 20210516", b"ok"]


def test_an_absent_address_stays_silent(bus_port: serial.Serial) -> None:
    bus_port.reset_input_buffer()
    bus_port.write(b"@9?\r\n")
    bus_port.timeout = 0.3
    try:
        assert bus_port.read(1) == b""
    finally:
        bus_port.timeout = 2.0
