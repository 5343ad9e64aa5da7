"""``mirobot mcp`` as an MCP client uses it, with the SDK's own client.

Two tests start the command as a subprocess over stdio (``stdio_client`` and ``ClientSession``):
on the embedded virtual Mirobot, and with ``--port`` and ``--envelope`` on an emulator of the test
pool on a pty. The other behaviour tests (hold and resume, reset, dry run, a cancelled call)
drive the server the command builds (:func:`~mirobot_async._mcp_server.open_server`, from the
same parsed arguments) over the SDK's in-memory transport (``Client(server, mode="legacy")``: the
same JSON-RPC messages and initialize handshake) in the test process, on a pooled emulator: no
interpreter and MCP SDK import (~1 s of CPU) per test.

The arm is judged through channels the server does not control: the emulator's control channel
(``stats``: the lines it received) and status reports. Waits are conditions with deadlines; each
test checks that the server left no process (and, in this process, no task) behind. The MCP SDK
is imported by the helpers, not at the top: a pytest-xdist worker that runs none of these tests
does not pay for it at collection.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import sys
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import psutil
import pytest
from waiting import poll_until, wait_until

from mirobot_async._cli.arguments import build_parser
from mirobot_async._cli.commands import cmd_mcp
from mirobot_async.testing import EmulatorPool, EmulatorProcess

if TYPE_CHECKING:
    from mcp import ClientSession
    from mcp.types import CallToolResult

pytestmark = pytest.mark.timeout(120)

ENVELOPE = str(Path(__file__).resolve().parents[2] / "examples" / "envelope.toml")
TOOLS = {
    "status",
    "home",
    "unlock",
    "move_joints",
    "move_pose",
    "set_pump",
    "gripper",
    "check_program",
    "run_program",
    "hold",
    "resume",
    "reset",
}
SQUARE = """\
; a small square in Cartesian mode, inside the default envelope
M20 G90 G21
G0 X200 Y-20 Z180 A0 B0 C0
G1 X220 Y-20 F3000
G1 X220 Y20
G1 X200 Y20
G1 X200 Y-20
"""
SLOW = """\
M21 G90 G21           ; joint mode: j1 out and back at 600 deg/min, 3 s each way
G1 X30 F600
G1 X-30
G1 X0
"""


def text_of(result: CallToolResult) -> str:
    from mcp.types import TextContent

    content = result.content[0]
    assert isinstance(content, TextContent)
    return content.text


def data_of(result: CallToolResult) -> dict[str, Any]:
    assert not result.is_error, text_of(result)
    data: dict[str, Any] = json.loads(text_of(result))
    return data


@pytest.fixture
def errlog(tmp_path: Path) -> Iterator[TextIO]:
    """The server's standard error (its notes), read back with :func:`said`."""
    with open(tmp_path / "stderr.txt", "w+") as file:
        yield file


def said(errlog: TextIO) -> str:
    errlog.flush()
    errlog.seek(0)
    return errlog.read()


def children() -> set[int]:
    return {child.pid for child in psutil.Process().children(recursive=True)}


class Tools:
    """``await tools(name, **arguments)``: call a tool of the server over ``session``."""

    def __init__(self, session: ClientSession) -> None:
        self.session = session

    async def __call__(self, tool: str, **arguments: Any) -> CallToolResult:
        return await self.session.call_tool(tool, arguments)


Call = Callable[..., Awaitable["CallToolResult"]]


@contextlib.asynccontextmanager
async def mcp_command(*args: str, errlog: TextIO) -> AsyncIterator[Tools]:
    """A ``mirobot mcp ARGS`` subprocess over stdio. Every process the server started is gone
    when the block ends."""
    from mcp import ClientSession, StdioServerParameters, stdio_client

    before = children()
    params = StdioServerParameters(
        command=sys.executable, args=["-m", "mirobot_async", "mcp", *args]
    )
    async with (
        stdio_client(params, errlog=errlog) as (read, write),
        ClientSession(read, write) as session,
    ):
        await session.initialize()
        yield Tools(session)
    await wait_until(lambda: not children() - before, 10, "the server's children to exit")


