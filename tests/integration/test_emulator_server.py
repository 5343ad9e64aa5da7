"""The emulator's server beyond the happy path: bounded memory, TCP details, portability.

In-process servers (:class:`VirtualMirobot`, a thread of this process) read through their
counters (``stats``); one ``mirobot-emulator`` process is measured for its memory. Clients are
plain file descriptors and sockets that write without reading, as a hostile client would.
"""

from __future__ import annotations

import contextlib
import os
import selectors
import signal
import socket
import subprocess
import sys
import termios
import time
from collections.abc import Callable, Iterator

import psutil
import pytest
from mirobot_emulator._faults import Fault, parse_fault
from mirobot_emulator.firmware import Firmware
from mirobot_emulator.server import ServerOptions, VirtualMirobot
from mirobot_emulator.server._link import INPUT_HOLD_LIMIT, OUTPUT_HOLD_LIMIT
from mirobot_emulator.server._port import READ_CHUNK
from waiting import wait_for

# the emulator as a process and its links: run on the link lanes (MIROBOT_TEST_LINK=pty|tcp)
pytestmark = [pytest.mark.timeout(60), pytest.mark.emulator_process]

LOOPBACK = ("127.0.0.1", 0)
STATUS_LINE_MAX = 256  # a status line is ~170 bytes
# What the server may hold at most: its limit, plus the output of one read of "?" bytes.
OUTPUT_BOUND = OUTPUT_HOLD_LIMIT + READ_CHUNK * STATUS_LINE_MAX
FLOOD_CAP = 64 * 1024 * 1024  # a writer never blocked by then: the server takes everything


def stats(robot: VirtualMirobot) -> dict[str, int]:
    answer = robot.command("stats")
    assert answer.startswith("ack stats "), answer
    return {name: int(value) for name, value in (w.split("=") for w in answer.split()[2:])}


def open_like_pyserial(path: str) -> int:
    """Open the pty non-blocking, configure it and flush it, as pyserial does when opening."""
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    termios.tcsetattr(fd, termios.TCSANOW, termios.tcgetattr(fd))
    termios.tcflush(fd, termios.TCIFLUSH)
    return fd


def flood(
    write: Callable[[bytes], int],
    writable: Callable[[float], bool],
    chunk: bytes,
    blocked: Callable[[], bool],
) -> int:
    """Write ``chunk`` after ``chunk`` without reading until a write is refused while
    ``blocked()`` (the server says it stopped taking input); return the bytes written."""
    written = 0
    deadline = time.monotonic() + 30
    while written < FLOOD_CAP:
        try:
            taken = write(chunk)
        except BlockingIOError:
            taken = 0
        written += taken
        if not taken:
            if blocked():
                return written
            writable(0.05)  # the server is still reading: wait for room
        assert time.monotonic() < deadline, f"still not blocked after {written} bytes"
    raise AssertionError(f"the server took {written} bytes without blocking the writer")


def fd_writable(fd: int | socket.socket) -> Callable[[float], bool]:
    """A wait of at most ``timeout`` s for room to write to ``fd``."""

    def wait(timeout: float) -> bool:
        with selectors.DefaultSelector() as selector:
            selector.register(fd, selectors.EVENT_WRITE)
            return bool(selector.select(timeout))

    return wait


def read_until(read: Callable[[], bytes], done: Callable[[bytes], bool], timeout: float) -> bytes:
    data = b""
    deadline = time.monotonic() + timeout
    while not done(data):
        assert time.monotonic() < deadline, f"timed out; {len(data)} bytes, ends {data[-80:]!r}"
        with contextlib.suppress(BlockingIOError, TimeoutError):
            data += read()
    return data


@contextlib.contextmanager
def served(
    *,
    baud: int | None = None,
    listen: tuple[str, int] | None = None,
    faults: tuple[Fault, ...] = (),
) -> Iterator[VirtualMirobot]:
    options = ServerOptions(
        firmware="classic", time_scale=0, baud=baud, listen=listen, faults=faults
    )
    with VirtualMirobot(options) as robot:
        yield robot


# ----------------------------------------------------------------------------- bounded memory
def test_a_client_that_never_reads_is_blocked_on_a_pty() -> None:
    with served() as robot:
        fd = open_like_pyserial(robot.path)
        try:
            written = flood(
                lambda data: os.write(fd, data),
                fd_writable(fd),
                b"?" * 256,
                lambda: stats(robot)["output_held"] >= OUTPUT_HOLD_LIMIT,
            )
            held = stats(robot)
            assert held["output_held_max"] <= OUTPUT_BOUND, held
            assert written < 2 * 1024 * 1024, written  # the kernel's buffers and ours, no more
            # Nothing was dropped: once the client reads again, every "?" taken is answered.
            termios.tcflush(fd, termios.TCOFLUSH)  # the "?" not yet taken: never sent
            os.write(fd, b"\n")
            data = read_until(
                lambda: os.read(fd, 65536), lambda d: d.endswith(b"ok\r\n"), timeout=30
            )
            after = stats(robot)
            assert data.count(b"<Idle,") == after["status_requests_in"] == after["status_lines"]
            assert after["output_held_max"] <= OUTPUT_BOUND, after
        finally:
            os.close(fd)


