"""The 3D scene of ``mirobot view``: the arm (our URDF through viser's URDF loader), the rail,
the envelope's box, a program's predicted path with its flagged lines, and the tool point.

Lengths are metres in the scene (the URDF's unit); the kinematics work in millimetres. The rail
(when the status has one) carries the arm along the base's y axis: PROTOCOL gives its travel
(mm) but not its direction, so y is this view's choice.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from typing import TYPE_CHECKING, Final

import numpy as np
import viser
import yourdfpy
from viser.extras import ViserUrdf

from mirobot_async._urdf import build_urdf, dh_of
from mirobot_async._view.preview import PATH_COLOURS, REFUSED_COLOUR, ProgramPreview
from mirobot_async.kinematics import forward

if TYPE_CHECKING:
    from mirobot_async._core.replies import StatusReport
    from mirobot_async._safety.envelope import Envelope

__all__ = ["ArmScene"]

_M: Final = 0.001
_REACH_MM: Final = 450.0
"""How far an open side of the envelope's box is drawn (beyond the arm's reach)."""


class ArmScene:
    """The scene nodes of one view and their updates (safe to call from any thread)."""

    def __init__(self, server: viser.ViserServer, firmware: str) -> None:
        self._server = server
        self._firmware = firmware
        self._dh = dh_of(firmware)
        scene = server.scene
        scene.set_up_direction("+z")
        scene.configure_environment_map(environment_intensity=0.35)
        scene.configure_default_lights(cast_shadow=False)  # shadows cost software renderers
        scene.add_grid("/ground", width=1.0, height=1.0, cell_size=0.05, section_size=0.1)
        self.base = scene.add_frame("/arm", show_axes=False)
        model = yourdfpy.URDF.load(io.StringIO(build_urdf(firmware)))
        self.urdf = ViserUrdf(server, model, root_node_name="/arm")
        self.tool = scene.add_icosphere("/tool", radius=0.006, color=(240, 120, 20))
        self._rail: viser.SceneNodeHandle | None = None
        self._path_nodes: list[viser.SceneNodeHandle] = []
        self.joints: tuple[float, ...] = (0.0,) * 6
        self.show_joints((0.0,) * 6, None)
        server.initial_camera.position = (0.42, -0.42, 0.34)
        server.initial_camera.look_at = (0.1, 0.0, 0.1)

    def show_joints(self, joints: Sequence[float], rail: float | None) -> None:
        """Pose the arm (degrees, rail mm) and the tool point."""
        self.joints = tuple(joints)
        self.urdf.update_cfg(np.radians(np.asarray(joints, dtype=float)))
        offset = (0.0, 0.0 if rail is None else rail * _M, 0.0)
        self.base.position = offset
        x, y, z, *_ = forward(joints, self._dh)
        self.tool.position = (x * _M + offset[0], y * _M + offset[1], z * _M + offset[2])
        if rail and self._rail is None:  # the 2021 status always has D: drawn once it moves
            self._rail = self._server.scene.add_box(
                "/rail",
                color=(90, 90, 100),
                dimensions=(0.14, 1.2, 0.02),
                position=(0, 0.5, -0.011),
            )

    def show_status(self, report: StatusReport) -> None:
        self.show_joints(report.joints, report.rail)

    def show_envelope(self, envelope: Envelope) -> None:
        """The envelope's box (open sides drawn to beyond the reach), as a wireframe."""
        if not envelope.has_box:
            return
        lows, highs = [], []
        for bound in (envelope.x, envelope.y, envelope.z):
            low = -_REACH_MM if bound is None or bound[0] is None else bound[0]
            high = _REACH_MM if bound is None or bound[1] is None else bound[1]
            lows.append(low)
            highs.append(high)
        size = ((highs[0] - lows[0]) * _M, (highs[1] - lows[1]) * _M, (highs[2] - lows[2]) * _M)
        centre = (
            (highs[0] + lows[0]) / 2 * _M,
            (highs[1] + lows[1]) / 2 * _M,
            (highs[2] + lows[2]) / 2 * _M,
        )
        self._server.scene.add_box(
            "/envelope", color=(230, 160, 0), dimensions=size, position=centre, wireframe=True
        )
        self._server.scene.add_box(
            "/envelope_fill", color=(250, 200, 60), dimensions=size, position=centre, opacity=0.08
        )

    def show_preview(self, preview: ProgramPreview) -> None:
        """The predicted path (blue: joint-space, green: Cartesian, grey: IK-branch snaps) and
        a red marker with its line number at each flagged line."""
        for node in self._path_nodes:
            node.remove()
        self._path_nodes.clear()
        scene = self._server.scene
        for i, segment in enumerate(preview.segments):
            pts = segment.points * _M
            if len(pts) < 2:
                continue
            pairs = np.stack([pts[:-1], pts[1:]], axis=1)
            self._path_nodes.append(
                scene.add_line_segments(
                    f"/program/path/{i}",
                    pairs,
                    PATH_COLOURS.get(segment.kind, (0, 0, 0)),
                    thickness=4.0,
                    thickness_units="screen",
                )
            )
        where = self._marker_positions(preview)
        for flag in preview.flagged:
            position = where.get(flag.number, (0.0, 0.0, 0.0))
            self._path_nodes.append(
                scene.add_icosphere(
                    f"/program/flag/{flag.number}",
                    radius=0.011,
                    color=REFUSED_COLOUR,
                    position=position,
                )
            )
            self._path_nodes.append(
                scene.add_label(
                    f"/program/flag/{flag.number}/label",
                    f"line {flag.number}",
                    position=(0, 0, 0.02),
                )
            )

    def _marker_positions(self, preview: ProgramPreview) -> dict[int, tuple[float, float, float]]:
        """Where each flagged line's marker goes: the end of the path drawn before it."""
        ends = [(s.number, s.points[-1]) for s in preview.segments if len(s.points)]
        home = forward((0.0,) * 6, self._dh)
        out: dict[int, tuple[float, float, float]] = {}
        for flag in preview.flagged:
            point: Sequence[float] = home[:3]
            for number, end in ends:
                if number < flag.number:
                    point = end
            out[flag.number] = (point[0] * _M, point[1] * _M, point[2] * _M)
        return out
