"""Remote arms: the real client through ser2net (RFC 2217 and raw TCP) and the emulator over TCP.

ser2net (Debian package ``ser2net``, 4.x) is started per test in front of an emulator pty, on a
free loopback port, with a configuration generated in ``tmp_path``; the client opens
``rfc2217://127.0.0.1:PORT?ign_set_control`` or ``socket://127.0.0.1:PORT``. Without ser2net
these tests skip with one line saying how to enable them; with ``MIROBOT_REQUIRE_SER2NET=1`` (CI)
the skip is a failure. The ``--listen`` tests (emulator serving TCP itself) need no ser2net.

``?ign_set_control``: ser2net answers RFC 2217 SET-CONTROL (DTR/RTS) only when the device takes
the modem-control ioctl, which a pty does not; pyserial would give up opening after 3 s without it.
A real USB-serial adapter answers, so the option is only needed (and harmless) here.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import os
import shutil
import socket
import struct
import warnings
from collections.abc import AsyncIterator, Awaitable, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from waiting import wait_until

from mirobot_async import Mirobot, MirobotConnectionError, MirobotError
from mirobot_async._client.transport import SerialLink
from mirobot_async.testing import EmulatorProcess

pytestmark = [
    pytest.mark.timeout(60),
    pytest.mark.usefixtures("no_leftover_tasks"),
    # pyserial 3.5's rfc2217 handler calls Thread.setDaemon() and .setName(), deprecated since
    # Python 3.10 (a DeprecationWarning is silent outside tests)
    pytest.mark.filterwarnings("ignore:set(Daemon|Name)\\(\\) is deprecated:DeprecationWarning"),
]

# Debian installs it in /usr/sbin, which is not on a normal user's PATH
SER2NET = shutil.which("ser2net") or shutil.which("ser2net", path="/usr/sbin:/usr/local/sbin:/sbin")
ENABLE_HINT = "ser2net is not installed; `apt-get install ser2net` enables the remote-arm tests"
KINDS = ("rfc2217", "socket")
ACCEPTERS = {"rfc2217": "telnet(rfc2217),tcp(nodelay)", "socket": "tcp(nodelay)"}
URL_OPTIONS = {"rfc2217": "?ign_set_control", "socket": ""}
HALF_STEP = 0.05  # degrees: the emulator reports whole motor steps (30 reads e.g. 29.988)
# The classic profile for wait=True moves: on 2021 the client's completion tolerance (0.01 deg)
# is finer than the emulator's step (30 reads 29.988) and wait=True times out, pty or not.
MOVES_FIRMWARE = "classic"
LINK_CUT_LIMIT = 1.0  # seconds from the cut to every pending call failing (issue 14)
STREAM_LIMIT = 15.0  # seconds for 10,000 lines (~1.5 s on an idle machine, ~6 s under load)
START_TIMEOUT = 5.0
# A second client is told the arm is in use, quoting the server (issue 14: "as a busy serial
# port would be"); the message says so whether it comes from the open or the lost link.
BUSY_WORDS = r"it is in use by another program \(could not lock it: the server says '.+'\)"


def free_port() -> int:
    """A loopback TCP port that was free a moment ago (the caller retries if it is taken)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def ser2net_config(device: str, kind: str, port: int) -> str:
    """A ser2net 4.x YAML configuration: one loopback accepter in front of ``device``.

    ``tcp(nodelay)`` matters: without it a status round trip takes ~44 ms (Nagle against
    delayed ACKs) instead of ~3 ms; ``chardelay: false`` forwards bytes as soon as they are read.
    """
    return (
        "%YAML 1.1\n---\n"
        f"connection: &arm{port}\n"
        f"  accepter: {ACCEPTERS[kind]},127.0.0.1,{port}\n"
        f"  connector: serialdev,{device},115200n81,local\n"
        "  options:\n"
        "    kickolduser: false\n"
        "    chardelay: false\n"
        "    mdns: false\n"
    )


@dataclass
class Ser2net:
    """A running ser2net process serving one device on ``url``."""

    process: asyncio.subprocess.Process
    url: str
    log: Path

    def kill(self) -> None:
        """SIGKILL ser2net now: the TCP link drops as a cut network cable or a crashed host."""
        if self.process.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                self.process.kill()


