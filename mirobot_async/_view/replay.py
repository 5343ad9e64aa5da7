"""``mirobot view --replay FILE``: scrub a run that happened, offline (no arm, no emulator).

The page shows the arm as it reported itself at the slider's instant, the tool path so far
(dark; the whole path faint), a marker at each event so far (outputs purple, refusals and
alarms red) and the list of events up to that instant. "Play" runs the slider at real time;
"Prev event" / "Next event" jump between events. Built on
:class:`~mirobot_async._view.timeline.Timeline` (pure); this module is its thin viser UI.
"""

from __future__ import annotations

import argparse
import asyncio
import threading
import webbrowser
from typing import Any, Final

import numpy as np
import viser

from mirobot_async._cli.exits import CliError, note
from mirobot_async._urdf import dh_of
from mirobot_async._view.scene import ArmScene
from mirobot_async._view.timeline import Sample, Timeline, load_timeline
from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import forward

__all__ = ["ReplayView", "describe_instant", "serve_replay"]

_M: Final = 0.001
_TICK: Final = 0.1
"""Seconds between the slider's steps while playing."""
_EVENT_COLOURS: Final = {"output": (150, 60, 200), "refusal": (220, 30, 30), "alarm": (220, 30, 30)}
_SHOWN_EVENTS: Final = 8


def describe_instant(line: Timeline, t: float) -> str:
    """The panel's text at ``t``: the arm's last report and the events so far (Markdown)."""
    s = line.sample_at(t)
    joints = "  ".join(f"J{i} {v:.2f}" for i, v in enumerate(s.joints, start=1))
    x, y, z = s.xyz
    outputs = "" if s.pump is None else f"  \n**Outputs:** PWM1 {s.pump}  PWM2 {s.valve}"
    rail = "" if s.rail is None else f"  \n**Rail:** {s.rail:.2f} mm"
    events = line.events_to(t)
    shown = events[-_SHOWN_EVENTS:]
    rows = "\n".join(f"- {e.t:.2f} s **{e.kind}**: {e.label}" for e in shown)
    more = f"  \n({len(events) - len(shown)} earlier)" if len(events) > len(shown) else ""
    head = (
        f"**At {t:.2f} s of {line.duration:.2f} s** (report {line.index_at(t) + 1} of "
        f"{len(line.samples)})  \n**State:** {s.state}  \n**Joints:** {joints}  \n"
        f"**Tool:** x {x:.2f}  y {y:.2f}  z {z:.2f}{rail}{outputs}"
    )
    listed = f"**Events so far ({len(events)}):**\n{rows}{more}" if events else "*No events yet.*"
    return f"{head}\n\n{listed}"


