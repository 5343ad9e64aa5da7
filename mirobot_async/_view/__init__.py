"""``mirobot view``: the arm in 3D in a browser, a program's predicted path, a teach pendant.

Needs the ``view`` extra (``pip install 'mirobot-async[view]'``: viser and yourdfpy). The page
is served by viser from this machine (default ``127.0.0.1`` and a free port); its URL is the
first line of standard output. Modules: :mod:`~mirobot_async._view.preview` (the path, pure),
:mod:`~mirobot_async._view.teach` (taught points and their export, pure),
:mod:`~mirobot_async._view.scene` (3D), :mod:`~mirobot_async._view.panel` (widgets),
:mod:`~mirobot_async._view.app` (the controller), this module (the command).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import sys
import webbrowser
from collections.abc import AsyncIterator
from typing import TYPE_CHECKING, Literal

from mirobot_async._cli.exits import CliError, note
from mirobot_async._cli.programs import read_lines, read_program

if TYPE_CHECKING:
    import viser

    from mirobot_async._client.client import Mirobot
    from mirobot_async._safety.envelope import Envelope

__all__ = ["parse_listen", "serve_view"]

DEFAULT_HOST = "127.0.0.1"


def parse_listen(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (``:PORT`` or ``HOST`` alone allowed; port 0 = a free one)."""
    host, _, port = text.rpartition(":") if ":" in text else (text, ":", "0")
    host = host.strip("[]") or DEFAULT_HOST
    try:
        number = int(port or "0")
    except ValueError:
        raise CliError(f"--listen {text!r}: the port must be a number") from None
    if not 0 <= number <= 65535:
        raise CliError(f"--listen {text!r}: the port must be 0..65535")
    return host, number


def _load_envelope(path: str | None, firmware: str) -> Envelope | None:
    if path is None:
        return None
    from mirobot_async._cli.envelope_file import load_envelope

    return load_envelope(path, firmware=firmware)


@contextlib.asynccontextmanager
async def _open_arm(args: argparse.Namespace, envelope: Envelope | None) -> AsyncIterator[Mirobot]:
    """The arm at ``--port`` as it is, or an embedded virtual Mirobot, homed first."""
    from mirobot_async._client.client import Mirobot

    firmware: Literal["2021", "classic", "2024"] = (
        args.firmware if args.firmware in ("classic", "2024") else "2021"
    )
    if args.port is not None:
        async with Mirobot.connect(
            args.port, firmware=args.firmware, envelope=envelope, record=args.record
        ) as arm:
            yield arm
        return
    from mirobot_async._cli.session import DEFAULT_TIME_SCALE
    from mirobot_async.virtual import start_emulator

    scale = DEFAULT_TIME_SCALE if args.time_scale is None else float(args.time_scale)
    note(
        f"no --port given; using an embedded virtual Mirobot (firmware {firmware}, "
        f"time-scale {scale:g})"
    )
    async with (
        start_emulator(firmware=firmware, time_scale=scale) as url,
        Mirobot.connect(url, firmware=firmware, envelope=envelope, record=args.record) as arm,
    ):
        note("homing the virtual Mirobot first")
        await arm.home()
        yield arm


async def serve_view(args: argparse.Namespace) -> int:
    """Serve the page until interrupted (Ctrl-C / SIGTERM); ``--run`` streams the program once
    the first browser has connected."""
    try:
        import viser
    except ImportError:
        raise CliError(
            "mirobot view needs the view extra: pip install 'mirobot-async[view]'"
        ) from None
    from mirobot_async._view.app import ProgramSource, ViewController
    from mirobot_async._view.preview import preview_program

    host, port = parse_listen(args.listen)
    source = None
    if args.program is not None:
        lines = read_lines(args.program)
        commands = [(p.number, p.text) for p in read_program(args.program)]
        if not commands:
            raise CliError(f"{args.program}: no commands in the file")
        source = ProgramSource(args.program, lines, commands)
    firmware = args.firmware or ("2021" if args.port is None else None)
    if args.envelope is not None and firmware is None:
        firmware = await _detect_firmware(args.port)
    envelope = _load_envelope(args.envelope, firmware or "2021")
    async with contextlib.AsyncExitStack() as stack:
        arm = await stack.enter_async_context(_open_arm(args, envelope))
        firmware = firmware or arm.firmware or await arm.detect_firmware()
        report = await arm.status()
        preview = None
        if source is not None:
            offset: tuple[float, float, float] | None = (0.0, 0.0, 0.0)
            lift: float | None = None
            if firmware != "classic":  # absolute M20 targets add $41..$43; G5 lifts by $49
                settings = await arm.settings()  # read-only ($$)
                offset = (settings.get(41, 0.0), settings.get(42, 0.0), settings.get(43, 0.0))
                lift = settings.get(49)
            preview = preview_program(
                source.lines,
                firmware=firmware,
                start=report.joints,
                envelope=envelope,
                base_offset=offset,
                gate_lift=lift,
            )
        with contextlib.redirect_stdout(sys.stderr):  # viser prints its own banner
            server = viser.ViserServer(host=host, port=port, verbose=False)
        stack.callback(_stop_server, server)
        url = f"http://{server.get_host()}:{server.get_port()}/"
        print(url, flush=True)
        view = ViewController(
            server, arm, firmware=firmware, program=source, preview=preview, envelope=envelope
        )
        if preview is not None and preview.flagged:
            for flag in preview.flagged:
                print(f"{source.name}:{flag.number}: {flag.message}", file=sys.stderr)  # type: ignore[union-attr]
        connected = asyncio.Event()
        loop = asyncio.get_running_loop()

        def on_connect(_client: viser.ClientHandle) -> None:
            loop.call_soon_threadsafe(connected.set)

        server.on_client_connect(on_connect)
        if not args.no_browser:
            webbrowser.open(url)
        tasks = [
            asyncio.create_task(view.follow_status(), name="view-status"),
            asyncio.create_task(view.work(), name="view-commands"),
        ]
        try:
            if args.run and source is not None:
                await connected.wait()
                view.command("Run program")
            await asyncio.Event().wait()  # until cancelled (Ctrl-C, SIGTERM)
        finally:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
    return 0


def _stop_server(server: viser.ViserServer) -> None:
    with contextlib.redirect_stdout(sys.stderr):  # and says "Server stopped"
        server.stop()


async def _detect_firmware(port: str) -> str:
    """The arm's profile (its banner, else ``$$``), to load the envelope with its geometry."""
    from mirobot_async._client.client import Mirobot

    async with Mirobot.connect(port) as arm:
        return arm.firmware or await arm.detect_firmware()
