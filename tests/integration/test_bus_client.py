"""The controller-bus client (issue 16) against the bus emulator: 4 controller+arm nodes behind
one real pty, served by a real emulator process (the server built with ``firmware_factory``
until ``mirobot-emulator --bus N`` exists), driven by :class:`mirobot_async.bus.ControllerBus`
and, for its controller features, by the vendor's ``wlkatapython``."""

from __future__ import annotations

import asyncio
import importlib.util
import os
import subprocess
import sys
import textwrap
import time
from collections.abc import AsyncIterator, Iterator
from pathlib import Path

import pytest
import serial
from waiting import wait_until

from mirobot_async import (
    MirobotCommandError,
    MirobotLinkLostError,
    MirobotTimeoutError,
    MirobotUsageError,
)
from mirobot_async.bus import (
    BusTiming,
    ControllerBus,
    ControllerCommandError,
    NodeSilentError,
    connect,
)

pytestmark = pytest.mark.timeout(60)

NODES = 4

_LAUNCHER = textwrap.dedent(
    """
    import sys
    from mirobot_emulator.bus import Bus
    from mirobot_emulator.server.loop import EmulatorServer
    from mirobot_emulator.server.options import ServerOptions

    nodes, scale, homing = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
    profile = sys.argv[4]
    server = EmulatorServer(
        ServerOptions(time_scale=scale),
        firmware_factory=lambda: Bus(nodes, profile, homing_seconds=homing),
    )
    print(server.open(), flush=True)
    server.serve()
    """
)


class BusEmulator:
    """A bus emulator process on a real pty: ``path`` to open, stopped by :meth:`stop`."""

    def __init__(
        self,
        directory: Path,
        nodes: int,
        time_scale: float,
        homing: float,
        profile: str = "2021",
    ) -> None:
        script = directory / "bus_launcher.py"
        script.write_text(_LAUNCHER)
        self.process = subprocess.Popen(
            [sys.executable, str(script), str(nodes), str(time_scale), str(homing), profile],
            stdout=subprocess.PIPE,
            text=True,
        )
        assert self.process.stdout is not None
        self.path = self.process.stdout.readline().strip()
        if not self.path:
            self.stop()
            raise RuntimeError("the bus emulator did not start")

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(5)
        if self.process.stdout is not None:
            self.process.stdout.close()


PACED = 4.0
"""Time scale of the buses whose tests time the arms' motion against the bus's traffic."""
FAST = 20.0
"""Time scale of the buses whose tests only wait for motion to end (homing, files, streams):
an arm's 18-block planner still holds ~0.6 s of wall time, more than any pause under load."""


@pytest.fixture(scope="module")
def shared_bus(tmp_path_factory: pytest.TempPathFactory) -> Iterator[BusEmulator]:
    """One paced 4-node bus emulator for the tests whose state does not matter to each other
    and whose motion must outlast what they do meanwhile."""
    emulator = BusEmulator(tmp_path_factory.mktemp("bus"), NODES, PACED, 0.3)
    try:
        yield emulator
    finally:
        emulator.stop()


@pytest.fixture(scope="module")
def fast_bus(tmp_path_factory: pytest.TempPathFactory) -> Iterator[BusEmulator]:
    """One fast 4-node bus emulator for the tests whose state does not matter to each other and
    that only wait for motion to end."""
    emulator = BusEmulator(tmp_path_factory.mktemp("bus"), NODES, FAST, 0.3)
    try:
        yield emulator
    finally:
        emulator.stop()


@pytest.fixture
def own_bus(tmp_path: Path) -> Iterator[BusEmulator]:
    """A fresh paced 4-node bus emulator for a test that breaks it while an arm moves."""
    emulator = BusEmulator(tmp_path, NODES, PACED, 0.3)
    try:
        yield emulator
    finally:
        emulator.stop()


@pytest.fixture
def own_fast_bus(tmp_path: Path) -> Iterator[BusEmulator]:
    """A fresh fast 4-node bus emulator for a test that reconfigures it."""
    emulator = BusEmulator(tmp_path, NODES, FAST, 0.3)
    try:
        yield emulator
    finally:
        emulator.stop()


@pytest.fixture
async def bus(fast_bus: BusEmulator) -> AsyncIterator[ControllerBus]:
    async with ControllerBus.open(fast_bus.path) as opened:
        yield opened


@pytest.fixture
async def paced_bus(shared_bus: BusEmulator) -> AsyncIterator[ControllerBus]:
    async with ControllerBus.open(shared_bus.path) as opened:
        yield opened


