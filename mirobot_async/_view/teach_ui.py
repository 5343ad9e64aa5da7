"""The teach pendant's widgets and behaviour: a thin viser UI over
:class:`~mirobot_async._view.program.ProgramTable`.

:class:`TeachPanel` builds the Teach folder's widgets (every button hands its text to one
callback: the controller queues it on the client's loop). :class:`Teacher` runs those on the
loop, in order: record a point, add an action (pump, gripper, dwell, speed), select, move,
delete, edit a row as its G-code line, go to a point, Play (a slow first move to the first
point, then the table ``Loops`` times), export and import (file name only, in the export folder
fixed at start; no overwrite without the Overwrite box). Taught points are drawn in 3D as
numbered spheres joined by a line.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import numpy as np
import viser

from mirobot_async._urdf import dh_of
from mirobot_async._view.program import (
    OUTPUTS,
    Dwell,
    Output,
    OutputName,
    ProgramTable,
    Speed,
    parse_program,
    parse_row,
    play_lines,
    program_lines,
    row_line,
    table_markdown,
)
from mirobot_async._view.teach import TaughtPoint, export_name, modes_line, write_export
from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import forward

if TYPE_CHECKING:
    from mirobot_async._client.client import Mirobot
    from mirobot_async._core.replies import StatusReport

__all__ = ["PLAY", "TeachPanel", "Teacher"]

PLAY: Final = "Play"
"""The button that runs the table (a program: jogs are refused while it runs)."""
_ADD: Final[dict[str, OutputName]] = {f"+ {name}": name for name in OUTPUTS}
_M: Final = 0.001
_POINT_COLOUR: Final = (230, 60, 160)


class TeachPanel:
    """The Teach folder's widgets (built inside the folder by the control panel)."""

    def __init__(self, gui: viser.GuiApi, on: Callable[[str], None]) -> None:
        def pick(event: viser.GuiEvent[viser.GuiButtonGroupHandle]) -> None:
            on(event.target.value)

        def button(text: str, **kwargs: Any) -> None:
            gui.add_button(text, **kwargs).on_click(lambda _: on(text))

        button("Record point", color="blue")
        gui.add_button_group("Add output", tuple(_ADD)).on_click(pick)
        self.dwell = gui.add_number("Dwell (s)", 1.0, min=0.0, max=600.0, step=0.1)
        self.row_speed = gui.add_number("Row speed (deg/min)", 1000.0, min=10.0, max=3000.0)
        gui.add_button_group("Add", ("+ dwell", "+ speed")).on_click(pick)
        self.table = gui.add_markdown("")
        self.point = gui.add_number("Row #", 1, min=1, max=999, step=1)
        gui.add_button_group("Row", ("Go to", "Up", "Down", "Delete", "Set here")).on_click(pick)
        self.row_text = gui.add_text("Row G-code", "")
        button("Apply row")
        self.speed = gui.add_number("Program speed (deg/min)", 2000.0, min=10.0, max=3000.0)
        self.loops = gui.add_number("Loops", 1, min=1, max=999, step=1)
        button(PLAY, color="green")
        self.file = gui.add_text("File", "taught.gcode")  # in the export folder
        self.overwrite = gui.add_checkbox("Overwrite", False)
        gui.add_button_group("G-code", ("Export", "Import")).on_click(pick)
        self.exported = gui.add_markdown("")


