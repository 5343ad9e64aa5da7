"""Fixtures of the real-time tests: the client against an arm that takes as long as a real one.

* ``profile``: both firmware profiles; ``emu``: an emulator at ``--time-scale 1`` over a pty,
  lent by the session's pool (the plugin's ``mirobot_emulator_pool``, as tests/integration
  does); ``arm``: a client connected to it with the default timing (no knob lowered).

Every test here is marked ``realtime`` (``python -m pytest -q -n 4 tests/realtime``): each one
waits for what a real arm takes (homing is 10-30 s), so nothing here belongs in a fast lane.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from mirobot_async import Mirobot
from mirobot_async.testing import EmulatorPool, EmulatorProcess

PROFILES = ("2021", "classic", "2024")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Every test of this directory is a real-time test."""
    here = Path(__file__).parent
    for item in items:
        if here in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.realtime)


@pytest.fixture(params=PROFILES)
def profile(request: pytest.FixtureRequest) -> str:
    """The firmware profile under test."""
    return str(request.param)


@pytest.fixture
async def emu(profile: str, mirobot_emulator_pool: EmulatorPool) -> AsyncIterator[EmulatorProcess]:
    """An emulator of ``profile`` at real speed (1 s of motion takes 1 s)."""
    async with mirobot_emulator_pool.lend_async(profile, 1.0) as emulator:
        yield emulator


@pytest.fixture
async def arm(emu: EmulatorProcess) -> AsyncIterator[Mirobot]:
    """A client on ``emu`` with the default timing."""
    async with Mirobot.connect(emu.url) as connected:
        yield connected