@contextlib.asynccontextmanager
async def mcp_in_memory(*args: str) -> AsyncIterator[Tools]:
    """The server ``mirobot mcp ARGS`` builds, served in this process over the SDK's in-memory
    transport. Its notes go to this process's stderr (``capsys``). Every process and task the
    server started is gone when the block ends."""
    from mcp import Client

    from mirobot_async._mcp_server import open_server

    parsed = build_parser().parse_args(["mcp", *args])
    assert parsed.handler is cmd_mcp
    processes, tasks = children(), asyncio.all_tasks()
    async with open_server(parsed) as server, Client(server, mode="legacy", cache=None) as client:
        yield Tools(client.session)
    await wait_until(lambda: not children() - processes, 10, "the server's children to exit")
    current = asyncio.current_task()
    left = {task for task in asyncio.all_tasks() - tasks if task is not current}
    if left:
        await asyncio.wait(left, timeout=5)
    assert all(task.done() for task in left), f"tasks left behind: {left}"


async def lines_received(emulator: EmulatorProcess) -> int:
    words = (await emulator.control("stats")).split()
    counts = {name: value for name, _, value in (w.partition("=") for w in words if "=" in w)}
    return int(counts["lines_in"])


def on_the_way(status: dict[str, Any]) -> bool:
    """The arm runs the program and has left its start (j1 = 0) by more than a degree."""
    return bool(status["state"] == "Run" and abs(status["joints"]["j1"]) > 1)


async def wait_status(
    call: Call,
    condition: Callable[[dict[str, Any]], bool],
    what: str,
    limit: float = 20.0,
) -> dict[str, Any]:
    seen: dict[str, Any] = {}

    async def matching() -> dict[str, Any] | None:
        seen.update(status := data_of(await call("status")))
        return status if condition(status) else None

    return await poll_until(matching, limit, lambda: f"{what} (last status {seen})", every=0.02)


async def test_the_tools_resources_and_a_session_on_the_embedded_arm(errlog: TextIO) -> None:
    # embedded; at time scale 100 each move still takes milliseconds: a tool that returned
    # before the arm stopped would report it in Run
    async with mcp_command("--time-scale", "100", errlog=errlog) as call:
        listed = (await call.session.list_tools()).tools
        resources = (await call.session.list_resources()).resources
        envelope = await call.session.read_resource("mirobot://envelope")
        settings = await call.session.read_resource("mirobot://settings")
        locked = data_of(await call("status"))
        refused = await call("move_joints", j1=20)
        homed = data_of(await call("home"))
        moved = data_of(await call("move_joints", j1=20, j2=10))
        pose = data_of(await call("move_pose", x=210, y=0, z=200))
        checked = data_of(await call("check_program", program=SQUARE))
        ran = data_of(await call("run_program", program=SQUARE))
        pumped = data_of(await call("set_pump", pwm=1000))
        gripped = data_of(await call("gripper", action="close"))
    assert {tool.name for tool in listed} == TOOLS
    for tool in listed:
        assert tool.description and "\n" not in tool.description.strip(), tool
    schema = {tool.name: tool.input_schema for tool in listed}
    assert set(schema["move_joints"]["properties"]) == {
        "j1", "j2", "j3", "j4", "j5", "j6", "rail", "speed", "relative"
    }  # fmt: skip
    assert set(schema["move_pose"]["properties"]) == {
        "x", "y", "z", "rx", "ry", "rz", "speed", "linear", "relative"
    }  # fmt: skip
    assert schema["run_program"]["required"] == ["program"]
    assert schema["gripper"]["properties"]["action"]["enum"] == ["open", "close"]
    assert {str(r.uri) for r in resources} == {
        "mirobot://status",
        "mirobot://envelope",
        "mirobot://settings",
    }
    box = json.loads(envelope.contents[0].text)["box_mm"]  # type: ignore[union-attr]
    assert box == {"x": [50.0, 300.0], "y": [-250.0, 250.0], "z": [20.0, 300.0]}
    assert "$1" in json.loads(settings.contents[0].text)  # type: ignore[union-attr]
    assert locked["state"] == "Alarm"
    assert refused.is_error and "the arm is locked (Alarm" in text_of(refused)
    assert homed["status"]["state"] == "Idle"
    assert homed["status"]["joints"] == {f"j{i}": 0.0 for i in range(1, 7)}
    assert moved["status"]["state"] == "Idle"
    assert moved["status"]["joints"]["j1"] == pytest.approx(20, abs=0.05)
    assert moved["status"]["joints"]["j2"] == pytest.approx(10, abs=0.05)
    assert pose["status"]["pose"]["x"] == pytest.approx(210, abs=0.1)
    assert pose["status"]["firmware_line"].startswith("<Idle,")
    assert checked["problems"] == []
    assert checked["envelope"] == "every line is inside the safety envelope"
    assert checked["predicted_end_pose"]["x"] == pytest.approx(200)
    assert checked["predicted_end_pose"]["y"] == pytest.approx(-20)
    assert ran["outcome"] == "done"
    assert [line["outcome"] for line in ran["lines"]] == ["ok"] * 6
    assert [line["line"] for line in ran["lines"]] == [2, 3, 4, 5, 6, 7]  # numbered as given
    assert ran["not_sent"] == []
    assert ran["status"]["state"] == "Idle"
    assert ran["status"]["pose"]["x"] == pytest.approx(200, abs=0.1)
    assert ran["status"]["pose"]["y"] == pytest.approx(-20, abs=0.1)
    assert pumped["outcome"] == "M3 S1000: ok" and pumped["status"]["pump_pwm"] == 1000
    assert gripped["outcome"] == "M3 S60: ok"
    assert "safety envelope (the default envelope): box x 50..300 mm" in said(errlog)


