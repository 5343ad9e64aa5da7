"""``mirobot mcp``: a Model Context Protocol server, so that an AI agent (Claude Desktop, Cursor,
any MCP client) can drive the arm, with the safety envelope always on.

Layout: :mod:`~mirobot_async._mcp_server.service` (what each tool does to the arm, without the
SDK), :mod:`~mirobot_async._mcp_server.server` (the tools and resources on the ``mcp`` SDK, an
optional dependency: ``pip install 'mirobot-async[mcp]'``), :func:`open_server` (the command's
server: the arm with its envelope, a virtual twin for ``--dry-run``) and :func:`serve` (the
command: that server over stdio).
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import AsyncIterator
from typing import TYPE_CHECKING

from mirobot_async._cli.envelope_file import describe_envelope
from mirobot_async._cli.exits import CliError, note
from mirobot_async._cli.session import envelope_of, firmware_of, open_robot
from mirobot_async._mcp_server.service import ArmService, default_envelope

if TYPE_CHECKING:
    from mcp.server.mcpserver import MCPServer

    from mirobot_async._client.client import Mirobot

__all__ = ["ArmService", "open_server", "serve"]

TWIN_TIME_SCALE = 0.0
"""The dry run's virtual twin finishes every motion at once: it only has to say whether the
firmware takes it."""


@contextlib.asynccontextmanager
async def _twin(args: argparse.Namespace, arm: Mirobot) -> AsyncIterator[Mirobot | None]:
    """A virtual Mirobot of the arm's profile for ``--dry-run`` with ``--port``, else None."""
    if not args.dry_run or args.port is None:
        if args.dry_run:
            note("--dry-run: the arm is already the embedded virtual Mirobot")
        yield None
        return
    from mirobot_async._client.client import Mirobot
    from mirobot_async.virtual import start_emulator

    firmware = args.firmware or arm.firmware or await arm.detect_firmware()
    note(f"--dry-run: every motion runs first on a virtual twin (firmware {firmware})")
    async with (
        start_emulator(firmware=firmware, time_scale=TWIN_TIME_SCALE) as url,
        Mirobot.connect(url, firmware=firmware) as twin,
    ):
        yield twin


@contextlib.asynccontextmanager
async def open_server(args: argparse.Namespace) -> AsyncIterator[MCPServer]:
    """The MCP server ``mirobot mcp ARGS`` serves, its arm (``--port`` or the embedded virtual
    Mirobot, with its safety envelope) and the ``--dry-run`` twin open for the block.

    Without the MCP SDK: a CliError saying how to install it."""
    try:
        from mirobot_async._mcp_server.server import build_server
    except ImportError as err:
        raise CliError(
            f"mirobot mcp needs the MCP SDK: pip install 'mirobot-async[mcp]' ({err})"
        ) from None
    if envelope_of(args) is None:
        args.envelope_object = default_envelope(firmware_of(args))
    async with open_robot(args) as arm:
        envelope = arm.envelope
        assert envelope is not None
        source = args.envelope or "the default envelope"
        note(f"safety envelope ({source}): {describe_envelope(envelope)}")
        async with _twin(args, arm) as twin:
            yield build_server(ArmService(arm, twin))


async def serve(args: argparse.Namespace) -> int:
    """Run the MCP server over stdio until the client closes it (exit status 0)."""
    async with open_server(args) as server:
        await server.run_stdio_async()
    return 0
