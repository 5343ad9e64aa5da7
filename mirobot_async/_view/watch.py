"""The 3D view of a script's own connection: ``async with arm.view() as view:``.

The page (served by viser from this process, behind the same secret URL and origin check as
``mirobot view``: :mod:`~mirobot_async._view.gate`) shows the arm as its status reports it
(polled every :data:`STATUS_INTERVAL` s on the script's connection, sharing its ``?``), the
tool's trail, the path predicted for every line the script writes (pipelined lines ahead of
the arm: :class:`~mirobot_async._view.script_lines.ScriptLines`), a red marker and an entry for
each line refused (by the firmware, or by the client before a byte was written), each alarm
and each reset. The page only watches: it has no control that moves the arm, and closing it
(or opening several) changes nothing for the script. When the block ends, the page says how
the script ended, then the server stops.

Needs the ``view`` extra (viser and yourdfpy); :meth:`Mirobot.view` checks it and says so.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import sys
import webbrowser
from collections import deque
from collections.abc import AsyncGenerator, Callable
from types import TracebackType
from typing import TYPE_CHECKING, Final, Protocol

import numpy as np

from mirobot_async._client.observers import LineObservers, Offset
from mirobot_async._core.modal import MotionModes
from mirobot_async._core.outgoing import OutgoingLine
from mirobot_async._core.protocol import LineAcknowledged, LineRejected
from mirobot_async._core.replies import State, StatusReport
from mirobot_async._urdf import dh_of
from mirobot_async._view.preview import PATH_COLOURS, REFUSED_COLOUR, PathSegment
from mirobot_async._view.script_lines import Marker, ScriptLines
from mirobot_async._view.status_text import describe_status
from mirobot_async.errors import (
    MirobotConnectionError,
    MirobotError,
    MirobotTimeoutError,
    MirobotUsageError,
)
from mirobot_async.kinematics import Joints, forward

if TYPE_CHECKING:
    import viser

    from mirobot_async._safety.envelope import Envelope

__all__ = ["STATUS_INTERVAL", "ArmView", "WatchedArm"]

_log = logging.getLogger("mirobot_async.view")

STATUS_INTERVAL: Final = 0.05
"""Seconds between the status reports the view asks for (20 Hz)."""
REDRAW_INTERVAL: Final = 0.1
"""Seconds between redraws of the predicted path and the trail (when they changed)."""
END_GRACE: Final = 0.5
"""Seconds the server stays up after the script ended, for the page to hear it."""
SETUP_TIMEOUT: Final = 30.0
"""Seconds the view may wait, once, for the arm at rest to learn its firmware and settings."""
_TRAIL_CHUNK: Final = 100
"""Points of the trail per scene node (a full one is not sent again)."""
_TRAIL_CHUNKS_KEPT: Final = 100
_KEYS_KEPT: Final = 4096
_PATH_CHUNK: Final = 100
"""Lines of the predicted path per scene node (a full one is not sent again)."""
_M: Final = 0.001
_TRAIL_COLOUR: Final = (40, 40, 40)


class WatchedArm(Protocol):
    """What the view reads of the script's arm (a :class:`mirobot_async.Mirobot`)."""

    @property
    def firmware(self) -> str | None: ...
    @property
    def envelope(self) -> Envelope | None: ...
    @property
    def pending_count(self) -> int: ...
    @property
    def last_status(self) -> StatusReport | None: ...
    def statuses(
        self, interval: float = ..., *, timeout: float | None = ...
    ) -> AsyncGenerator[StatusReport, None]: ...
    async def detect_firmware(self, *, timeout: float | None = ...) -> str: ...
    async def settings(self, *, timeout: float | None = ...) -> dict[int, float]: ...
    async def status(self, *, fresh: bool = ..., timeout: float | None = ...) -> StatusReport: ...