def test_a_client_that_never_reads_is_blocked_on_tcp() -> None:
    with (
        served(listen=LOOPBACK) as robot,
        socket.create_connection(robot_address(robot), timeout=5) as sock,
    ):
        sock.setblocking(False)
        written = flood(
            sock.send,
            fd_writable(sock),
            b"?" * 4096,
            lambda: stats(robot)["output_held"] >= OUTPUT_HOLD_LIMIT,
        )
        held = stats(robot)
        assert held["output_held_max"] <= OUTPUT_BOUND, (held, written)


def test_writing_faster_than_the_baud_rate_blocks_the_writer() -> None:
    # Spaces: the firmware drops them, so the input, not the output, is what backs up.
    with served(baud=9600) as robot:
        fd = open_like_pyserial(robot.path)
        try:
            written = flood(
                lambda data: os.write(fd, data),
                fd_writable(fd),
                b" " * 4096,
                lambda: stats(robot)["input_held"] > INPUT_HOLD_LIMIT - 64,
            )
            held = stats(robot)
            assert held["input_held_max"] <= INPUT_HOLD_LIMIT, held
            assert written < 1024 * 1024, written
            assert held["bytes_in"] <= written
        finally:
            os.close(fd)


def test_the_emulator_process_memory_stays_flat_under_a_status_flood() -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "mirobot_emulator", "--time-scale", "0"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        assert proc.stdout is not None and proc.stdin is not None
        path = proc.stdout.readline().decode().strip()

        def control(text: str) -> dict[str, int]:
            assert proc.stdin is not None and proc.stdout is not None
            proc.stdin.write(text.encode() + b"\n")
            proc.stdin.flush()
            answer = proc.stdout.readline().decode().split()
            return {n: int(v) for n, v in (w.split("=") for w in answer[2:])}

        fd = open_like_pyserial(path)
        try:
            os.write(fd, b"?")
            read_until(lambda: os.read(fd, 4096), lambda d: d.endswith(b">\r\n"), timeout=10)
            before = psutil.Process(proc.pid).memory_info().rss
            flood(
                lambda data: os.write(fd, data),
                fd_writable(fd),
                b"?" * 1024,
                lambda: control("stats")["output_held"] >= OUTPUT_HOLD_LIMIT,
            )
            grown = psutil.Process(proc.pid).memory_info().rss - before
            print(f"RSS growth under a status flood: {grown / 1e6:.2f} MB")
            assert grown < 8e6
        finally:
            os.close(fd)
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert b"Traceback" not in err, err


# ----------------------------------------------------------------------------- TCP details
def robot_address(robot: VirtualMirobot) -> tuple[str, int]:
    host, port = robot.path.removeprefix("socket://").rsplit(":", 1)
    return host, int(port)


def test_tcp_split_bytes_writes_one_byte_at_a_time() -> None:
    with served(listen=LOOPBACK, faults=(parse_fault("split-bytes"),)) as robot:
        with socket.create_connection(robot_address(robot), timeout=5) as sock:
            sock.sendall(b"$$\n")
            chunks: list[bytes] = []

            def receive() -> bytes:
                chunks.append(sock.recv(4096))
                return chunks[-1]

            data = read_until(
                receive,
                lambda d: d.endswith(b"ok\r\n") and d.count(b"\n") > 20,
                timeout=20,
            )
        # one byte per write (the server's thread counts a write after it; wait for the last)
        wait_for(lambda: robot.server.split_writes >= len(data), 5, "the last write counted")
        assert robot.server.split_writes == len(data)
        # TCP cannot tell what the client read: reads coalesce bytes that arrive while the
        # reader is busy (here it shares the GIL with the server), but stay short on average
        # (unsplit, the whole dump comes in one or two reads).
        assert len(chunks) >= len(data) / 8, [len(c) for c in chunks]


def test_tcp_output_while_no_client_is_connected_is_lost_not_kept() -> None:
    with served(listen=LOOPBACK) as robot:
        assert robot.command("reset") == "ack reset"  # a banner, nobody to receive it
        assert stats(robot)["output_held"] == 0
        with socket.create_connection(robot_address(robot), timeout=5) as sock:
            sock.sendall(b"?")
            data = read_until(lambda: sock.recv(4096), lambda d: d.endswith(b">\r\n"), 5)
        assert data.startswith(b"<Idle,"), data


# ----------------------------------------------------------------------------- portability
_CRIPPLE = """
import os, sys
for name in ("fcntl", "termios", "tty", "pty"):
    sys.modules[name] = None  # import raises ImportError, as on Windows
if hasattr(os, "pipe2"):
    del os.pipe2  # as on macOS
"""

