"""``bus.connect(url, address=N)``: an arm behind a multi-robot controller on a bus emulator
(the launcher approach of ``test_bus_client.py``: a real emulator process on a real pty)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest

from mirobot_async import State, bus
from mirobot_async.bus import NodeSilentError

pytestmark = pytest.mark.timeout(60)

_LAUNCHER = textwrap.dedent(
    """
    import sys
    from mirobot_emulator.bus import Bus
    from mirobot_emulator.server.loop import EmulatorServer
    from mirobot_emulator.server.options import ServerOptions

    nodes = int(sys.argv[1])
    server = EmulatorServer(
        ServerOptions(time_scale=0.0),
        firmware_factory=lambda: Bus(nodes, "2021", homing_seconds=0.1),
    )
    print(server.open(), flush=True)
    server.serve()
    """
)


@pytest.fixture
def bus_path(tmp_path: Path) -> Iterator[str]:
    """A 2-node bus emulator process; its pty path."""
    script = tmp_path / "bus_launcher.py"
    script.write_text(_LAUNCHER)
    process = subprocess.Popen(
        [sys.executable, str(script), "2"], stdout=subprocess.PIPE, text=True
    )
    try:
        assert process.stdout is not None
        path = process.stdout.readline().strip()
        assert path, "the bus emulator did not start"
        yield path
    finally:
        process.terminate()
        try:
            process.wait(5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(5)
        if process.stdout is not None:
            process.stdout.close()


async def test_connect_with_an_address_reaches_that_arm(bus_path: str) -> None:
    async with bus.connect(bus_path, address=2) as arm:
        await arm.unlock()
        report = await arm.move_joints(j1=12, speed=2000)
        assert report is not None and report.state is State.IDLE
        assert report.joints[0] == pytest.approx(12, abs=0.05)
    async with bus.connect(bus_path, address=1) as other:
        assert (await other.status()).joints[0] == pytest.approx(0, abs=0.05)


async def test_connect_to_a_missing_address_names_it(bus_path: str) -> None:
    with pytest.raises(NodeSilentError):
        async with bus.connect(bus_path, address=7, timeout=2):
            pass


async def test_connect_with_an_address_records_that_arms_tape(
    bus_path: str, tmp_path: Path
) -> None:
    from mirobot_async._tapes.format import Written, read_tapes

    path = tmp_path / "bus.jsonl"
    async with bus.connect(bus_path, address=2, record=path) as arm:
        await arm.unlock()
    [tape] = read_tapes(path)
    assert tape.header["link"] == "bus" and tape.header["source"] == "device"
    written = b"".join(e.data for e in tape.events if isinstance(e, Written))
    assert b"M50\n" in written and b"@" not in written  # the arm's lines, not the bus's frames
    assert bus_path not in path.read_text()