class ArmView:
    """The 3D view of one connection while a block runs (see the module). ``url`` is the
    page's address with this run's secret (known once the block is entered)."""

    def __init__(
        self,
        arm: WatchedArm,
        observers: LineObservers,
        *,
        host: str,
        port: int,
        open_browser: bool,
        allow_remote: bool,
        wait_for_page: float | None,
    ) -> None:
        from mirobot_async._view.gate import is_loopback

        if not is_loopback(host) and not allow_remote:
            raise MirobotUsageError(
                f"view(host={host!r}): not a loopback address; anyone who reaches it with the "
                "URL sees the arm. Pass allow_remote=True to serve it anyway"
            )
        if wait_for_page is not None and not wait_for_page >= 0:
            raise MirobotUsageError(f"view(wait_for_page={wait_for_page!r}): must be >= 0 or None")
        if not 0 <= port <= 65535:
            raise MirobotUsageError(f"view(port={port!r}): must be 0..65535")
        self._arm = arm
        self._observers = observers
        self._host = host
        self._port = port
        self._open_browser = open_browser
        self._allow_remote = allow_remote
        self._wait_for_page = wait_for_page
        self._url: str | None = None
        self._server: viser.ViserServer | None = None
        self._tasks: list[asyncio.Task[None]] = []
        self._entered = False
        self._lines: ScriptLines | None = None  # what the page shows of the script's lines

    @property
    def url(self) -> str:
        """The page's URL with its secret (``http://127.0.0.1:PORT/?token=...``)."""
        if self._url is None:
            raise MirobotUsageError("the view's URL is known once its block is entered")
        return self._url

    @property
    def clients(self) -> int:
        """Pages connected now."""
        return 0 if self._server is None else len(self._server.get_clients())

    # ---- the block ------------------------------------------------------------------------

    async def __aenter__(self) -> ArmView:
        """Serve the page (the URL is printed on stderr, and opened in a browser if asked),
        then wait for a page to connect if asked (at most ``wait_for_page`` s; the script goes
        on without one then).
        Waits, at most :data:`SETUP_TIMEOUT` s, for the arm at rest when its firmware (or, on
        2021, its base offset ``$41..$43``) is not known yet: one ``$$``."""
        if self._entered:
            raise MirobotUsageError("a view can be entered only once; call arm.view() again")
        self._entered = True
        firmware = await self._learn(self._arm)
        first = await self._arm.status(fresh=True)  # the path starts here if at rest
        from mirobot_async._view.gate import serve_guarded, stop_server

        server, url = serve_guarded(self._host, self._port, allow_remote=self._allow_remote)
        try:
            self._build(server, firmware, first)  # no await: no line is written meanwhile
        except BaseException:
            stop_server(server)
            raise
        self._url = url
        print(f"mirobot: view: {self._url}", file=sys.stderr, flush=True)
        self._server = server
        self._tasks = [
            asyncio.create_task(self._follow(), name="mirobot-view-status"),
            asyncio.create_task(self._redraw(), name="mirobot-view-redraw"),
        ]
        if self._open_browser:
            webbrowser.open(self._url)
        if self._wait_for_page and not self.clients:
            try:
                async with asyncio.timeout(self._wait_for_page):
                    await self._page_connected.wait()
            except TimeoutError:
                _log.warning("no page connected to %s within %g s", self._url, self._wait_for_page)
            except BaseException as err:  # cancelled (Ctrl-C) while waiting: stop the server
                await self.__aexit__(type(err), err, err.__traceback__)
                raise
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        """Tell the page how the script ended, give it :data:`END_GRACE` s to hear it, stop."""
        if self._server is None:
            return
        self._observers.remove(self._watcher)
        for task in self._tasks:
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        last = self._arm.last_status  # the newest report, though the poll was cancelled
        if last is not None:
            self._show(last)
        self._draw()
        if exc is None:
            ended = "ended"
        elif isinstance(exc, asyncio.CancelledError | KeyboardInterrupt):
            ended = "stopped (interrupted)"
        else:
            ended = f"ended with an error: {type(exc).__name__}: {exc}"
        assert self._lines is not None
        self._script.content = (
            self._lines.describe(ended) + "\n\n*The script has ended: this page no longer updates.*"
        )
        server = self._server
        self._server = None
        try:
            server.flush()
            await asyncio.sleep(END_GRACE)
        finally:
            from mirobot_async._view.gate import stop_server

            stop_server(server)

    # ---- inside ---------------------------------------------------------------------------

    def _build(self, server: viser.ViserServer, firmware: str, first: StatusReport) -> None:
        """The page's widgets and scene, and the ear on the connection."""
        from mirobot_async._view.scene import ArmScene

        server.gui.configure_theme(
            control_width="large", dark_mode=False, show_logo=False, show_share_button=False
        )
        self._status = server.gui.add_markdown("**State:** connecting ...")
        self._script = server.gui.add_markdown("**Script: running**")
        self._scene = ArmScene(server, firmware)
        envelope = self._arm.envelope
        if envelope is not None:
            self._scene.show_envelope(envelope)
        self._dh = dh_of(firmware)
        self._trail_points: list[tuple[float, float, float]] = []
        self._trail_drawn = 0
        self._trail_chunks = 0
        self._trail_frozen: deque[viser.SceneNodeHandle] = deque()
        self._marks: list[viser.SceneNodeHandle] = []
        self._path_nodes: dict[int, tuple[viser.SceneNodeHandle, int]] = {}
        self._drawn_version = -1
        self._drawn_markers: list[Marker] = []
        self._lines = ScriptLines(firmware, envelope)
        self._page_connected = asyncio.Event()
        loop = asyncio.get_running_loop()

        def connected(_: viser.ClientHandle) -> None:
            loop.call_soon_threadsafe(self._page_connected.set)

        server.on_client_connect(connected)
        self._watcher = _Watcher(self._lines, loop.time())
        self._show(first)
        self._observers.add(self._watcher)

    @staticmethod
    async def _learn(arm: WatchedArm) -> str:
        """The arm's profile (for its geometry) and, off classic, its settings (the base
        offset the path of absolute ``M20`` lines needs): read once, at rest, if unknown."""
        firmware = arm.firmware
        try:
            if firmware is None:
                firmware = await arm.detect_firmware(timeout=SETUP_TIMEOUT)
            if firmware != "classic":
                await arm.settings(timeout=SETUP_TIMEOUT)
        except MirobotTimeoutError as err:
            raise MirobotTimeoutError(
                f"the arm to come to rest, to open its view ({err.waited_for})", SETUP_TIMEOUT
            ) from err
        return firmware

    async def _follow(self) -> None:
        """Show every status report until cancelled; the path starts at rest."""
        assert self._lines is not None
        while True:
            try:
                async with contextlib.aclosing(self._arm.statuses(STATUS_INTERVAL)) as reports:
                    async for report in reports:
                        self._show(report)
            except MirobotTimeoutError:
                self._status.content = "**State:** no status reply (homing?)"
            except MirobotConnectionError as err:
                self._status.content = f"**State: LINK LOST** ({err}); the arm's state is unknown"
                return
            except MirobotError as err:  # an alarm that answers nothing but a reset
                self._status.content = f"**State:** {err}"
                await asyncio.sleep(STATUS_INTERVAL * 10)

    def _show(self, report: StatusReport) -> None:
        """One status report on the page; at rest with nothing in flight, the path's start."""
        assert self._lines is not None
        self._scene.show_status(report)
        text = describe_status(report, None)
        if text != self._status.content:
            self._status.content = text
        at_rest = report.state in (State.IDLE, State.ALARM)
        if at_rest and self._arm.pending_count == 0:
            self._watcher.at_rest(report.joints)
        x, y, z, *_ = forward(report.joints, self._dh)
        point = (x * _M, y * _M, z * _M)
        if not self._trail_points or self._trail_points[-1] != point:
            self._trail_points.append(point)

    async def _redraw(self) -> None:
        while True:
            await asyncio.sleep(REDRAW_INTERVAL)
            self._draw()

    def _draw(self) -> None:
        """The predicted path, the markers, the trail and the script's text, where they
        changed. Path and trail are drawn in chunks (:data:`_PATH_CHUNK` lines,
        :data:`_TRAIL_CHUNK` points): only the newest chunk is sent again as it grows."""
        lines, server = self._lines, self._server
        if lines is None or server is None:
            return
        self._watcher.catch_up()
        if lines.version != self._drawn_version:
            self._drawn_version = lines.version
            self._draw_path(server, lines.path())
            markers = list(lines.markers)
            if markers != self._drawn_markers:
                self._drawn_markers = markers
                self._draw_markers(server, markers)
        text = lines.describe(None)
        if text != self._script.content:
            self._script.content = text
        self._draw_trail(server)

    def _draw_path(self, server: viser.ViserServer, path: list[PathSegment]) -> None:
        chunks: dict[int, list[PathSegment]] = {}
        for segment in path:
            if len(segment.points) >= 2:
                chunks.setdefault(segment.number // _PATH_CHUNK, []).append(segment)
        for key in [k for k in self._path_nodes if k not in chunks]:  # dropped (oldest)
            self._path_nodes.pop(key)[0].remove()
        for key, segments in chunks.items():
            drawn = self._path_nodes.get(key)
            if drawn is not None and drawn[1] == len(segments):
                continue
            pairs = np.concatenate(
                [np.stack([s.points[:-1], s.points[1:]], axis=1) for s in segments]
            )
            colours = np.concatenate(
                [
                    np.tile(PATH_COLOURS.get(s.kind, (0, 0, 0)), (len(s.points) - 1, 2, 1))
                    for s in segments
                ]
            ).astype(np.uint8)
            node = server.scene.add_line_segments(
                f"/script/path/{key}", pairs * _M, colours, thickness=3.0, thickness_units="screen"
            )
            self._path_nodes[key] = (node, len(segments))

    def _draw_markers(self, server: viser.ViserServer, markers: list[Marker]) -> None:
        for node in self._marks:
            node.remove()
        self._marks = []
        seen: dict[tuple[float, float, float], int] = {}
        for i, marker in enumerate(markers):
            x, y, z = marker.point
            above = seen.get(marker.point, 0)  # labels of one place stacked, not overlaid
            seen[marker.point] = above + 1
            self._marks.append(
                server.scene.add_icosphere(
                    f"/script/refused/{i}",
                    radius=0.009,
                    color=REFUSED_COLOUR,
                    position=(x * _M, y * _M, z * _M),
                )
            )
            self._marks.append(
                server.scene.add_label(
                    f"/script/refused/{i}/label", marker.label, position=(0, 0, 0.02 + 0.02 * above)
                )
            )

    def _draw_trail(self, server: viser.ViserServer) -> None:
        points = self._trail_points
        if len(points) < 2 or self._trail_drawn == len(points):
            return
        pairs = np.asarray(points)
        self._trail_node = server.scene.add_line_segments(
            f"/script/trail/{self._trail_chunks}",
            np.stack([pairs[:-1], pairs[1:]], axis=1),
            _TRAIL_COLOUR,
            thickness=2.0,
            thickness_units="screen",
        )
        self._trail_drawn = len(points)
        if len(points) >= _TRAIL_CHUNK:  # frozen: the next chunk starts at its last point
            self._trail_frozen.append(self._trail_node)
            if len(self._trail_frozen) > _TRAIL_CHUNKS_KEPT:
                self._trail_frozen.popleft().remove()
            self._trail_chunks += 1
            self._trail_points = [points[-1]]
            self._trail_drawn = 1


class _Watcher:
    """The view's ear on the connection. The client tells it each fact on the loop, in the
    middle of writing lines: it only notes them (with the modes and the time they came with),
    and :meth:`catch_up` hands them to :class:`ScriptLines` in order when the page is redrawn,
    so that predicting the path never delays a line."""

    def __init__(self, lines: ScriptLines, opened: float) -> None:
        self._lines = lines
        self._opened = opened
        self._loop = asyncio.get_running_loop()
        self._facts: list[Callable[[], object]] = []
        self._keys: dict[int, tuple[OutgoingLine, int]] = {}  # the lines awaiting a reply
        self._next_key = 0

    def _t(self) -> float:
        return self._loop.time() - self._opened

    def catch_up(self) -> None:
        """Hand every fact noted so far to the model, oldest first."""
        facts, self._facts = self._facts, []
        for fact in facts:
            fact()

    def at_rest(self, joints: Joints) -> None:
        self._facts.append(functools.partial(self._lines.at_rest, joints))

    def line_written(
        self, line: OutgoingLine, modes: MotionModes, base_offset: Offset | None
    ) -> None:
        self._next_key += 1
        if len(self._keys) >= _KEYS_KEPT:  # lines a reset left unanswered
            self._keys.clear()
        self._keys[id(line)] = (line, self._next_key)
        self._facts.append(
            functools.partial(
                self._lines.written, self._next_key, line.parsed, line.command, modes, base_offset
            )
        )

    def line_answered(self, line: OutgoingLine, reply: LineAcknowledged | LineRejected) -> None:
        _, key = self._keys.pop(id(line), (line, 0))
        answered = functools.partial(self._lines.answered, key, line.command, self._t())
        if isinstance(reply, LineRejected):
            self._facts.append(functools.partial(answered, error=reply.text))
        else:
            refusal = reply.refusal
            self._facts.append(
                functools.partial(answered, refused=None if refusal is None else refusal.text)
            )

    def line_not_sent(self, command: str, error: MirobotError) -> None:
        self._facts.append(functools.partial(self._lines.not_sent, command, str(error), self._t()))

    def alarm(self, text: str) -> None:
        self._facts.append(functools.partial(self._lines.alarm, text, self._t()))

    def reset(self) -> None:
        self._facts.append(functools.partial(self._lines.reset, self._t()))
