"""The teach table as a program: rows of poses and actions, and their G-code both ways.

A row is a taught :class:`~mirobot_async._view.teach.TaughtPoint` (joints, rail, pose), an
:class:`Output` (pump on/blow/off, gripper open/close), a :class:`Dwell` or a :class:`Speed`.
:func:`program_lines` writes a table as the program ``mirobot check`` accepts and ``mirobot run``
runs: a title comment, the modes line (``M21 G90 G21 G1 F<speed>``: joint moves), then one line
per row. :func:`parse_program` reads such a program back into rows (``rows -> lines -> rows`` is
the identity; the tests check it with hypothesis). :func:`play_lines` is what "Play" streams: a
slow first move to the first point, then the rows ``loops`` times. Pure module.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Final, Literal

from mirobot_async._core import gcode
from mirobot_async._view.teach import (
    DEFAULT_TEACH_SPEED,
    TaughtPoint,
    modes_line,
    point_line,
)
from mirobot_async.errors import MirobotUsageError

__all__ = [
    "OUTPUTS",
    "SLOW_FIRST_SPEED",
    "Dwell",
    "Output",
    "ProgramTable",
    "Row",
    "Speed",
    "TeachProgram",
    "describe_row",
    "parse_program",
    "parse_row",
    "play_lines",
    "program_lines",
    "row_line",
    "table_markdown",
]

OutputName = Literal["pump on", "pump blow", "pump off", "gripper open", "gripper close"]
OUTPUTS: Final[dict[OutputName, int]] = {
    "pump on": gcode.PUMP_SUCK,
    "pump blow": gcode.PUMP_BLOW,
    "pump off": gcode.PUMP_OFF,
    "gripper open": gcode.GRIPPER_OPEN,
    "gripper close": gcode.GRIPPER_CLOSE,
}
"""The outputs a row can set: PWM 1 (``M3 S<pwm>``) values."""
_BY_PWM: Final = {pwm: name for name, pwm in OUTPUTS.items()}
SLOW_FIRST_SPEED: Final = 500.0
"""Joint speed (deg/min) of Play's first move to the first point (from wherever the arm is)."""


@dataclass(frozen=True, slots=True)
class Output:
    """Set the pump or the gripper (PWM 1)."""

    name: OutputName


@dataclass(frozen=True, slots=True)
class Dwell:
    """Wait ``seconds`` once the moves before have ended (``G4 P``)."""

    seconds: float


@dataclass(frozen=True, slots=True)
class Speed:
    """Joint speed (deg/min) of the moves after this row (``F``)."""

    deg_per_min: float


Row = TaughtPoint | Output | Dwell | Speed


@dataclass(frozen=True, slots=True)
class TeachProgram:
    """The table's rows and its speed (the modes line's feed: moves before any Speed row)."""

    rows: tuple[Row, ...]
    speed: float = DEFAULT_TEACH_SPEED


def row_line(row: Row, *, firmware: str = "2021") -> str:
    """One row's G-code line (values checked: joint ranges, seconds >= 0, speed > 0)."""
    if isinstance(row, TaughtPoint):
        return point_line(row, firmware=firmware)
    if isinstance(row, Output):
        return gcode.set_pump(OUTPUTS[row.name]).decode().strip()
    if isinstance(row, Dwell):
        return gcode.dwell(row.seconds).decode().strip()
    return gcode.feed_rate(row.deg_per_min, decimals=1).decode().strip()


def describe_row(row: Row) -> str:
    """A row as the table shows it."""
    if isinstance(row, TaughtPoint):
        return row.describe()
    if isinstance(row, Output):
        return row.name
    if isinstance(row, Dwell):
        return f"dwell {row.seconds:g} s"
    return f"speed {row.deg_per_min:g} deg/min"


def program_lines(
    program: TeachProgram, *, firmware: str = "2021", title: str = "taught with mirobot view"
) -> list[str]:
    """The program (lines, no line endings): title, modes, one line per row."""
    if not any(isinstance(r, TaughtPoint) for r in program.rows):
        raise MirobotUsageError("no points in the table: record some first")
    head = f"({title}: {len(program.rows)} rows, firmware {firmware})"
    return [head, modes_line(program.speed)] + [
        row_line(r, firmware=firmware) for r in program.rows
    ]


def play_lines(
    program: TeachProgram,
    *,
    loops: int = 1,
    first_speed: float = SLOW_FIRST_SPEED,
    firmware: str = "2021",
) -> list[str]:
    """What Play streams: to the first point at ``first_speed``, then the table ``loops`` times
    (each pass starts at the table's speed). Ends where :func:`program_lines` ends, with the
    same outputs."""
    if loops < 1:
        raise MirobotUsageError(f"loops={loops!r} must be >= 1")
    points = [r for r in program.rows if isinstance(r, TaughtPoint)]
    if not points:
        raise MirobotUsageError("no points in the table: record some first")
    speed = min(first_speed, program.speed)
    lines = [modes_line(speed), point_line(points[0], firmware=firmware)]
    body = [row_line(r, firmware=firmware) for r in program.rows]
    feed = row_line(Speed(program.speed))
    for _ in range(loops):
        lines += [feed, *body]
    return lines


