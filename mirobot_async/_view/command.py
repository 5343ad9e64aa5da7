"""``mirobot view``: the arm in 3D in a browser, a program's predicted path, a teach pendant.

Needs the ``view`` extra (``pip install 'mirobot-async[view]'``: viser and yourdfpy). The page
is served by viser from this machine (default ``127.0.0.1`` and a free port; other addresses
only with ``--allow-remote``); its URL, with this run's secret, is the first line of standard
output. Modules: :mod:`~mirobot_async._view.gate` (the secret and the origin, checked at the
websocket's handshake), :mod:`~mirobot_async._view.preview` (the path, pure),
:mod:`~mirobot_async._view.teach` (taught points and their export, pure),
:mod:`~mirobot_async._view.scene` (3D), :mod:`~mirobot_async._view.panel` (widgets),
:mod:`~mirobot_async._view.app` (the controller), this module (the command).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import sys
import time
import webbrowser
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final, Literal

import numpy as np

from mirobot_async._cli.exits import CliError, note
from mirobot_async._cli.programs import read_lines, read_program
from mirobot_async._view.listen import parse_listen
from mirobot_async.errors import MirobotLinkLostError, MirobotUsageError

if TYPE_CHECKING:
    import viser

    from mirobot_async._client.client import Mirobot
    from mirobot_async._safety.envelope import Envelope

__all__ = ["parse_listen", "serve_view"]

LOST_LINK_GRACE: Final = 1.0
"""Seconds the page keeps showing that the link is lost before the command exits (status 1)."""
RENDER_WAIT: Final = 20.0
"""Seconds for a page to answer one request for a frame before it is asked again."""
RENDER_SIZE: Final = 160
"""Pixels (square) of the frame asked of the page to tell that it shows the arm."""
DRAWN_PIXELS: Final = 200
"""Pixels of the arm (:func:`arm_pixels`) in that frame beyond which it is on screen (at the
first camera about 620; the grid and the path alone under 10)."""


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
    """Serve the page until interrupted (Ctrl-C / SIGTERM: exit 0) or until the link to the arm
    is lost (said on the page, then :class:`MirobotLinkLostError`: exit 1); ``--run`` streams
    the program once a browser shows the scene."""
    try:
        import viser  # noqa: F401  (the view extra is installed)
    except ImportError:
        raise CliError(
            "mirobot view needs the view extra: pip install 'mirobot-async[view]'"
        ) from None
    if getattr(args, "replay", None) is not None:  # offline: no arm
        from mirobot_async._view.replay import serve_replay

        return await serve_replay(args)
    from mirobot_async._view.app import ProgramSource, ViewController
    from mirobot_async._view.gate import is_loopback, serve_guarded, stop_server
    from mirobot_async._view.preview import preview_program

    host, port = parse_listen(args.listen)
    allow_remote = bool(getattr(args, "allow_remote", False))
    if not is_loopback(host):
        if not allow_remote:
            raise CliError(
                f"--listen {args.listen}: {host} is not a loopback address; anyone who reaches "
                "it with the printed URL drives the arm. Add --allow-remote to serve it anyway"
            )
        note(
            f"warning: serving on {host}: anyone on that network who has the printed URL "
            "(its secret) can drive the arm; the link is plain HTTP, not encrypted"
        )
    export_dir = _export_dir(getattr(args, "export_dir", None))
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
        try:
            server, url = serve_guarded(host, port, allow_remote=allow_remote)
        except MirobotUsageError as err:  # fail closed: never serve the arm to any page
            raise CliError(str(err)) from None
        stack.callback(stop_server, server)
        print(url, flush=True)
        view = ViewController(
            server,
            arm,
            firmware=firmware,
            program=source,
            preview=preview,
            envelope=envelope,
            export_dir=export_dir,
        )
        if preview is not None and preview.flagged:
            for flag in preview.flagged:
                print(f"{source.name}:{flag.number}: {flag.message}", file=sys.stderr)  # type: ignore[union-attr]
        shown_scene = asyncio.Event()
        loop = asyncio.get_running_loop()

        def on_connect(client: viser.ClientHandle) -> None:
            # viser calls this once the page has sent its camera (its canvas exists); the
            # scene is on screen once a frame rendered by the page shows it
            if scene_drawn(server, client, lambda: not shown_scene.is_set()):
                loop.call_soon_threadsafe(shown_scene.set)

        if args.run and source is not None:
            server.on_client_connect(on_connect)
        if not args.no_browser:
            webbrowser.open(url)
        tasks = [
            asyncio.create_task(view.follow_status(), name="view-status"),
            asyncio.create_task(view.work(), name="view-commands"),
        ]
        try:
            if args.run and source is not None:
                await shown_scene.wait()
                note(f"a browser shows the scene: running {source.name}")
                view.command("Run program")
            await view.link_lost.wait()  # else until cancelled (Ctrl-C, SIGTERM)
            server.flush()
            await asyncio.sleep(LOST_LINK_GRACE)  # the page shows why before the server stops
            raise MirobotLinkLostError(view.link_error or "closed")
        finally:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
    return 0


def scene_drawn(
    server: viser.ViserServer, client: viser.ClientHandle, wanted: Callable[[], bool]
) -> bool:
    """Whether a frame rendered by ``client`` shows the arm (blocking: viser's thread pool).
    Asks again while the page is connected and ``wanted()``: a frame rendered before the
    arm's meshes are decoded shows the grid alone, and a loaded machine may take longer than
    :data:`RENDER_WAIT` to render one."""
    while wanted() and client.client_id in server.get_clients():
        try:
            image = client.get_render(
                height=RENDER_SIZE, width=RENDER_SIZE, transport_format="png", timeout=RENDER_WAIT
            )
        except TimeoutError:
            continue
        except Exception:  # the page went away: not shown there
            return False
        if arm_pixels(np.asarray(image)) >= DRAWN_PIXELS:
            return True
        time.sleep(0.2)
    return False


def arm_pixels(image: Any) -> int:
    """Pixels of an RGBA frame that are drawn (opaque), grey and dark: the arm's links (the
    grid's lines are light, the path's colours saturated)."""
    rgb = np.asarray(image[:, :, :3], dtype=np.int16)
    grey = rgb.max(axis=2) - rgb.min(axis=2) < 40
    dark = rgb.max(axis=2) < 140
    return int(((image[:, :, 3] > 0) & grey & dark).sum())


def _export_dir(given: str | None) -> Path:
    """The folder the pendant exports into, fixed now (an absolute path)."""
    folder = Path(given or ".").resolve()
    if not folder.is_dir():
        raise CliError(f"--export-dir {folder}: not a folder")
    return folder


async def _detect_firmware(port: str) -> str:
    """The arm's profile (its banner, else ``$$``), to load the envelope with its geometry."""
    from mirobot_async._client.client import Mirobot

    async with Mirobot.connect(port) as arm:
        return arm.firmware or await arm.detect_firmware()