async def test_each_arm_answers_for_itself(bus: ControllerBus) -> None:
    arms = [await bus.connect_arm(n) for n in range(1, NODES + 1)]
    for n in range(1, NODES + 1):
        await bus.controller(n).set_pin_modes(D1=3)  # PWM out
        await bus.controller(n).write_pins(D1=n)  # a per-node mark, read back below
    reports = await asyncio.gather(*(arm.status() for arm in arms))
    assert all(r.state.value in ("Alarm", "Idle", "Run", "Home") for r in reports)
    marks = [await bus.controller(n).read_pins() for n in range(1, NODES + 1)]
    assert [m["D1"] for m in marks] == [1, 2, 3, 4]
    version = await bus.controller(3).version()
    assert version.controller is not None and version.controller.startswith("EXbox")
    assert version.arm is not None and version.arm.startswith("Mirobot")
    assert (await bus.controller(2).software_version()).isdigit()
    assert bus.stats.stray_lines == 0 and bus.stats.silent_nodes == 0


async def test_four_arms_home_and_stream_concurrently(bus: ControllerBus) -> None:
    arms = [await bus.connect_arm(n) for n in range(1, NODES + 1)]
    await asyncio.gather(*(bus.controller(n).home() for n in range(1, NODES + 1)))
    for n, arm in enumerate(arms, 1):
        assert (await bus.controller(n).arm_state()).word == "Idle"
        report = await arm.status()
        assert report.state.value == "Idle" and report.joints == (0, 0, 0, 0, 0, 0)

    count = 40
    seen: dict[int, list[int]] = {n: [] for n in range(1, NODES + 1)}

    async def drive(n: int) -> None:
        arm = arms[n - 1]
        before = arm.stats.lines_acknowledged
        lines = ["M21 G91 F3000"] + [f"G01 X{0.1 * (i % 2 * 2 - 1) * n:.2f}" for i in range(count)]
        result = await arm.stream(lines, on_progress=lambda r: seen[n].append(r.number))
        assert result.ok and result.sent == result.acknowledged == count + 1
        assert arm.stats.lines_acknowledged - before == count + 1

    await asyncio.gather(*(drive(n) for n in range(1, NODES + 1)))
    for n in range(1, NODES + 1):
        assert seen[n] == list(range(1, count + 2))  # each line once, in order, per arm
    moved = await asyncio.gather(*(arm.wait_idle() for arm in arms))
    assert all(abs(r.joints[0]) < 0.01 for r in moved)  # the +/- pairs cancel out
    # sends from many tasks of one loop: each gets its own reply
    replies = await asyncio.gather(
        *(arms[i % NODES].send("G90") for i in range(4 * NODES)), return_exceptions=True
    )
    assert replies == [()] * (4 * NODES)
    assert bus.stats.stray_lines == 0 and bus.stats.silent_nodes == 0


async def test_homing_through_the_arm_holds_only_its_node(bus: ControllerBus) -> None:
    arm1, arm2 = await bus.connect_arm(1), await bus.connect_arm(2)
    await arm1.home()  # "$H": the arm answers when homed; the bus asks it for its status
    assert (await arm1.status()).state.value == "Idle"
    assert (await arm2.status()).state is not None
    assert bus.stats.stray_lines == 0


async def test_files_on_the_controller(bus: ControllerBus) -> None:
    controller = bus.controller(2)
    await controller.home()
    assert "test" in await controller.list_files()
    program = ["M21 G90 F2000", "G00 X1", "G00 X0"]  # short moves: a stopped loop ends soon
    await controller.write_file("square", program)
    assert await controller.read_file("square") == tuple(program)
    assert "square" in await controller.list_files()
    await controller.run_file("square")
    state = await controller.wait_idle(timeout=20)
    assert state.word == "Idle"
    await controller.run_file("square", loop=True)
    assert (await controller.arm_state()).word == "Run"
    await controller.stop_file()
    await controller.wait_idle(timeout=20)
    await controller.delete_file("square")
    assert "square" not in await controller.list_files()
    with pytest.raises(ControllerCommandError, match=r"@02.*o111square.*'error'"):
        await controller.run_file("square")
    with pytest.raises(MirobotUsageError):
        await controller.run_file("bad name!")


async def test_gpio(bus: ControllerBus) -> None:
    controller = bus.controller(4)
    await controller.set_pin_modes(D0=1, A0=2)
    await controller.write_pins(D0=1)
    modes = await controller.pin_modes()
    assert modes["D0"] == 1 and modes["A0"] == 2
    assert (await controller.read_pins())["D0"] == 1
    await controller.write_pins(D0=0)
    assert (await controller.read_pins())["D0"] == 0
    with pytest.raises(MirobotUsageError):
        await controller.write_pins(D7=1)
    with pytest.raises(ControllerCommandError, match="@04"):
        await controller.request("o199")


