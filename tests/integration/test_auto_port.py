"""Finding the arm (issue 14 item 4): :func:`find_mirobot`, ``Mirobot.connect("auto")`` and the
CLI's ``--auto`` / ``MIROBOT_PORT``, against emulators (pty and TCP), a port that answers garbage,
a silent one, and a recording fake Mirobot that proves the probe sends only ``?`` and ``$$``."""

from __future__ import annotations

import contextlib
import logging
import os
import socket
import subprocess
import threading
from collections.abc import Callable, Iterator

import pytest
import serial.tools.list_ports
from serial.tools.list_ports_common import ListPortInfo

from mirobot_async import Mirobot, MirobotConnectionError
from mirobot_async._client.ports import AUTO_PORTS_ENV, find_mirobot
from mirobot_async.testing import EmulatorPool, SyncEmulatorProcess

# the emulator as a process and its links: run on the link lanes (MIROBOT_TEST_LINK=pty|tcp)
pytestmark = pytest.mark.emulator_process

PROBE = 0.5  # seconds a probe of a port that never answers a status takes
STATUS = (
    b"<Idle,Angle(ABCDXYZ):0.000,0.000,0.000,0.000,0.000,0.000,0.000,"
    b"Cartesian coordinate(XYZ RxRyRz):198.670,0.000,230.720,0.000,0.000,0.000,"
    b"Pump PWM:0,Valve PWM:0,Motion_MODE:0>\r\n"
)


class FakePort:
    """A loopback TCP "serial port" (``socket://``) answering with ``reply(received)``; it
    records every byte it received."""

    def __init__(self, reply: Callable[[bytes], bytes]) -> None:
        self._reply = reply
        self.received = bytearray()
        self._server = socket.create_server(("127.0.0.1", 0))
        self.url = f"socket://127.0.0.1:{self._server.getsockname()[1]}"
        self._threads: list[threading.Thread] = []
        self._clients: list[socket.socket] = []
        self._closing = threading.Event()
        self._accepting = threading.Thread(target=self._accept, daemon=True)
        self._accepting.start()

    def _accept(self) -> None:
        with contextlib.suppress(OSError):
            while True:
                client, _ = self._server.accept()
                if self._closing.is_set():
                    client.close()
                    return
                self._clients.append(client)
                thread = threading.Thread(target=self._serve, args=(client,), daemon=True)
                self._threads.append(thread)
                thread.start()

    def _serve(self, client: socket.socket) -> None:
        with contextlib.suppress(OSError), client:
            while chunk := client.recv(4096):
                self.received += chunk
                answer = self._reply(chunk)
                if answer:
                    client.sendall(answer)

    def close(self) -> None:
        self._closing.set()
        with contextlib.suppress(OSError):  # wakes accept() (closing the socket does not)
            socket.create_connection(self._server.getsockname(), timeout=1).close()
        self._accepting.join(5)
        self._server.close()
        for client in self._clients:
            with contextlib.suppress(OSError):
                client.shutdown(socket.SHUT_RDWR)
        for thread in self._threads:
            thread.join(5)


@contextlib.contextmanager
def fake_port(reply: Callable[[bytes], bytes]) -> Iterator[FakePort]:
    port = FakePort(reply)
    try:
        yield port
    finally:
        port.close()


def fake_mirobot(chunk: bytes) -> bytes:
    """Answers ``?`` with a status and ``$$`` with a 2021-style listing."""
    answer = b""
    if b"?" in chunk:
        answer += STATUS
    if b"$$" in chunk:
        answer += b"$0=10\r\n$29=0\r\nok\r\n"
    return answer


@pytest.fixture(scope="module")
def emulators(
    mirobot_emulator_pool: EmulatorPool,
) -> Iterator[tuple[SyncEmulatorProcess, SyncEmulatorProcess]]:
    """A pty emulator and a TCP one (shared: probing changes nothing on them), lent by the
    session's pool of emulator processes."""
    listen = "pty" if os.name == "posix" else "tcp"
    pool = mirobot_emulator_pool
    with pool.lend("classic", listen=listen) as first, pool.lend("2021", listen="tcp") as tcp:
        yield first, tcp


def test_the_one_mirobot_among_garbage_and_silence_is_chosen(
    emulators: tuple[SyncEmulatorProcess, SyncEmulatorProcess], caplog: pytest.LogCaptureFixture
) -> None:
    first, _ = emulators
    with (
        fake_port(lambda _: b"\x00\xffgarbage\r\nok\r\n") as garbage,
        fake_port(lambda _: b"") as silent,
    ):
        with caplog.at_level(logging.INFO, logger="mirobot_async.ports"):
            chosen = find_mirobot([garbage.url, first.url, silent.url], timeout=PROBE)
        assert chosen == first.url
        assert f"auto: using {first.url}" in caplog.text
        assert set(garbage.received) <= set(b"?") and garbage.received  # asked, nothing else


