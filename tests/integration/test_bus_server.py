"""``mirobot-emulator --bus 4``: the bus model served on a real pty by the emulator process, in
place of one Firmware, driven with pyserial as the vendor SDKs do; and the ``--bus`` flags'
errors (exit status 2 before anything is opened)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest
import serial
from mirobot_emulator.__main__ import main

# the emulator as a process and its links: run on the link lanes (MIROBOT_TEST_LINK=pty|tcp)
pytestmark = [pytest.mark.timeout(60), pytest.mark.emulator_process]

MODULE = (sys.executable, "-m", "mirobot_emulator")


@pytest.fixture(scope="module")
def bus_port() -> Iterator[serial.Serial]:
    """One ``--bus 4`` emulator process for the module (the tests set their own node state)."""
    proc = subprocess.Popen(
        [*MODULE, "--bus", "4"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().decode().strip()  # the process prints it once serving
        assert path.startswith("/dev/"), (path, proc.poll())
        port = serial.serial_for_url(path, 38400, timeout=2.0)
        try:
            yield port
        finally:
            port.close()
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=10)
        assert proc.returncode == 0, err
        assert b"Traceback" not in err, err


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


def test_bus_baud_and_options_reach_the_served_bus() -> None:
    """``--bus-baud 9600 --bus-option o103=number``: the slower bus, the manual's bare O103."""
    proc = subprocess.Popen(
        [*MODULE, "--bus", "1", "--bus-baud", "9600", "--bus-option", "o103=number"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().decode().strip()
        with serial.serial_for_url(path, 9600, timeout=2.0) as port:
            reply, _ = request(port, b"@1o103\r\n", 1)
            assert reply == [b"2"]  # Alarm, as a number
            # $V's two lines and ok (~40 bytes) take ~42 ms at 9600 baud, ~10 ms at 38400
            port.reset_input_buffer()
            started = time.monotonic()
            port.write(b"@1$V\r\n")
            lines = [port.readline() for _ in range(3)]
            assert lines[-1] == b"ok\r\n", lines
            assert time.monotonic() - started >= 40 * 10 / 9600
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err


@pytest.fixture
def keep_signal_handlers() -> Iterator[None]:
    """``main()`` installs its SIGINT/SIGTERM handlers first: put pytest's back afterwards."""
    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("--bus", "100"), "--bus must be 1..99"),
        (("--bus", "-1"), "--bus must be 1..99"),
        (("--bus", "2", "--bus-baud", "1200"), "invalid choice: 1200"),
        (("--bus", "2", "--bus-option", "nonsense=1"), "bus option 'nonsense=1'"),
        (("--bus", "2", "--bus-option", "o103"), "expected KEY=VALUE"),
        (("--bus", "2", "--baud", "9600"), "the bus paces itself"),
        (("--bus", "2", "--reset-on-open"), "power-cycles every node"),
        (
            (
                "--bus-baud",
                "9600",
            ),
            "need --bus N",
        ),
        (("--bus-option", "o103=number"), "need --bus N"),
    ],
)
def test_bus_argument_errors_exit_2(
    args: tuple[str, ...],
    words: str,
    keep_signal_handlers: None,
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit) as exited:
        main(list(args))
    assert exited.value.code == 2
    out, err = capsys.readouterr()
    assert words in err and out == ""


def test_version_prints_the_package_version(
    keep_signal_handlers: None, capsys: pytest.CaptureFixture[str]
) -> None:
    from importlib.metadata import version

    with pytest.raises(SystemExit) as exited:
        main(["--version"])
    assert exited.value.code == 0
    assert capsys.readouterr().out == f"mirobot-emulator {version('mirobot-async')}\n"
