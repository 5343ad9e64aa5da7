"""Homing at the arm's own speed on the other surfaces: the CLI (``home``, ``run --home``,
``move joints --home``), the blocking facade and the controller bus, each against an emulator at
``--time-scale 1`` (the switch search answers no ``?`` for 8-10 s)."""

from __future__ import annotations

import asyncio
import contextlib
import io
import os
import signal
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest
from waiting import poll_until

from mirobot_async import State
from mirobot_async._cli import main
from mirobot_async.bus import ControllerBus
from mirobot_async.sync import Mirobot as SyncMirobot
from mirobot_async.testing import EmulatorPool


@pytest.fixture
def cli(capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> Iterator[object]:
    """``mirobot ARGS`` run in this process (as tests/integration's ``cli`` fixture)."""
    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}

    def run(*args: str, stdin: str = "") -> subprocess.CompletedProcess[str]:
        capfd.readouterr()
        with monkeypatch.context() as patch:
            patch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(stdin.encode())))
            try:
                status: object = main(list(args))
            except SystemExit as exited:
                status = 0 if exited.code is None else exited.code
        out, err = capfd.readouterr()
        assert isinstance(status, int), status
        return subprocess.CompletedProcess(["mirobot", *args], status, out, err)

    try:
        yield run
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


@pytest.mark.parametrize("profile", ["2021", "classic", "2024"])
def test_cli_home_at_real_speed(
    cli: object, mirobot_emulator_pool: EmulatorPool, profile: str
) -> None:
    with mirobot_emulator_pool.lend(profile, 1.0) as emulator:
        done = cli("home", "--port", emulator.url)  # type: ignore[operator]
    assert done.returncode == 0, done.stderr
    assert "Idle" in done.stdout, done.stdout


def test_cli_run_home_at_real_speed(cli: object, mirobot_emulator_pool: EmulatorPool) -> None:
    program = "M21 G90 G0 X10 F2000\nG0 X0\n"
    with mirobot_emulator_pool.lend("classic", 1.0) as emulator:
        done = cli("run", "-", "--home", "--port", emulator.url, stdin=program)  # type: ignore[operator]
    assert done.returncode == 0, done.stderr


def test_cli_move_home_at_real_speed(cli: object, mirobot_emulator_pool: EmulatorPool) -> None:
    with mirobot_emulator_pool.lend("2021", 1.0) as emulator:
        done = cli(  # type: ignore[operator]
            "move", "joints", "j1=10", "--home", "--port", emulator.url, "--speed", "2000"
        )
    assert done.returncode == 0, done.stderr


def test_cli_embedded_run_home_at_time_scale_1(cli: object) -> None:
    done = cli(  # type: ignore[operator]
        "run",
        "-",
        "--home",
        "--time-scale",
        "1",
        "--firmware",
        "classic",
        stdin="M21 G90 G0 X5 F2000\n",
    )
    assert done.returncode == 0, done.stderr


def test_sync_facade_home(mirobot_emulator_pool: EmulatorPool) -> None:
    with (
        mirobot_emulator_pool.lend("2021", 1.0) as emulator,
        SyncMirobot.connect(emulator.url) as arm,
    ):
        report = arm.home()
        assert report.state is State.IDLE and all(abs(j) < 0.05 for j in report.joints)
        arm.move_joints(j1=5, speed=2000)


_BUS_LAUNCHER = textwrap.dedent(
    """
    import sys
    from mirobot_emulator.bus import Bus
    from mirobot_emulator.server.loop import EmulatorServer
    from mirobot_emulator.server.options import ServerOptions

    server = EmulatorServer(
        ServerOptions(time_scale=1.0), firmware_factory=lambda: Bus(2, sys.argv[1])
    )
    print(server.open(), flush=True)
    server.serve()
    """
)


@contextlib.contextmanager
def bus_emulator(directory: Path, profile: str) -> Iterator[str]:
    """Two controller+arm nodes at real speed behind one pty (tests/integration/
    test_bus_client.py starts its buses the same way); yields the pty path."""
    script = directory / "bus_launcher.py"
    script.write_text(_BUS_LAUNCHER)
    proc = subprocess.Popen(
        [sys.executable, str(script), profile], stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().strip()
        assert path, "the bus emulator did not start"
        yield path
    finally:
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
        if proc.stdout is not None:
            proc.stdout.close()


@pytest.mark.parametrize("profile", ["2021", "classic", "2024"])
async def test_bus_arm_home_at_real_speed(tmp_path: Path, profile: str) -> None:
    with bus_emulator(tmp_path, profile) as path:
        async with ControllerBus.open(path) as bus:
            arm = await bus.connect_arm(1)
            report = await arm.home()
            assert report.state is State.IDLE and all(abs(j) < 0.05 for j in report.joints)
            await arm.move_joints(j1=5, speed=2000)
            assert bus.stats.silent_nodes == 0


def test_cli_monitor_shows_an_arm_that_is_homing(
    cli: object, mirobot_emulator_pool: EmulatorPool
) -> None:
    """Another program started homing and left: the monitor opens the silent arm anyway, says
    it is probably homing, and shows the ``Home`` report its search ends with."""
    with mirobot_emulator_pool.lend("2021", 1.0) as emulator:
        fd = os.open(emulator.url, os.O_RDWR | os.O_NOCTTY)
        try:
            os.write(fd, b"$H\n")
        finally:
            os.close(fd)
        done = cli(  # type: ignore[operator]
            "monitor", "--samples", "3", "--interval", "0.2", "--port", emulator.url
        )
    assert done.returncode == 0, done.stderr
    assert "probably homing" in done.stdout, done.stdout
    assert " Home " in done.stdout, done.stdout  # the report printed when the search ended


@pytest.mark.parametrize("profile", ["2021"])
async def test_bus_controller_homing_keeps_the_arms_client(tmp_path: Path, profile: str) -> None:
    """``O105`` homes the arm by the controller: the arm answers no ``?`` meanwhile, so the
    bus holds its client's status requests back (it stays free) instead of giving it up."""
    with bus_emulator(tmp_path, profile) as path:
        async with ControllerBus.open(path) as bus:
            arm = await bus.connect_arm(1)
            other = await bus.connect_arm(2)
            homing = asyncio.create_task(bus.controller(1).home())
            try:

                async def searching() -> bool:
                    return (await bus.controller(1).arm_state()).word == "Home"

                await poll_until(searching, 20, "the controller's Home state", every=0.05)
                asking = asyncio.create_task(arm.status(timeout=60))
                assert (await other.status()).state is not None  # the bus stays free
                await homing
                report = await asking  # answered once the controller says the search is over
                assert report.state in (State.HOME, State.RUN, State.IDLE), report
                report = await arm.wait_idle()
                assert all(abs(j) < 0.05 for j in report.joints), report
            finally:
                homing.cancel()
                await asyncio.gather(homing, return_exceptions=True)
            assert bus.stats.silent_nodes == 0
            assert not arm.closed