async def _stop(process: asyncio.subprocess.Process) -> None:
    """SIGTERM, then SIGKILL after 2 s (ser2net may ignore SIGTERM after a failed bind)."""
    if process.returncode is None:
        with contextlib.suppress(ProcessLookupError):
            process.terminate()
        try:
            async with asyncio.timeout(2.0):
                await process.wait()
        except TimeoutError:
            with contextlib.suppress(ProcessLookupError):
                process.kill()
    await process.wait()


async def _listening(process: asyncio.subprocess.Process, port: int, log: Path) -> bool:
    """Wait until ser2net accepts on ``port`` (True) or reports the port taken (False).

    Raises ``RuntimeError`` with ser2net's output if it exits or is not ready within
    START_TIMEOUT seconds.
    """
    async with asyncio.timeout(START_TIMEOUT):
        while True:
            output = (await asyncio.to_thread(log.read_bytes)).decode(errors="replace")
            if "Unable to startup network port" in output:
                return False  # lost the race for the free port: try another one
            if process.returncode is not None:
                raise RuntimeError(f"ser2net exited ({process.returncode}): {output.strip()}")
            with contextlib.suppress(OSError):
                _, writer = await asyncio.open_connection("127.0.0.1", port)
                writer.close()
                await writer.wait_closed()
                return True
            await asyncio.sleep(0.01)  # polling the condition "port accepts"


@contextlib.asynccontextmanager
async def run_ser2net(device: str, kind: str, workdir: Path) -> AsyncIterator[Ser2net]:
    """Run ser2net in the foreground in front of ``device``; stopped and reaped on exit."""
    assert SER2NET is not None
    for _attempt in range(3):
        port = free_port()
        config = workdir / f"ser2net-{port}.yaml"
        config.write_text(ser2net_config(device, kind, port))
        log = workdir / f"ser2net-{port}.log"
        with log.open("wb") as out:
            process = await asyncio.create_subprocess_exec(
                SER2NET,
                *("-d", "-u", "-c", str(config), "-P", str(workdir / f"ser2net-{port}.pid")),
                stdin=asyncio.subprocess.DEVNULL,
                stdout=out,
                stderr=asyncio.subprocess.STDOUT,
            )
        try:
            ready = await _listening(process, port, log)
        except BaseException:
            await _stop(process)
            raise
        if ready:
            break
        await _stop(process)
    else:
        raise RuntimeError("ser2net found no free loopback port in 3 attempts")
    url = f"{kind}://127.0.0.1:{port}{URL_OPTIONS[kind]}"
    try:
        yield Ser2net(process, url, log)
    finally:
        await _stop(process)


@pytest.fixture
def ser2net_installed() -> None:
    """Skip (or fail, with MIROBOT_REQUIRE_SER2NET=1) when ser2net is not installed."""
    if SER2NET is None:
        if os.environ.get("MIROBOT_REQUIRE_SER2NET") == "1":
            pytest.fail(f"MIROBOT_REQUIRE_SER2NET=1 but {ENABLE_HINT}")
        pytest.skip(ENABLE_HINT)


RemoteFactory = Callable[..., Awaitable[tuple[EmulatorProcess, Ser2net]]]


@pytest.fixture
async def remote(ser2net_installed: None, tmp_path: Path) -> AsyncIterator[RemoteFactory]:
    """``await remote(kind, firmware=..., time_scale=...)``: an emulator behind ser2net."""
    async with contextlib.AsyncExitStack() as stack:

        async def start(
            kind: str, firmware: str = "2021", time_scale: float = 0.0
        ) -> tuple[EmulatorProcess, Ser2net]:
            emulator = await stack.enter_async_context(
                await EmulatorProcess.start(firmware, time_scale, listen="pty")  # for ser2net
            )
            server = await stack.enter_async_context(run_ser2net(emulator.url, kind, tmp_path))
            return emulator, server

        yield start


@pytest.fixture(params=KINDS)
def kind(request: pytest.FixtureRequest) -> str:
    """The URL scheme the client uses to reach ser2net."""
    return str(request.param)