async def test_an_envelope_refusal_is_a_tool_error_with_nothing_sent(
    errlog: TextIO, mirobot_emulator_pool: EmulatorPool
) -> None:
    leaving = "M20 G90 G21\nG0 X200 Y0 Z150 A0 B0 C0\nG1 Z5 F1000\n"
    async with mirobot_emulator_pool.lend_async(time_scale=0) as emulator:
        args = ("--port", emulator.url, "--envelope", ENVELOPE)
        async with mcp_command(*args, errlog=errlog) as call:
            data_of(await call("home"))
            data_of(await call("move_joints", j1=10))
            before = data_of(await call("status"))
            sent = await lines_received(emulator)
            low = await call("move_pose", z=5)
            wide = await call("move_joints", j1=120)
            program = await call("run_program", program=leaving)
            checked = data_of(await call("check_program", program=leaving))
            after = data_of(await call("status"))
            assert await lines_received(emulator) == sent  # not one line written by the refusals
    assert low.is_error and wide.is_error and program.is_error
    message = text_of(low)
    assert "refused by the safety envelope" in message
    assert "target z=5.000 mm is below the envelope's minimum z=20 mm" in message
    assert "nothing was sent" in message
    assert "The safety envelope allows: box x 100..300 mm, y -200..200 mm, z 20..300 mm" in message
    assert "outside the envelope's J1 range -100..100 deg" in text_of(wide)
    assert "line 3 (G1 Z5 F1000)" in text_of(program) and "nothing was sent" in text_of(program)
    assert checked["envelope"].startswith("refused at line 3 (G1 Z5 F1000)")
    assert after["firmware_line"] == before["firmware_line"]  # the arm did not move


async def test_hold_stops_a_running_program_and_resume_finishes_it(
    mirobot_emulator_pool: EmulatorPool,
) -> None:
    async with (
        mirobot_emulator_pool.lend_async(time_scale=1) as emulator,  # real time: 12 s of motion
        mcp_in_memory("--port", emulator.url) as call,
    ):
        data_of(await call("unlock"))
        running = asyncio.ensure_future(call("run_program", program=SLOW))
        try:
            await wait_status(call, lambda s: on_the_way(s) or running.done(), "motion")
            assert not running.done(), text_of(running.result())
            busy = await call("move_joints", j1=5)
            held = data_of(await call("hold"))
            # standing still: two reports in a row in Hold with the same joints
            seen: list[dict[str, Any]] = []

            def still_in_hold(status: dict[str, Any]) -> bool:
                seen.append(status)
                return len(seen) > 1 and all(
                    s["state"] == "Hold" and s["joints"] == status["joints"] for s in seen[-2:]
                )

            still = await wait_status(call, still_in_hold, "a held arm standing still")
            assert not running.done()  # the program waits, held
            await emulator.control("time-scale 100")  # the rest of the motion needs no real time
            resumed = data_of(await call("resume"))
            ran = data_of(await asyncio.wait_for(running, 60))
        finally:
            running.cancel()
            with contextlib.suppress(BaseException):
                await running
    assert busy.is_error
    assert "run_program is still running (one command at a time)" in text_of(busy)
    assert held["outcome"].startswith("feed hold sent (!)")
    assert held["interrupted"] == "run_program"
    assert still["state"] == "Hold"
    assert 0 < abs(still["joints"]["j1"]) < 30  # stopped on the way
    assert resumed["status"]["state"] in ("Run", "Idle")
    assert ran["outcome"] == "done"
    assert [line["outcome"] for line in ran["lines"]] == ["ok"] * 4
    assert ran["status"]["state"] == "Idle"
    assert ran["status"]["joints"]["j1"] == pytest.approx(0, abs=0.05)


