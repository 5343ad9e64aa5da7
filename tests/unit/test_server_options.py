"""``ServerOptions.check()`` for the bus options: bad ones fail before anything is opened."""

from __future__ import annotations

import pytest
from mirobot_emulator.server import ServerOptions


@pytest.mark.parametrize(
    ("options", "words"),
    [
        (ServerOptions(bus=100), "1..99"),
        (ServerOptions(bus=-1), "1..99"),
        (ServerOptions(bus=2, bus_baud=1200), "bus_baud=1200"),
        (ServerOptions(bus=2, bus_options=("nonsense=1",)), "nonsense"),
        (ServerOptions(bus=2, reset_on_open=True), "reset_on_open"),
    ],
)
def test_bad_bus_options_are_refused(options: ServerOptions, words: str) -> None:
    with pytest.raises(ValueError, match=words):
        options.check()


@pytest.mark.parametrize("baud", [4800, 9600, 38400, 57600, 115200])
def test_every_controller_baud_is_accepted(baud: int) -> None:
    ServerOptions(bus=99, bus_baud=baud, bus_options=("o103=number",)).check()


def test_without_a_bus_the_bus_options_are_not_read() -> None:
    ServerOptions(bus=0, bus_baud=1200, reset_on_open=True).check()


def test_the_cli_offers_the_bauds_the_options_accept() -> None:
    from mirobot_emulator.__main__ import BUS_BAUDS as CLI_BAUDS
    from mirobot_emulator.bus import BAUD_CODES
    from mirobot_emulator.server.options import BUS_BAUDS

    assert CLI_BAUDS == BUS_BAUDS == tuple(sorted(BAUD_CODES.values()))