_MODES: Final = re.compile(r"^M21 G90 G21 G1 F(?P<speed>[0-9.]+)$")
_WORD: Final = re.compile(r"([A-Z])(-?[0-9.]+)")


def parse_program(
    lines: Iterable[str], *, firmware: str = "2021", name: str = "program"
) -> TeachProgram:
    """Rows from a program in :func:`program_lines`' form (comments and blank lines skipped).
    Raises :class:`MirobotUsageError` naming the line of anything else."""
    from mirobot_async._urdf import dh_of
    from mirobot_async.kinematics import forward

    dh = dh_of(firmware)
    rows: list[Row] = []
    speed: float | None = None
    for number, raw in enumerate(lines, start=1):
        text = raw.split(";", 1)[0].strip()
        if not text or (text.startswith("(") and text.endswith(")")):
            continue
        where = f"{name}:{number}: {raw.strip()!r}"
        modes = _MODES.match(text)
        if modes:
            if speed is not None or rows:
                raise MirobotUsageError(f"{where}: the modes line comes once, first")
            speed = float(modes["speed"])
            continue
        if speed is None:
            raise MirobotUsageError(f"{where}: expected the modes line 'M21 G90 G21 G1 F<speed>'")
        words = _WORD.findall(text)
        if " ".join(f"{k}{v}" for k, v in words) != text:
            raise MirobotUsageError(f"{where}: not a teach-table line")
        letters = "".join(k for k, _ in words)
        try:
            values = [float(v) for _, v in words]
        except ValueError:
            raise MirobotUsageError(f"{where}: not a number") from None
        if letters in ("XYZABC", "XYZABCD"):
            joints = (values[0], values[1], values[2], values[3], values[4], values[5])
            rail = values[6] if len(values) == 7 else None
            row: Row = TaughtPoint(joints, rail, forward(joints, dh))
        elif letters == "MS" and values[0] == 3 and int(values[1]) in _BY_PWM:
            row = Output(_BY_PWM[int(values[1])])
        elif letters == "GP" and values[0] == 4:
            row = Dwell(values[1])
        elif letters == "F":
            row = Speed(values[0])
        else:
            raise MirobotUsageError(
                f"{where}: not a teach-table line (joint moves, M3 S<pump/gripper>, G4 P, F)"
            )
        try:
            row_line(row, firmware=firmware)  # its values are in range
        except MirobotUsageError as err:
            raise MirobotUsageError(f"{where}: {err}") from None
        rows.append(row)
    if speed is None:
        raise MirobotUsageError(f"{name}: no modes line 'M21 G90 G21 G1 F<speed>'")
    return TeachProgram(tuple(rows), speed)


def table_markdown(rows: Sequence[Row], selected: int | None = None) -> str:
    """The rows as Markdown (the page shows it)."""
    if not rows:
        return "*No rows yet: jog the arm, then **Record point**; add actions below.*"
    out = ["| # | row |", "|---|---|"]
    for n, row in enumerate(rows, start=1):
        mark = f"**{n}**" if n == selected else str(n)
        out.append(f"| {mark} | {describe_row(row)} |")
    return "\n".join(out)


class ProgramTable:
    """The pendant's rows (1-based numbers): add, insert, replace (edit), move, delete."""

    def __init__(self, rows: Iterable[Row] = ()) -> None:
        self.rows: list[Row] = list(rows)

    def _index(self, number: int) -> int:
        if not 1 <= number <= len(self.rows):
            raise MirobotUsageError(f"there is no row {number} (the table has {len(self.rows)})")
        return number - 1

    def add(self, row: Row) -> int:
        """Append; returns the row's number."""
        self.rows.append(row)
        return len(self.rows)

    def get(self, number: int) -> Row:
        return self.rows[self._index(number)]

    def replace(self, number: int, row: Row) -> None:
        self.rows[self._index(number)] = row

    def delete(self, number: int) -> None:
        del self.rows[self._index(number)]

    def move(self, number: int, offset: int) -> int:
        """Move row ``number`` up (-1) or down (+1); returns its new number."""
        i = self._index(number)
        j = min(max(i + offset, 0), len(self.rows) - 1)
        self.rows.insert(j, self.rows.pop(i))
        return j + 1

    def points(self) -> list[tuple[int, TaughtPoint]]:
        """(row number, point) of each point row."""
        return [(n, r) for n, r in enumerate(self.rows, start=1) if isinstance(r, TaughtPoint)]

    def program(self, speed: float) -> TeachProgram:
        return TeachProgram(tuple(self.rows), speed)


def parse_row(text: str, *, firmware: str = "2021") -> Row:
    """One row from its G-code line (the page's row editor)."""
    program = parse_program(["M21 G90 G21 G1 F2000", text], firmware=firmware, name="row")
    if len(program.rows) != 1:
        raise MirobotUsageError(f"row {text!r}: one G-code line of the table's kinds")
    return program.rows[0]
