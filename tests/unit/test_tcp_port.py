"""The emulator's TCP port refuses a second client as a busy serial port: one line, then the end.

Driven by hand (no serve loop): the port is told which socket is ready, as the loop would.
"""

from __future__ import annotations

import selectors
import socket
import time
from collections.abc import Iterator

import pytest
from mirobot_emulator.server._port import OPEN_SETTLE_S
from mirobot_emulator.server._tcp_port import BUSY_MESSAGE, REFUSED_LINGER_S, TcpPort


def ready(port: TcpPort, timeout: float = 5.0) -> None:
    """Wait until a watched socket is readable and hand every ready one to the port."""
    with selectors.DefaultSelector() as selector:
        for fileobj, events in port.watches(read=True, write=False).items():
            selector.register(fileobj, events)
        found = selector.select(timeout)
        assert found, "nothing became ready"
        for key, events in found:
            port.on_ready(key.fileobj, events, room=4096)


def read_to_end(sock: socket.socket) -> bytes:
    """Everything until the end of the stream (a reset raises ConnectionResetError)."""
    sock.settimeout(5)
    data = b""
    while chunk := sock.recv(4096):
        data += chunk
    return data


@pytest.fixture
def served() -> Iterator[tuple[TcpPort, socket.socket]]:
    """A listening port with its first client accepted."""
    port = TcpPort("127.0.0.1", 0)
    url = port.open()
    address = ("127.0.0.1", int(url.rsplit(":", 1)[1]))
    first = socket.create_connection(address, timeout=5)
    try:
        ready(port)
        assert port.has_client
        yield port, first
    finally:
        first.close()
        port.close()


def second_client(port: TcpPort) -> socket.socket:
    assert port.address is not None
    host, number = port.address.removeprefix("socket://").rsplit(":", 1)
    return socket.create_connection((host, int(number)), timeout=5)


def test_a_second_client_that_writes_first_gets_the_line_and_an_end_not_a_reset(
    served: tuple[TcpPort, socket.socket],
) -> None:
    port, _ = served
    with second_client(port) as second:
        second.sendall(b"?")  # unread bytes: closing at once would reset the connection
        ready(port)  # accepted and refused
        assert port.refused == 1
        ready(port)  # its "?": its open is over, it is told
        assert read_to_end(second) == BUSY_MESSAGE
    assert port.has_client  # the first client is still served


def test_a_silent_second_client_is_told_when_its_open_is_over(
    served: tuple[TcpPort, socket.socket],
) -> None:
    port, _ = served
    with second_client(port) as second:
        ready(port)
        start = time.monotonic()
        due = port.next_time()
        assert due is not None and due <= start + OPEN_SETTLE_S
        second.settimeout(0)
        with pytest.raises(BlockingIOError):
            second.recv(1)  # nothing yet: pyserial's open would flush it away
        port.poll(start + OPEN_SETTLE_S)
        assert read_to_end(second) == BUSY_MESSAGE


def test_a_refused_client_that_never_closes_is_closed_after_the_linger(
    served: tuple[TcpPort, socket.socket],
) -> None:
    port, _ = served
    with second_client(port) as second:
        ready(port)
        now = time.monotonic()
        port.poll(now + OPEN_SETTLE_S)  # told
        assert port.next_time() == pytest.approx(now + REFUSED_LINGER_S, abs=0.5)
        port.poll(now + REFUSED_LINGER_S + 1)  # closed by the port
        assert port.next_time() is None
        assert read_to_end(second) == BUSY_MESSAGE