async def test_address_and_baud_queries(bus: ControllerBus) -> None:
    assert await bus.controller(3).bus_address() == 3
    assert await bus.controller(3).bus_baud() == 38400


async def test_a_missing_node_times_out_naming_its_address(bus: ControllerBus) -> None:
    arm1 = await bus.connect_arm(1)
    started = time.monotonic()
    with pytest.raises(NodeSilentError, match="@05") as caught:
        await bus.connect_arm(5)
    assert isinstance(caught.value, MirobotTimeoutError) and caught.value.address == 5
    with pytest.raises(NodeSilentError, match="@05"):
        await bus.controller(5).arm_state()
    assert time.monotonic() - started < 3.0
    assert (await arm1.status()).state is not None  # the others keep working
    assert (await bus.controller(2).arm_state()).word


async def test_cancelling_a_waiting_call_shifts_no_reply(paced_bus: ControllerBus) -> None:
    bus = paced_bus  # the dwell (0.1 s of wall time) outlasts the wait for its pending reply
    arm = await bus.connect_arm(3)
    await arm.send("$X")
    task = asyncio.create_task(arm.send("G4 P0.4"))
    await wait_until(lambda: arm.pending_count > 0, 5, "a call pending")
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    assert await arm.send("G90") == ()
    assert arm.pending_count == 0
    other = bus.controller(1)
    assert (await other.arm_state()).word
    assert bus.stats.stray_lines == 0


async def test_change_of_address_and_baud(own_fast_bus: BusEmulator) -> None:
    async with ControllerBus.open(own_fast_bus.path) as bus:
        controller = bus.controller(4)
        await controller.set_bus_address(7)
        assert controller.address == 7 and bus.controller(7) is controller
        assert await controller.bus_address() == 7
        arm = await bus.connect_arm(7)
        assert (await arm.status()).state is not None
        with pytest.raises(NodeSilentError, match="@04"):
            await bus.controller(4).arm_state()
        arm2 = await bus.connect_arm(2)
        await bus.controller(2).set_bus_baud(9600)  # node 2 now listens at 9600: deaf to us
        with pytest.raises(NodeSilentError, match="@02"):
            await bus.controller(2).arm_state()
        with pytest.raises(MirobotLinkLostError, match="@02"):
            await arm2.status()  # a connected arm whose node falls silent: its link is lost
        assert (await bus.controller(1).arm_state()).word
        assert (await arm.status()).state is not None  # the others keep working


async def test_a_lost_link_fails_every_pending_call_of_every_arm(own_bus: BusEmulator) -> None:
    async with ControllerBus.open(own_bus.path) as bus:
        arms = [await bus.connect_arm(n) for n in (1, 2, 3)]
        await arms[0].send("$X")
        # the dwell lasts 15 s at this time scale and the others wait behind it (30 s allowed):
        # ending within 5 s is the lost bus's doing
        dwell = arms[0].send("G4 P60", timeout=60)
        calls: list[asyncio.Task[object]] = [asyncio.create_task(dwell)]
        calls += [asyncio.create_task(arm.status(timeout=30)) for arm in arms[1:]]
        calls.append(asyncio.create_task(bus.controller(4).arm_state(timeout=30)))
        await wait_until(lambda: arms[0].pending_count > 0, 5, "a call pending on the first arm")
        own_bus.stop()
        started = time.monotonic()
        results = await asyncio.gather(*calls, return_exceptions=True)
        assert time.monotonic() - started < 5.0
        assert all(isinstance(r, MirobotLinkLostError) for r in results), results
        with pytest.raises(MirobotLinkLostError):
            await arms[1].status()


async def test_connect_one_arm_by_address(fast_bus: BusEmulator) -> None:
    async with connect(fast_bus.path, address=2) as arm:
        assert (await arm.status()).state is not None
        assert "@02" in str(arm.url)