class Teacher:
    """The table and what the Teach buttons do (run on the client's loop, one at a time)."""

    def __init__(
        self, server: viser.ViserServer, panel: TeachPanel, *, firmware: str, export_dir: Path
    ) -> None:
        self.server = server
        self.panel = panel
        self.firmware = firmware
        self.export_dir = export_dir
        self.table = ProgramTable()
        self._nodes: list[Any] = []
        self.show()

    def _selected(self) -> int:
        return int(self.panel.point.value)

    async def act(self, name: str, arm: Mirobot) -> str | None:
        """Do what the button ``name`` asks; the message for the page (None: "done")."""
        table, panel = self.table, self.panel
        said = None
        if name in ("Record point", "Set here"):
            report: StatusReport = await arm.status(fresh=True)
            point = TaughtPoint(report.joints, report.rail, report.pose)
            if name == "Set here":
                table.replace(self._selected(), point)
            else:
                number = table.add(point)
                _set(panel.point, number)
                said = f"Recorded point {number}"
        elif name in _ADD:
            _set(panel.point, table.add(Output(_ADD[name])))
        elif name == "+ dwell":
            _set(panel.point, table.add(Dwell(round(float(panel.dwell.value), 3))))
        elif name == "+ speed":
            _set(panel.point, table.add(Speed(round(float(panel.row_speed.value), 1))))
        elif name in ("Up", "Down"):
            _set(panel.point, table.move(self._selected(), -1 if name == "Up" else 1))
        elif name == "Delete":
            table.delete(self._selected())
        elif name == "Apply row":
            table.replace(self._selected(), parse_row(panel.row_text.value, firmware=self.firmware))
        elif name == "Go to":
            row = table.get(self._selected())
            if not isinstance(row, TaughtPoint):
                raise MirobotUsageError(f"row {self._selected()} is not a point")
            lines = [modes_line(self._speed()), row_line(row, firmware=self.firmware)]
            await _stream(arm, lines)
        elif name == PLAY:
            said = await self._play(arm)
        elif name == "Export":
            said = self._export()
        elif name == "Import":
            said = self._import()
        self.show()
        return said

    def _speed(self) -> float:
        return round(float(self.panel.speed.value), 1)

    async def _play(self, arm: Mirobot) -> str:
        loops = int(self.panel.loops.value)
        program = self.table.program(self._speed())
        await _stream(arm, play_lines(program, loops=loops, firmware=self.firmware))
        return f"Played {len(program.rows)} rows x {loops}"

    def _export(self) -> str:
        lines = program_lines(self.table.program(self._speed()), firmware=self.firmware)
        name = export_name(self.panel.file.value)
        try:
            write_export(
                self.export_dir / name,
                "\n".join(lines) + "\n",
                overwrite=self.panel.overwrite.value,
            )
        except FileExistsError:
            raise MirobotUsageError(
                f"{name} exists in {self.export_dir}: tick Overwrite to replace it, or give "
                "another name"
            ) from None
        finally:
            _set(self.panel.overwrite, False)
        shown = "\n".join(lines)
        self.panel.exported.content = f"```\n{shown}\n```"
        points = len(self.table.points())
        actions = len(self.table.rows) - points
        extra = f", {actions} actions" if actions else ""
        return f"Wrote {name} ({points} points{extra}) in {self.export_dir}"

    def _import(self) -> str:
        name = export_name(self.panel.file.value)
        path = self.export_dir / name
        try:
            text = path.read_text(encoding="ascii")
        except (OSError, UnicodeDecodeError) as err:
            raise MirobotUsageError(f"cannot read {name} in {self.export_dir}: {err}") from None
        program = parse_program(text.splitlines(), firmware=self.firmware, name=name)
        self.table.rows = list(program.rows)
        _set(self.panel.speed, program.speed)
        _set(self.panel.point, 1)
        return f"Imported {name}: {len(program.rows)} rows"

    def show(self) -> None:
        """The table's text, the selected row's line, the points in 3D."""
        table, panel = self.table, self.panel
        selected = self._selected()
        if selected > len(table.rows) >= 1:  # the last row was deleted: select the new last
            selected = len(table.rows)
            _set(panel.point, selected)
        panel.table.content = table_markdown(table.rows, selected)
        if 1 <= selected <= len(table.rows):
            _set(panel.row_text, row_line(table.get(selected), firmware=self.firmware))
        else:
            _set(panel.row_text, "")
        for node in self._nodes:
            node.remove()
        self._nodes.clear()
        scene = self.server.scene
        dh = dh_of(self.firmware)
        where = []
        for number, point in table.points():
            x, y, z, *_ = forward(point.joints, dh)
            rail = point.rail or 0.0
            position = (x * _M, (y + rail) * _M, z * _M)
            where.append(position)
            self._nodes.append(
                scene.add_icosphere(
                    f"/teach/point/{number}", radius=0.007, color=_POINT_COLOUR, position=position
                )
            )
            self._nodes.append(
                scene.add_label(f"/teach/point/{number}/label", f"{number}", position=(0, 0, 0.015))
            )
        if len(where) >= 2:
            pts = np.asarray(where)
            self._nodes.append(
                scene.add_line_segments(
                    "/teach/path",
                    np.stack([pts[:-1], pts[1:]], axis=1),
                    _POINT_COLOUR,
                    thickness=2.5,
                    thickness_units="screen",
                )
            )


async def _stream(arm: Mirobot, lines: list[str]) -> None:
    result = await arm.stream(lines, wait=True)
    if result.errors:
        failed = result.errors[0]
        raise MirobotUsageError(f"stopped at line {failed.number}: {failed.error or 'failed'}")


def _set(handle: Any, value: object) -> None:
    """Set an input's value (viser types ``value`` read-only on some handles; the setter
    exists and sends the value to the page)."""
    handle.value = value
