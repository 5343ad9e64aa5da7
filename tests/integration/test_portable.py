"""The client, the CLI and the pytest plugin need no Linux-only module (issue 14 item 2).

Each check runs in a fresh interpreter where ``fcntl``, ``termios``, ``tty`` and ``pty`` cannot
be imported (as on Windows) and ``os.pipe2`` does not exist (as on macOS). pyserial and
pyserial-asyncio-fast are imported first, with the real modules: they pick their own backend per
platform (``serialwin32`` on Windows), so what is checked is that nothing of ours reaches for a
POSIX-only module. Then every module of ``mirobot_async`` is imported, and the client and the CLI
(``--port socket://...``) talk to an emulator served over TCP.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator

import pytest

from mirobot_async.testing import EmulatorPool, SyncEmulatorProcess

_CRIPPLE = """
import os, sys
import serial, serial.rfc2217, serial.tools.list_ports, serial.urlhandler.protocol_socket
import serial_asyncio_fast
for name in ("fcntl", "termios", "tty", "pty"):
    sys.modules[name] = None  # import raises ImportError, as on Windows
if hasattr(os, "pipe2"):
    del os.pipe2  # as on macOS
"""

_CLIENT = (
    _CRIPPLE
    + """
import asyncio, importlib, pkgutil
import mirobot_async
names = [
    info.name
    for info in pkgutil.walk_packages(mirobot_async.__path__, "mirobot_async.")
    if not info.name.endswith("__main__")
    # optional extras: their third-party SDKs carry their own platform support
    and not info.name.startswith(("mirobot_async._mcp_server", "mirobot_async._view"))
]
for name in names:
    importlib.import_module(name)
print("imported", len(names))

from mirobot_async import Mirobot

async def main(url):
    async with Mirobot.connect(url) as arm:
        await arm.unlock()
        await arm.move_joints(j1=10, wait=True, timeout=10)
        stream = arm.stream(["M3 S1", "G4 P0", "M3 S0"])
        async for result in stream:
            assert result.ok, result
        report = await arm.status()
        print("state", report.state.value, round(report.joints[0]))

asyncio.run(main(sys.argv[1]))
"""
)

_CLI = (
    _CRIPPLE
    + """
import runpy
sys.argv = ["mirobot", *sys.argv[1:]]
runpy.run_module("mirobot_async", run_name="__main__")
"""
)


def crippled(script: str, *args: str) -> subprocess.CompletedProcess[str]:
    """Run ``script`` in a fresh interpreter without the POSIX-only modules."""
    return subprocess.run(
        [sys.executable, "-c", script, *args],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


@pytest.fixture(scope="module")
def tcp_emulator(mirobot_emulator_pool: EmulatorPool) -> Iterator[SyncEmulatorProcess]:
    """A classic-profile emulator on a loopback TCP port (shared: every check reads its state),
    lent by the session's pool of emulator processes."""
    with mirobot_emulator_pool.lend("classic", 0.0, listen="tcp") as emulator:
        yield emulator


@pytest.mark.parametrize("check", ["import fcntl", "import termios", "import tty", "os.pipe2"])
def test_the_poison_works(check: str) -> None:
    proc = crippled(_CRIPPLE + check)
    assert proc.returncode != 0
    assert "ModuleNotFoundError" in proc.stderr or "has no attribute 'pipe2'" in proc.stderr


def test_client_imports_and_talks_over_tcp(tcp_emulator: SyncEmulatorProcess) -> None:
    proc = crippled(_CLIENT, tcp_emulator.url)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("imported ") and int(lines[0].split()[1]) > 30
    assert lines[-1] == "state Idle 10"


def test_cli_talks_over_tcp(tcp_emulator: SyncEmulatorProcess) -> None:
    # --unlock: the shared arm may not have been unlocked by the client test (another worker)
    proc = crippled(_CLI, "move", "joints", "j2=5", "--unlock", "--port", tcp_emulator.url)
    assert proc.returncode == 0, proc.stderr
    proc = crippled(_CLI, "status", "--port", tcp_emulator.url)
    assert proc.returncode == 0, proc.stderr
    assert "Idle" in proc.stdout