def test_several_mirobots_are_refused_and_listed(
    emulators: tuple[SyncEmulatorProcess, SyncEmulatorProcess],
) -> None:
    first, tcp = emulators
    with pytest.raises(MirobotConnectionError, match="2 Mirobots answer") as info:
        find_mirobot([first.url, tcp.url], timeout=PROBE)
    assert first.url in str(info.value) and tcp.url in str(info.value)
    assert "firmware classic" in str(info.value) and "firmware 2021" in str(info.value)


def test_no_mirobot_says_what_each_port_did() -> None:
    with (
        fake_port(lambda _: b"hello\r\n") as garbage,
        fake_port(lambda _: b"") as silent,
        pytest.raises(MirobotConnectionError, match="no Mirobot answered") as info,
    ):
        find_mirobot([garbage.url, silent.url], timeout=PROBE)
    text = str(info.value)
    assert f"{garbage.url} (-): not a Mirobot (answers something else" in text
    assert f"{silent.url} (-): not a Mirobot (silent" in text
    with pytest.raises(MirobotConnectionError, match="no serial ports found"):
        find_mirobot([], timeout=PROBE)


def test_the_probe_sends_only_status_and_settings_requests() -> None:
    with fake_port(fake_mirobot) as arm:
        assert find_mirobot([arm.url], timeout=PROBE) == arm.url
    sent = bytes(arm.received)
    assert sent.replace(b"?", b"").replace(b"$$\n", b"") == b"", sent
    assert b"?" in sent


async def test_connect_auto_uses_the_found_port(
    emulators: tuple[SyncEmulatorProcess, SyncEmulatorProcess], monkeypatch: pytest.MonkeyPatch
) -> None:
    _, tcp = emulators
    with fake_port(lambda _: b"garbage\r\n") as garbage:
        monkeypatch.setenv(AUTO_PORTS_ENV, f"{garbage.url},{tcp.url}")
        async with Mirobot.connect("auto", timeout=1.0) as arm:
            assert (await arm.status()).state.value in ("Idle", "Alarm")


async def test_connect_auto_without_a_mirobot_fails(monkeypatch: pytest.MonkeyPatch) -> None:
    with fake_port(lambda _: b"garbage\r\n") as garbage:
        monkeypatch.setenv(AUTO_PORTS_ENV, garbage.url)
        with pytest.raises(MirobotConnectionError, match="no Mirobot answered"):
            await Mirobot.connect("auto", timeout=PROBE)


Cli = Callable[..., subprocess.CompletedProcess[str]]


def test_cli_auto_and_mirobot_port_env(
    emulators: tuple[SyncEmulatorProcess, SyncEmulatorProcess], cli: Cli
) -> None:
    first, tcp = emulators
    one = {AUTO_PORTS_ENV: tcp.url}
    proc = cli("status", "--auto", env=one)
    assert proc.returncode == 0, proc.stderr
    assert f"auto: using {tcp.url}" in proc.stderr
    assert "embedded" not in proc.stderr
    proc = cli("status", env={**one, "MIROBOT_PORT": "auto"})
    assert proc.returncode == 0, proc.stderr
    assert f"auto: using {tcp.url}" in proc.stderr
    proc = cli("status", env={"MIROBOT_PORT": tcp.url})
    assert proc.returncode == 0 and "embedded" not in proc.stderr, proc.stderr
    both = {AUTO_PORTS_ENV: f"{first.url}, {tcp.url}"}
    proc = cli("status", "--auto", env=both)
    assert proc.returncode == 2, proc.stderr
    assert "2 Mirobots answer" in proc.stderr and "Traceback" not in proc.stderr


def test_ports_with_a_mirobot_usb_chip_are_probed_first(
    emulators: tuple[SyncEmulatorProcess, SyncEmulatorProcess], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two Mirobots listed, one behind a CH340 (1a86:7523): that one is chosen and the other is
    not even opened (a USB match settles it); without the match both answer and it refuses."""
    _, tcp = emulators
    with fake_port(fake_mirobot) as other:
        ch340 = ListPortInfo(tcp.url, skip_link_detection=True)
        ch340.vid, ch340.pid, ch340.description = 0x1A86, 0x7523, "USB-SERIAL CH340"
        plain = ListPortInfo(other.url, skip_link_detection=True)
        monkeypatch.delenv(AUTO_PORTS_ENV, raising=False)
        monkeypatch.setattr(serial.tools.list_ports, "comports", lambda: [plain, ch340])
        assert find_mirobot(timeout=PROBE) == tcp.url
        assert other.received == b""
        ch340.vid = ch340.pid = None
        with pytest.raises(MirobotConnectionError, match="2 Mirobots answer") as info:
            find_mirobot(timeout=PROBE)
        assert "USB-SERIAL CH340" in str(info.value)
        assert other.received
