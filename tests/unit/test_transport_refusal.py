"""A network server's "busy" line before the end of the stream is a connection error quoting it."""

from __future__ import annotations

from typing import Any

import pytest

from mirobot_async._client.transport import refusal_error
from mirobot_async._client.wire import ClientStats, Wire
from mirobot_async.errors import MirobotConnectionError

URL = "socket://127.0.0.1:4000"


@pytest.mark.parametrize(
    "said",
    [
        b"mirobot-emulator: port busy: another client is connected\r\n",
        b"Port already in use\r\n",  # ser2net
        b"\r\nPort already in use\r\n",
    ],
)
def test_a_busy_line_then_the_end_is_a_busy_port(said: bytes) -> None:
    error = refusal_error(URL, said)
    assert isinstance(error, MirobotConnectionError)
    words = said.decode().strip()
    assert str(error) == (
        f"could not open {URL!r}: it is in use by another program "
        f"(could not lock it: the server says {words!r})"
    )


@pytest.mark.parametrize(
    "said",
    [
        b"",  # a plain end of the stream
        b"ok\r\n",  # the robot talking
        b"<Idle,Angle(ABCDXYZ):0.000>\r\n",
        b"Grbl 0.9j ['$' for help]\r\nbusy\r\n",  # more than one line
        b"x" * 300 + b" busy\r\n",  # too long to be a refusal
        b"connection closed\r\n",  # no word of being busy
    ],
)
def test_anything_else_is_not_a_refusal(said: bytes) -> None:
    assert refusal_error(URL, said) is None


@pytest.mark.parametrize("url", ["/dev/ttyUSB0", "loop://", "COM3"])
def test_only_network_links_have_a_server_to_refuse(url: str) -> None:
    assert refusal_error(url, b"port busy\r\n") is None


def test_rfc2217_is_a_network_link() -> None:
    assert refusal_error("rfc2217://host:2217", b"Port already in use\r\n") is not None


async def test_the_wire_keeps_a_transport_s_refusal_and_still_reports_the_loss() -> None:
    """``Wire.refusal``: what the client raises for a connect whose link a server refused."""
    seen: list[BaseException | None] = []
    refused = MirobotConnectionError("could not open 'socket://h:1': it is in use")
    callbacks: dict[str, Any] = {}

    class Opened:
        def write(self, data: bytes) -> None: ...
        def abort(self) -> None: ...
        async def close(self) -> None: ...

    # the TransportOpener signature names its timeout
    async def opener(url: str, *, on_data: Any, on_lost: Any, timeout: float) -> Opened:  # noqa: ASYNC109
        callbacks["lost"] = on_lost
        return Opened()

    wire = Wire(ClientStats())
    await wire.open("socket://h:1", opener, on_data=lambda d: None, on_lost=seen.append, timeout=1)
    assert wire.refusal is None
    callbacks["lost"](None)  # a plain end of file is no refusal
    assert wire.refusal is None
    callbacks["lost"](refused)
    assert wire.refusal is refused
    assert seen == [None, refused]
