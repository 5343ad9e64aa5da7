"""The MCP tools and resources of ``mirobot mcp``, on the official MCP Python SDK
(``pip install 'mirobot-async[mcp]'``), served over stdio.

Each tool is a typed function: the SDK makes its JSON schema from the type hints and its
description from the docstring's one line. A :class:`~mirobot_async.errors.MirobotError` (a
refusal, the firmware's error, an alarm) becomes a tool error carrying its message, so the
model reads why; anything else is a crash the SDK reports without details.
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable
from typing import Annotated, Any, Literal, TypeVar

from mcp.server.mcpserver import MCPServer
from mcp.server.mcpserver.exceptions import ResourceError, ToolError
from pydantic import Field

from mirobot_async.errors import MirobotError
from mirobot_async.mcp_server.service import ArmService

__all__ = ["SERVER_NAME", "build_server"]

SERVER_NAME = "mirobot"
INSTRUCTIONS = (
    "Drives a WLKATA Mirobot arm (or its virtual twin). Every motion is checked against a "
    "safety envelope first (read mirobot://envelope): a refused call says why and that nothing "
    "was sent. The arm is locked after power-on and after reset: call home (or unlock) first. "
    "Joints j1..j6 are in degrees, x/y/z in mm and rx/ry/rz in degrees. One command at a time; "
    "hold and reset act at once, even while a move or program runs."
)

T = TypeVar("T")

Angle = Annotated[float | None, Field(description="degrees (omit: the joint stays)")]
Millimetres = Annotated[float | None, Field(description="mm (omit: it stays)")]
Degrees = Annotated[float | None, Field(description="degrees (omit: it stays)")]
Program = Annotated[str, Field(description="G-code text, one command per line")]


async def _tool(call: Awaitable[T]) -> T:
    """The outcome, or a tool error with the client's message (it quotes the firmware)."""
    try:
        return await call
    except MirobotError as err:
        raise ToolError(str(err)) from None


def build_server(service: ArmService) -> MCPServer:
    """The MCP server whose tools and resources drive ``service``'s arm."""
    server: MCPServer = MCPServer(SERVER_NAME, instructions=INSTRUCTIONS, log_level="WARNING")

    def tool(fn: Callable[..., Awaitable[dict[str, Any]]]) -> None:
        server.add_tool(fn, structured_output=False)

    async def status() -> dict[str, Any]:
        """Read the arm's status now: state (Idle, Run, Hold, Alarm...), joints, pose, outputs."""
        return await _tool(service.status())

    async def home(sequential: bool = False) -> dict[str, Any]:
        """Home the arm ($H; sequential: one axis after another), which also unlocks it."""
        return await _tool(service.home(sequential))

    async def unlock() -> dict[str, Any]:
        """Unlock the axes without homing ($X, M50); leaves Alarm."""
        return await _tool(service.unlock())

    async def move_joints(
        j1: Angle = None,
        j2: Angle = None,
        j3: Angle = None,
        j4: Angle = None,
        j5: Angle = None,
        j6: Angle = None,
        rail: Millimetres = None,
        speed: Annotated[
            float | None, Field(description="deg/min (omit: the fastest)", gt=0)
        ] = None,
        relative: bool = False,
    ) -> dict[str, Any]:
        """Move the joints to angles in degrees (relative: by increments); returns at rest."""
        return await _tool(service.move_joints((j1, j2, j3, j4, j5, j6), rail, speed, relative))

    async def move_pose(
        x: Millimetres = None,
        y: Millimetres = None,
        z: Millimetres = None,
        rx: Degrees = None,
        ry: Degrees = None,
        rz: Degrees = None,
        speed: Annotated[
            float | None, Field(description="mm/min (linear: default 2000)", gt=0)
        ] = None,
        linear: bool = False,
        relative: bool = False,
    ) -> dict[str, Any]:
        """Move the tool to x, y, z (mm) and rx, ry, rz (deg); linear: a straight line."""
        return await _tool(service.move_pose((x, y, z, rx, ry, rz), speed, linear, relative))

    async def set_pump(
        pwm: Annotated[
            int, Field(description="0 off, 500 blow (release), 1000 suck", ge=0, le=1000)
        ],
    ) -> dict[str, Any]:
        """Set the suction pump (M3 S<pwm>): 1000 sucks, 500 blows, 0 is off."""
        return await _tool(service.set_pump(pwm))

    async def gripper(action: Literal["open", "close"], legacy: bool = False) -> dict[str, Any]:
        """Open or close the gripper (legacy: the older gripper on PWM 2)."""
        return await _tool(service.gripper(action == "close", legacy))

    async def check_program(program: Program) -> dict[str, Any]:
        """Check a G-code program without running it: problems, envelope verdict, end pose."""
        return await _tool(service.check_program(program))

    async def run_program(program: Program, continue_on_error: bool = False) -> dict[str, Any]:
        """Run a G-code program (checked whole first); returns every line's outcome at rest."""
        return await _tool(service.run_program(program, continue_on_error))

    async def hold() -> dict[str, Any]:
        """Feed hold (!): decelerate and stop now, even during a move or program; resume goes on."""
        return await _tool(service.hold())

    async def resume() -> dict[str, Any]:
        """Cycle start (~): continue the motion stopped by hold."""
        return await _tool(service.resume())

    async def reset() -> dict[str, Any]:
        """Soft reset (%): stop at once and drop every queued move; the arm is locked after."""
        return await _tool(service.reset())

    for fn in (
        status,
        home,
        unlock,
        move_joints,
        move_pose,
        set_pump,
        gripper,
        check_program,
        run_program,
        hold,
        resume,
        reset,
    ):
        tool(fn)

    async def resource(call: Awaitable[Any]) -> str:
        try:
            return json.dumps(await call, indent=1)
        except MirobotError as err:
            raise ResourceError(str(err)) from None

    @server.resource(
        "mirobot://status",
        name="status",
        description="the arm's status now",
        mime_type="application/json",
    )
    async def status_resource() -> str:
        return await resource(service.status())

    @server.resource(
        "mirobot://envelope",
        name="envelope",
        description="the safety envelope every motion is checked against",
        mime_type="application/json",
    )
    async def envelope_resource() -> str:
        return json.dumps(service.envelope(), indent=1)

    @server.resource(
        "mirobot://settings",
        name="settings",
        description="the firmware's settings ($$)",
        mime_type="application/json",
    )
    async def settings_resource() -> str:
        return await resource(service.settings())

    return server