# ---- shared checks (through ser2net and straight to the TCP emulator) ----


async def check_status_and_moves(url: str) -> None:
    async with Mirobot.connect(url) as arm:
        report = await arm.status()
        assert report.state.value in ("Idle", "Alarm")
        await arm.home(timeout=10)
        await arm.move_joints(j1=30, j2=10, wait=True, timeout=10)
        report = await arm.status()
        assert report.state.value == "Idle"
        assert report.joints[0] == pytest.approx(30, abs=HALF_STEP)
        assert report.joints[1] == pytest.approx(10, abs=HALF_STEP)
        assert arm.pending_count == 0


async def check_stream(url: str, count: int) -> None:
    """``count`` lines streamed within STREAM_LIMIT s, each acknowledged once and in order."""
    lines = [f"M3 S{i % 1001}" if i % 3 else "G4 P0" for i in range(count)]
    async with Mirobot.connect(url) as arm:
        await arm.unlock()
        numbers: list[int] = []
        stream = arm.stream(lines)
        async with asyncio.timeout(STREAM_LIMIT):
            async for result in stream:
                assert result.ok, result
                assert result.line == lines[result.number - 1]
                numbers.append(result.number)
        assert numbers == list(range(1, count + 1))
        assert stream.result.ok
        assert stream.result.acknowledged == stream.result.sent == count
        assert arm.stats.replies_lost == 0 and arm.stats.protocol_violations == 0
        last_pump = max(i for i in range(count) if i % 3) % 1001
        assert (await arm.status()).pump_pwm == last_pump
        assert arm.pending_count == 0


async def check_link_cut(url: str, cut: Callable[[], None]) -> None:
    """A dwell and a line queued behind it are pending when ``cut()`` drops the link: both
    fail with a MirobotError within LINK_CUT_LIMIT, and later calls fail at once."""
    async with Mirobot.connect(url) as arm:
        await arm.unlock()
        dwell = asyncio.create_task(arm.send("G4 P20", timeout=30))
        queued = asyncio.create_task(arm.send("M3 S500", timeout=30))
        await wait_until(lambda: arm.pending_count >= 2, 5, "both lines written", every=0.001)
        loop = asyncio.get_running_loop()
        cut_at = loop.time()
        cut()
        failures: list[tuple[BaseException | None, float]] = []
        for task in (dwell, queued):
            with contextlib.suppress(MirobotError):
                async with asyncio.timeout(5):
                    await task
            failures.append((task.exception(), loop.time() - cut_at))
        for error, elapsed in failures:
            assert isinstance(error, MirobotError), error
            assert elapsed < LINK_CUT_LIMIT, f"{error!r} came {elapsed:.2f} s after the cut"
        with pytest.raises(MirobotError):
            await arm.status(timeout=LINK_CUT_LIMIT)


# ---- through ser2net ----


async def test_status_home_and_moves_through_ser2net(remote: RemoteFactory, kind: str) -> None:
    _, server = await remote(kind, firmware=MOVES_FIRMWARE)
    await check_status_and_moves(server.url)


@pytest.mark.parametrize("kind", ["rfc2217", "socket"])
async def test_stream_through_ser2net_acknowledges_each_line_once_in_order(
    remote: RemoteFactory, kind: str
) -> None:
    _, server = await remote(kind)
    await check_stream(server.url, 10_000)


@pytest.mark.parametrize("kind", ["rfc2217", "socket"])
async def test_status_polling_while_streaming_through_ser2net(
    remote: RemoteFactory, kind: str
) -> None:
    _, server = await remote(kind)
    async with Mirobot.connect(server.url) as arm:
        await arm.unlock()
        seen: list[Any] = []

        async def monitor() -> None:
            async with contextlib.aclosing(arm.statuses(interval=0.005)) as reports:
                async for report in reports:
                    seen.append(report)

        watcher = asyncio.create_task(monitor())
        try:
            async with asyncio.timeout(5):  # ~1 s on an idle machine
                result = await arm.stream(f"M3 S{i % 1001}" for i in range(1_000))
        finally:
            watcher.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await watcher
        assert result.ok and result.acknowledged == 1_000
        assert len(seen) > 5