_IN_PROCESS = (
    _CRIPPLE
    + """
import importlib, pkgutil, socket
import mirobot_emulator
for info in pkgutil.walk_packages(mirobot_emulator.__path__, "mirobot_emulator."):
    importlib.import_module(info.name)
from mirobot_emulator.server import ServerOptions, VirtualMirobot
options = ServerOptions(firmware="classic", time_scale=0, listen=("127.0.0.1", 0))
with VirtualMirobot(options) as robot:
    host, port = robot.path.removeprefix("socket://").rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=5) as sock:
        sock.sendall(b"M50\\nM21 G90 G1 X10 F2000\\n?")
        data = b""
        while not data.endswith(b">\\r\\n"):
            data += sock.recv(4096)
    print(data.decode().splitlines()[-1])
    print(robot.command("stats"))
"""
)

_CLI = (
    _CRIPPLE
    + """
import runpy
sys.argv = ["mirobot-emulator", "--firmware", "classic", "--time-scale", "0", *sys.argv[1:]]
runpy.run_module("mirobot_emulator", run_name="__main__")
"""
)


def test_the_tcp_server_runs_in_process_without_posix_modules() -> None:
    proc = subprocess.run(
        [sys.executable, "-c", _IN_PROCESS], capture_output=True, timeout=30, check=False
    )
    assert proc.returncode == 0, proc.stderr.decode()
    status, stats_line = proc.stdout.decode().splitlines()[-2:]
    angles = status.removeprefix("<Idle,Angle(ABCDXYZ):").split(",")
    assert float(angles[4]) == pytest.approx(10.0, abs=0.01), status  # J1, in whole steps
    assert stats_line.startswith("ack stats ") and "ports_opened=1 " in stats_line


@pytest.mark.parametrize("args", [(), ("--listen", "127.0.0.1:0")])
def test_the_cli_serves_tcp_without_posix_modules(args: tuple[str, ...]) -> None:
    """Without ptys (``termios`` missing) TCP on the loopback is the default."""
    proc = subprocess.Popen(
        [sys.executable, "-c", _CLI, *args],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        assert proc.stdout is not None
        url = proc.stdout.readline().decode().strip()
        assert url.startswith("socket://127.0.0.1:"), (url, proc.stderr)
        host, port = url.removeprefix("socket://").rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=5) as sock:
            sock.sendall(b"?")
            data = read_until(lambda: sock.recv(4096), lambda d: d.endswith(b">\r\n"), 10)
        assert data.startswith(b"<Idle,"), data
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert b"Traceback" not in err, err


# ----------------------------------------------------------------------------- control queries
class _PlannerCounters:
    starvations = 3
    run_outs = 5
    starved_seconds = 0.25


class _FirmwareWithPlanner(Firmware):
    """The firmware model with a public planner exposing the counters (as issue 12 asks)."""

    planner = _PlannerCounters()  # type: ignore[assignment]  # a test double


class _FirmwareWithoutPlanner(Firmware):
    planner = None  # type: ignore[assignment]  # the firmware without the optional counters


def test_starvations_are_answered_from_the_planners_public_counters() -> None:
    options = ServerOptions(firmware="classic", time_scale=0)
    with VirtualMirobot(options, firmware_factory=lambda: _FirmwareWithPlanner("classic")) as robot:
        assert robot.command("starvations") == "ack starvations 3"
        counters = stats(robot)
        assert (counters["starvations"], counters["run_outs"], counters["starved_ms"]) == (
            3,
            5,
            250,
        )
        assert robot.command("starvations now").startswith("error starvations now:")
    with VirtualMirobot(
        options, firmware_factory=lambda: _FirmwareWithoutPlanner("classic")
    ) as robot:
        assert robot.command("starvations").startswith("error starvations: ")
        assert "starvations" not in stats(robot)


def test_starvations_count_the_real_planners_stops() -> None:
    """The firmware's own planner: a move after the arm stopped for want of blocks counts."""
    with served() as robot:
        assert robot.command("starvations") == "ack starvations 0"
        fd = open_like_pyserial(robot.path)
        try:

            def reply_to(line: bytes, done: Callable[[bytes], bool]) -> bytes:
                os.write(fd, line)
                return read_until(lambda: os.read(fd, 4096), done, timeout=5)

            assert b"Unlock" in reply_to(b"M50\n", lambda d: d.endswith(b"ok\r\n"))
            for target in (5, 10):  # time scale 0: each move is over before the next comes
                reply_to(f"M21 G90 G1 X{target} F2000\n".encode(), lambda d: d.endswith(b"ok\r\n"))
                assert reply_to(b"?", lambda d: d.endswith(b">\r\n")).startswith(b"<Idle,")
        finally:
            os.close(fd)
        assert robot.command("starvations") == "ack starvations 1"
        counters = stats(robot)
        assert counters["starvations"] == 1 and counters["run_outs"] == 2, counters
