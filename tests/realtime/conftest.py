"""Fixtures of the real-time tests: the client against an arm that takes as long as a real one.

* ``profile``: both firmware profiles; ``emu``: an emulator at ``--time-scale 1`` over a pty,
  lent by the session's pool (the plugin's ``mirobot_emulator_pool``, as tests/integration
  does); ``arm``: a client connected to it with the default timing (no knob lowered).
* ``oracle``: the vendor's firmware in its AVR simulator at real time (``run.sh -s 1``,
  tests/oracle/harness.py finds it the same way), yielding its pty path; skipped when the
  oracle is not built. The client connects to it with :meth:`Mirobot.connect` like to an arm.

Every test here is marked ``realtime`` (``python -m pytest -q -n 4 tests/realtime``): each one
waits for what a real arm takes (homing is 10-30 s), so nothing here belongs in a fast lane.
"""

from __future__ import annotations

import os
import signal
import subprocess
from collections.abc import AsyncIterator, Iterator
from pathlib import Path

import pytest

from mirobot_async import Mirobot
from mirobot_async.testing import EmulatorPool, EmulatorProcess

PROFILES = ("2021", "classic", "2024")
REPO = Path(__file__).resolve().parents[2]
_SOURCES = [
    REPO.parent / "shared" / "firmware-oracle",
    REPO.parents[1] / "shared" / "firmware-oracle",
]
ORACLE_SOURCE = Path(
    os.environ.get(
        "MIROBOT_ORACLE_SOURCE",
        str(next((path for path in _SOURCES if path.is_dir()), _SOURCES[0])),
    )
)
"""As tests/oracle/harness.py finds it (``../shared`` next to the repository), also from a
worktree one level deeper."""
_CACHE = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
ORACLE_BUILD = Path(os.environ.get("MIROBOT_ORACLE_DIR", str(_CACHE / "mirobot-firmware-oracle")))


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Every test of this directory is a real-time test; one on the firmware oracle gets one
    rerun when its failure names a hard limit (the simulator's torn switch reads:
    tests/oracle/conftest.py, TORN_SWITCH_READ)."""
    here = Path(__file__).parent
    for item in items:
        if here in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.realtime)
            if "oracle" in item.name:
                item.add_marker(pytest.mark.flaky(reruns=1, only_rerun=[r"Hard limit"]))


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


def oracle_missing() -> str | None:
    """Why the firmware oracle cannot run here (``None`` when it can)."""
    if not (ORACLE_SOURCE / "run.sh").is_file():
        return f"no firmware oracle at {ORACLE_SOURCE} (MIROBOT_ORACLE_SOURCE)"
    for name in ("fwsim", "grbl.elf", "eeprom.bin", "sys_addr"):
        if not (ORACLE_BUILD / name).is_file():
            return f"firmware oracle not built: {ORACLE_BUILD / name} missing (build.sh)"
    return None


@pytest.fixture
def oracle() -> Iterator[str]:
    """The vendor's firmware at real time (``run.sh -s 1``): yields its pty path. It powers on
    (prints its banner) when the client opens the pty; stopped with SIGTERM and reaped."""
    missing = oracle_missing()
    if missing is not None:
        pytest.skip(missing)
    env = {**os.environ, "MIROBOT_ORACLE_DIR": str(ORACLE_BUILD)}
    proc = subprocess.Popen(
        [str(ORACLE_SOURCE / "run.sh"), "-s", "1"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().decode().strip()
        assert path.startswith("/dev/"), f"the oracle printed {path!r}, not its pty"
        yield path
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()