async def test_reset_stops_a_running_program_at_once(
    mirobot_emulator_pool: EmulatorPool,
) -> None:
    async with (
        mirobot_emulator_pool.lend_async(time_scale=1) as emulator,  # real time: 12 s of motion
        mcp_in_memory("--port", emulator.url) as call,
    ):
        data_of(await call("unlock"))
        running = asyncio.ensure_future(call("run_program", program=SLOW))
        try:
            await wait_status(call, on_the_way, "motion")
            reset = data_of(await call("reset"))
            outcome = await asyncio.wait_for(running, 20)
        finally:
            running.cancel()
            with contextlib.suppress(BaseException):
                await running
        after = data_of(await call("status"))
    assert reset["status"]["state"] == "Alarm"
    assert reset["banner"]
    # the program's call ends with what happened: the reset failed its lines
    assert outcome.is_error or json.loads(text_of(outcome))["outcome"] != "done"
    assert "reset" in text_of(outcome).lower()
    assert after["state"] == "Alarm"


async def test_dry_run_runs_every_motion_on_a_twin_first(
    mirobot_emulator_pool: EmulatorPool, capsys: pytest.CaptureFixture[str]
) -> None:
    async with mirobot_emulator_pool.lend_async(time_scale=0) as emulator:
        args = ("--port", emulator.url, "--dry-run", "--firmware", "2021")
        async with mcp_in_memory(*args) as call:
            data_of(await call("home"))
            moved = data_of(await call("move_joints", j1=15))
            ran = data_of(await call("run_program", program=SQUARE))
            sent = await lines_received(emulator)
            refused = await call("move_pose", z=5)
            assert await lines_received(emulator) == sent
    assert (
        "--dry-run: every motion runs first on a virtual twin (firmware 2021)"
        in capsys.readouterr().err
    )
    assert moved["status"]["joints"]["j1"] == pytest.approx(15, abs=0.05)
    assert ran["outcome"] == "done"
    assert refused.is_error and "nothing was sent" in text_of(refused)


def test_the_readme_configuration_is_a_mirobot_mcp_command() -> None:
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    section = readme[readme.index("### AI agents (MCP)") :]
    snippet = section[section.index("```json") + len("```json") : section.index("```\n\n")]
    server = json.loads(snippet)["mcpServers"]["mirobot"]
    assert server["command"] == "mirobot"
    args = build_parser().parse_args(server["args"])
    assert args.handler is cmd_mcp
    assert args.port == "/dev/ttyUSB0" and args.envelope == "/path/to/envelope.toml"


async def test_a_cancelled_program_call_leaves_the_arm_held(
    mirobot_emulator_pool: EmulatorPool,
) -> None:
    """The client gives up on run_program (its request is cancelled): the arm is held at once,
    not left running the program with nobody watching."""
    async with (
        mirobot_emulator_pool.lend_async(time_scale=1) as emulator,  # real time: 12 s of motion
        mcp_in_memory("--port", emulator.url) as call,
    ):
        data_of(await call("unlock"))
        running = asyncio.ensure_future(call("run_program", program=SLOW))
        await wait_status(call, on_the_way, "motion")
        running.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await running
        held = await wait_status(call, lambda s: s["state"] == "Hold", "Hold", limit=5)
        assert held["busy_with"] is None  # the next command may run
        behind = await call("move_joints", j1=5)  # ... but not queued behind the held moves
        reset = data_of(await call("reset"))
    assert 0 < abs(held["joints"]["j1"]) < 30
    assert behind.is_error and "the arm is in Hold with moves still queued" in text_of(behind)
    assert reset["status"]["state"] == "Alarm"