async def test_killing_ser2net_fails_pending_calls_promptly(
    remote: RemoteFactory, kind: str
) -> None:
    _, server = await remote(kind, time_scale=1.0)
    await check_link_cut(server.url, server.kill)


async def test_arm_unplugged_behind_ser2net_fails_pending_calls_promptly(
    remote: RemoteFactory, kind: str
) -> None:
    emulator, server = await remote(kind, time_scale=1.0)
    await check_link_cut(server.url, emulator.kill)  # the pty vanishes on the remote host


async def test_second_client_through_ser2net_is_refused(remote: RemoteFactory) -> None:
    _, server = await remote("socket")
    async with Mirobot.connect(server.url) as arm:
        with pytest.raises(MirobotConnectionError, match=BUSY_WORDS):
            await Mirobot.connect(server.url, timeout=1.0)
        assert (await arm.status()).state.value in ("Idle", "Alarm")


# ---- straight to the emulator's own TCP server (issue 14 item 1, client side) ----


@pytest.fixture
async def tcp_emulator(request: pytest.FixtureRequest) -> AsyncIterator[EmulatorProcess]:
    """An emulator serving ``socket://127.0.0.1:PORT`` itself (``--listen 127.0.0.1:0``)."""
    firmware, time_scale = getattr(request, "param", ("2021", 0.0))
    emulator = await EmulatorProcess.start(firmware, time_scale, listen="tcp")
    async with emulator:
        assert emulator.url.startswith("socket://127.0.0.1:"), emulator.url
        yield emulator


@pytest.mark.parametrize("tcp_emulator", [(MOVES_FIRMWARE, 0.0)], indirect=True)
async def test_tcp_emulator_status_home_and_moves(tcp_emulator: EmulatorProcess) -> None:
    await check_status_and_moves(tcp_emulator.url)


async def test_tcp_emulator_stream(tcp_emulator: EmulatorProcess) -> None:
    await check_stream(tcp_emulator.url, 10_000)


@pytest.mark.parametrize("implementation", ["fast", "original"])
async def test_tcp_emulator_refuses_a_second_client(
    tcp_emulator: EmulatorProcess, implementation: Any
) -> None:
    """The second client is told the arm is in use, in the emulator's words, at once."""
    async with Mirobot.connect(tcp_emulator.url) as arm:
        start = asyncio.get_running_loop().time()
        with pytest.raises(MirobotConnectionError, match=BUSY_WORDS):
            await Mirobot.connect(tcp_emulator.url, timeout=5.0, implementation=implementation)
        assert asyncio.get_running_loop().time() - start < 1.0
        assert (await arm.status()).state.value in ("Idle", "Alarm")


async def test_original_implementation_releases_a_socket_the_peer_reset() -> None:
    """pyserial's socket:// close leaks the socket once the peer has reset the connection
    (its ``shutdown`` fails, its ``close`` is skipped): the link closes it, no ResourceWarning."""

    async def on_accept(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        await reader.read(1)  # the client's first byte (after pyserial's open-time flush)
        conn = writer.get_extra_info("socket")
        conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        writer.transport.abort()  # with linger 0: the client sees a reset, not a FIN

    server = await asyncio.start_server(on_accept, "127.0.0.1", 0)
    async with server:
        url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
        lost: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ResourceWarning)

            def on_lost(exc: BaseException | None) -> None:  # (exc holds the port)
                if not lost.done():
                    lost.set_result(None)

            link = await SerialLink.open(
                url,
                on_data=lambda data: None,
                on_lost=on_lost,
                implementation="original",
            )
            link.write(b"?")  # answered by a reset
            await asyncio.wait_for(lost, 5)
            await link.close()
            del link
            gc.collect()
        leaked = [w for w in caught if issubclass(w.category, ResourceWarning)]
        assert leaked == [], [str(w.message) for w in leaked]


@pytest.mark.parametrize("tcp_emulator", [("2021", 1.0)], indirect=True)
async def test_tcp_emulator_killed_fails_pending_calls_promptly(
    tcp_emulator: EmulatorProcess,
) -> None:
    await check_link_cut(tcp_emulator.url, tcp_emulator.kill)
