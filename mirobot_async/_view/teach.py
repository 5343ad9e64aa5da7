"""The teach pendant's table of points and the G-code program it exports.

A taught point is the arm's joints (and rail) when "Record point" was pressed, with its pose
for display. The export is joint-space moves, so that ``mirobot run`` drives the arm to exactly
the recorded joints (a pose has several IK solutions; joints have one): the modes are stated
once in the first line (``M21 G90 G21 G1 F<speed>``), then one line of axis words per point. The
output passes ``mirobot check`` (tests run it). Pure module.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from mirobot_async._core import gcode
from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import Joints, Pose

__all__ = [
    "DEFAULT_TEACH_SPEED",
    "TaughtPoint",
    "TeachTable",
    "export_name",
    "export_program",
    "point_line",
    "write_export",
]

DEFAULT_TEACH_SPEED: Final = 2000.0
"""Joint speed of an exported program (deg/min)."""
_LETTERS: Final = "XYZABC"


@dataclass(frozen=True, slots=True)
class TaughtPoint:
    """Joints J1..J6 (deg), rail (mm, None without one) and the pose there (for display)."""

    joints: Joints
    rail: float | None
    pose: Pose

    def describe(self) -> str:
        j = " ".join(f"{v:.2f}" for v in self.joints)
        x, y, z = self.pose[:3]
        rail = "" if self.rail is None else f" D{self.rail:.1f}"
        return f"J {j}{rail} | xyz {x:.1f} {y:.1f} {z:.1f}"


def point_line(point: TaughtPoint, *, firmware: str = "2021") -> str:
    """The axis words of one point (3 decimals, checked against the joint ranges)."""
    words = [
        f"{letter}{gcode.fmt_number(v, 3, name=letter)}"
        for letter, v in zip(_LETTERS, point.joints, strict=True)
    ]
    if point.rail is not None:
        words.append(f"D{gcode.fmt_number(point.rail, 3, name='rail')}")
    line = " ".join(words)
    # the same range check the client applies to move_joints
    gcode.move_joints(*point.joints, point.rail, firmware=firmware)
    return line


def modes_line(speed: float) -> str:
    """The first line: joint mode, absolute, millimetres, feed moves at ``speed`` deg/min."""
    if not speed > 0:
        raise MirobotUsageError(f"speed={speed!r} must be > 0 deg/min")
    return f"M21 G90 G21 G1 F{gcode.fmt_number(speed, 1, name='speed')}"


def export_program(
    points: Sequence[TaughtPoint],
    *,
    speed: float = DEFAULT_TEACH_SPEED,
    firmware: str = "2021",
    title: str = "taught with mirobot view",
) -> list[str]:
    """The program that drives the arm through ``points`` in order (lines, no line endings)."""
    if not points:
        raise MirobotUsageError("no points to export: record some first")
    lines = [f"({title}: {len(points)} points, firmware {firmware})", modes_line(speed)]
    lines += [point_line(p, firmware=firmware) for p in points]
    return lines


def export_name(text: str) -> str:
    """The export's file name as the page gives it: a plain name, never a folder (the export
    folder is fixed when the command starts)."""
    name = text.strip()
    if not name or name in (".", "..") or any(c in name for c in "/\\\0") or name[0] == "~":
        raise MirobotUsageError(
            f"export to {text!r}: give a file name only (it is written in the export folder)"
        )
    return name


class TeachTable:
    """The ordered points of the pendant: add, replace (edit), move, delete."""

    def __init__(self) -> None:
        self.points: list[TaughtPoint] = []

    def _index(self, number: int) -> int:
        if not 1 <= number <= len(self.points):
            raise MirobotUsageError(
                f"there is no point {number} (the table has {len(self.points)})"
            )
        return number - 1

    def add(self, point: TaughtPoint) -> int:
        """Append; returns the point's number (1-based)."""
        self.points.append(point)
        return len(self.points)

    def get(self, number: int) -> TaughtPoint:
        return self.points[self._index(number)]

    def replace(self, number: int, point: TaughtPoint) -> None:
        self.points[self._index(number)] = point

    def delete(self, number: int) -> None:
        del self.points[self._index(number)]

    def move(self, number: int, offset: int) -> int:
        """Move point ``number`` up (-1) or down (+1); returns its new number."""
        i = self._index(number)
        j = min(max(i + offset, 0), len(self.points) - 1)
        self.points.insert(j, self.points.pop(i))
        return j + 1

    def markdown(self, selected: int | None = None) -> str:
        """The table as Markdown (the page shows it)."""
        if not self.points:
            return "*No points yet: jog the arm, then **Record point**.*"
        rows = ["| # | J1..J6 (deg) | rail | x y z (mm) |", "|---|---|---|---|"]
        for n, p in enumerate(self.points, start=1):
            mark = f"**{n}**" if n == selected else str(n)
            joints = " ".join(f"{v:.1f}" for v in p.joints)
            rail = "" if p.rail is None else f"{p.rail:.1f}"
            xyz = " ".join(f"{v:.1f}" for v in p.pose[:3])
            rows.append(f"| {mark} | {joints} | {rail} | {xyz} |")
        return "\n".join(rows)


def write_export(path: Path, text: str, *, overwrite: bool) -> None:
    """Write ``text`` to ``path``: a new file only (``FileExistsError``), unless ``overwrite``;
    never through a symbolic link. Another failure is a :class:`MirobotUsageError` naming it."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_NOFOLLOW | (os.O_TRUNC if overwrite else os.O_EXCL)
    try:
        fd = os.open(path, flags, 0o644)
    except OSError as err:
        if isinstance(err, FileExistsError) or path.is_symlink():
            raise FileExistsError(str(path)) from None
        raise MirobotUsageError(f"cannot write {path}: {err.strerror}") from None
    with os.fdopen(fd, "w", encoding="ascii") as file:
        file.write(text)