class ReplayView:
    """The scene and the slider of one replay (viser's threads call its handlers)."""

    def __init__(self, server: viser.ViserServer, line: Timeline, firmware: str) -> None:
        self.server = server
        self.line = line
        self.scene = ArmScene(server, firmware)
        self._dh = dh_of(firmware)
        self._lock = threading.Lock()
        self._nodes: list[Any] = []
        self.playing = False
        gui = server.gui
        gui.configure_theme(
            control_width="large", dark_mode=False, show_logo=False, show_share_button=False
        )
        gui.add_markdown(
            f"**Replay of {line.source}**: {len(line.samples)} reports, "
            f"{len(line.events)} events, {line.duration:.2f} s"
        )
        step = max(line.duration / 1000.0, 0.001)
        self.slider = gui.add_slider(
            "Time (s)", min=0.0, max=max(line.duration, step), step=step, initial_value=0.0
        )
        self.slider.on_update(lambda _: self.show(float(self.slider.value)))
        moves = gui.add_button_group("Replay", ("Start", "Prev event", "Next event", "End"))
        moves.on_click(lambda e: self.jump(e.target.value))
        play = gui.add_button_group("Play", ("Play", "Pause"))
        play.on_click(lambda e: self.set_playing(e.target.value == "Play"))
        self.text = gui.add_markdown("")
        whole = [self._tool(s) for s in line.samples]
        if len(whole) >= 2:
            pts = np.asarray(whole)
            server.scene.add_line_segments(
                "/replay/whole",
                np.stack([pts[:-1], pts[1:]], axis=1),
                (190, 190, 200),
                thickness=2.0,
                thickness_units="screen",
            )
        self.show(0.0)

    def _tool(self, s: Sample) -> tuple[float, float, float]:
        """The tool point in the scene (m): from the joints (and rail) as the arm is drawn."""
        x, y, z, *_ = forward(s.joints, self._dh)
        rail = 0.0 if s.rail is None else s.rail
        return (x * _M, (y + rail) * _M, z * _M)

    def show(self, t: float) -> None:
        """Pose the arm, draw the path and the events up to ``t``, write the text."""
        line = self.line
        with self._lock:
            sample = line.sample_at(t)
            self.scene.show_joints(sample.joints, sample.rail)
            for node in self._nodes:
                node.remove()
            self._nodes.clear()
            upto = line.samples[: line.index_at(t) + 1]
            pts = np.asarray([self._tool(s) for s in upto])
            scene = self.server.scene
            if len(pts) >= 2:
                self._nodes.append(
                    scene.add_line_segments(
                        "/replay/path",
                        np.stack([pts[:-1], pts[1:]], axis=1),
                        (20, 60, 160),
                        thickness=5.0,
                        thickness_units="screen",
                    )
                )
            for i, event in enumerate(line.events_to(t)):
                self._nodes.append(
                    scene.add_icosphere(
                        f"/replay/event/{i}",
                        radius=0.008,
                        color=_EVENT_COLOURS.get(event.kind, (220, 30, 30)),
                        position=self._tool(line.sample_at(event.t)),
                    )
                )
            self.text.content = describe_instant(line, t)

    def _set(self, t: float) -> None:
        handle: Any = self.slider  # viser types value read-only; its setter updates the page
        handle.value = min(max(t, 0.0), float(self.slider.max))  # shown via on_update

    def jump(self, where: str) -> None:
        now = float(self.slider.value)
        times = sorted({e.t for e in self.line.events})
        if where == "Start":
            self._set(0.0)
        elif where == "End":
            self._set(self.line.duration)
        elif where == "Next event":
            after = [t for t in times if t > now + 1e-9]
            self._set(after[0] if after else self.line.duration)
        else:
            before = [t for t in times if t < now - 1e-9]
            self._set(before[-1] if before else 0.0)

    def set_playing(self, on: bool) -> None:
        if on and float(self.slider.value) >= self.line.duration:
            self._set(0.0)
        self.playing = on

    async def play(self) -> None:
        """Advance the slider at real time while playing (until cancelled)."""
        while True:
            await asyncio.sleep(_TICK)
            if self.playing:
                now = float(self.slider.value)
                if now >= self.line.duration:
                    self.playing = False
                else:
                    self._set(now + _TICK)


async def serve_replay(args: argparse.Namespace) -> int:
    """Serve the replay of ``args.replay`` until interrupted (no arm is opened)."""
    from mirobot_async._view.gate import is_loopback, serve_guarded, stop_server
    from mirobot_async._view.listen import parse_listen

    try:
        line = load_timeline(args.replay)
    except (MirobotUsageError, OSError) as err:
        raise CliError(f"--replay {args.replay}: {err}") from None
    host, port = parse_listen(args.listen)
    allow_remote = bool(getattr(args, "allow_remote", False))
    if not is_loopback(host) and not allow_remote:
        raise CliError(f"--listen {args.listen}: {host} is not a loopback address (--allow-remote)")
    try:
        server, url = serve_guarded(host, port, allow_remote=allow_remote)
    except MirobotUsageError as err:
        raise CliError(str(err)) from None
    try:
        print(url, flush=True)
        note(f"replaying {line.source}: {len(line.samples)} reports, {len(line.events)} events")
        view = ReplayView(server, line, getattr(args, "firmware", None) or "2021")
        if not args.no_browser:
            webbrowser.open(url)
        await view.play()
    finally:
        stop_server(server)
    return 0