def test_wlkatapython_drives_the_bus_emulator(own_fast_bus: BusEmulator) -> None:
    required = os.environ.get("MIROBOT_REQUIRE_THIRD_PARTY")
    if required and not importlib.util.find_spec("Mirobot_robot"):
        pytest.fail("MIROBOT_REQUIRE_THIRD_PARTY=1, wlkatapython missing: pip install wlkatapython")
    uart = pytest.importorskip("Mirobot_robot.Mirobot_UART", reason="wlkatapython not installed")
    serial = pytest.importorskip("serial")
    port = serial.Serial(own_fast_bus.path, 38400, timeout=1)
    try:
        robot = uart.Mirobot_UART(block_flag=False)  # blocking mode polls "?" 3x 0.2 s a round
        robot.init(port, 2)
        assert robot.version() == ("EXbox 20210410", "Mirobot 20210516")
        robot.homing()  # o105=8
        states = [robot.getState()]  # each takes 0.6 s of the SDK's sleeps
        while states[-1] != "Idle" and len(states) < 8:
            states.append(robot.getState())
        assert states[-1] == "Idle", states
        # The SDK reads a fixed number of lines and flushes only before "$V" and "?": what
        # those leave unread ("$V"'s "ok", the arm's "ok"s for "?\r\n") would be taken as the
        # GPIO replies, so flush here as its next status query would.
        _drain_until_quiet(port)
        assert robot.gpio_mode_write("D0", 1) == 1
        assert robot.gpio_mode_read("D0") == "1"
        assert robot.gpio_output_write("D0", 1) == 1
        assert robot.gpio_input_read("D0") == "1"
        robot.cancellation()  # o117 (runFile is o111 too, then sleeps 3 s: left out)
        assert robot.read_message() == "ok"
    finally:
        port.close()


async def test_a_streaming_arm_leaves_room_for_the_others(shared_bus: BusEmulator) -> None:
    timing = BusTiming(planner_window=3)  # small, so that 12 lines fill it several times
    async with ControllerBus.open(shared_bus.path, timing=timing) as bus:
        arm1, arm2 = await bus.connect_arm(1), await bus.connect_arm(2)
        await arm1.unlock()  # where it powered on (not homed): the moves below are relative
        lines = ["M21 G91 F600"] + [f"G01 X{2 if i % 2 else -2}" for i in range(12)]
        stream = asyncio.ensure_future(arm1.stream(lines))
        delays: list[float] = []
        while not stream.done():
            started = time.monotonic()
            await arm2.status()
            delays.append(time.monotonic() - started)
        result = await stream
        assert result.ok and result.acknowledged == len(lines)
        assert bus.stats.window_waits > 0  # arm 1 waited for its planner, not the bus
        assert len(delays) > 3 and max(delays) < 0.5
        assert bus.stats.stray_lines == 0


async def test_reset_through_the_controller(bus: ControllerBus) -> None:
    arm = await bus.connect_arm(3)
    resets = arm.stats.resets
    state = (await arm.status()).state.value
    await arm.reset()  # "%" forwarded: the arm's banner comes back through the controller
    assert arm.stats.resets == resets + 1
    # an Alarm survives a reset, none is made by one (oracle): the state the arm had
    assert (await arm.status()).state.value == state
    await arm.send("$X")
    assert (await arm.status(fresh=True)).state.value == "Idle"
    assert bus.stats.stray_lines == 0


async def test_classic_arms_on_the_bus(tmp_path: Path) -> None:
    emulator = BusEmulator(tmp_path, 2, FAST, 0.3, profile="classic")
    try:
        async with ControllerBus.open(emulator.path) as bus:
            arms = [await bus.connect_arm(1), await bus.connect_arm(2)]
            assert arms[0].firmware is None  # no banner is relayed on the bus
            assert await arms[0].detect_firmware() == "classic"  # "$$" through the controller
            await arms[0].home()  # "$H" through the controller: "in homeing moving...ok"
            await bus.controller(2).home()
            lines = ["M21 G91 F2000"] + [f"G01 X{1 if i % 2 else -1}" for i in range(10)]
            results = await asyncio.gather(*(arm.stream(lines) for arm in arms))
            assert all(r.ok and r.acknowledged == len(lines) for r in results)
            with pytest.raises(MirobotCommandError, match=r"Bad number format|Expected command"):
                await arms[1].send("G01 X1.2.3", validate=False)  # the firmware refuses it
            assert bus.stats.stray_lines == 0
    finally:
        emulator.stop()


def _drain_until_quiet(port: serial.Serial, quiet: float = 0.05, limit: float = 2.0) -> None:
    """Read and drop what the bus still sends until ``quiet`` seconds pass without a byte
    (bounded by ``limit``): the replies the SDK left unread."""
    old_timeout = port.timeout
    port.timeout = quiet
    try:
        end = time.monotonic() + limit
        while time.monotonic() < end and port.read(4096):
            pass
    finally:
        port.timeout = old_timeout
