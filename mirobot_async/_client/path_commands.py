"""Paths of :class:`~mirobot_async._client.client.Mirobot` (a mixin): ``move_path``,
``move_joint_path``.

A path is one modal line (``M20``/``M21 G90 G0|G1 G21 F..``,
:func:`~mirobot_async._core.gcode.path_header`) and then one bare ``G1 X.. Y..`` line per point
(:func:`~mirobot_async._core.gcode.path_point`), streamed with character counting so that the
firmware's planner blends them; the call returns when a status shows the arm at rest at the
last point. The header states ``M20``/``M21`` only when the mode changes, and ``G4 P0`` goes
before it when the points would otherwise restart from where the moving arm is
(:func:`~mirobot_async._client.motion_commands.write_move`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

from mirobot_async._client.completion import Target
from mirobot_async._client.deadline import deadline_after
from mirobot_async._client.guard import NeedPosition, PathRefused
from mirobot_async._client.motion_commands import absolute_pose, path_timeout, write_move
from mirobot_async._client.parts import MOVE_TIMEOUT, ClientParts
from mirobot_async._client.streaming import Stream
from mirobot_async._core import gcode
from mirobot_async._core.line import parse_line
from mirobot_async._core.replies import StatusReport
from mirobot_async.errors import (
    MirobotError,
    MirobotUsageError,
    PathError,  # defined with the error tree
)

if TYPE_CHECKING:
    from mirobot_async._safety.envelope import LineCheck

__all__ = ["PathCommands", "PathError"]

Point = Sequence[float | None]


class PathCommands(ClientParts):
    """Blended paths through many points."""

    async def move_path(
        self,
        poses: Iterable[Point],
        *,
        speed: float | None = None,
        linear: bool = True,
        timeout: float | None = MOVE_TIMEOUT,
    ) -> StatusReport:
        """Move the tool through ``poses`` (each ``(x, y, z[, rx, ry, rz])`` in mm and degrees,
        ``None`` entries stay), blending the moves: straight lines (``G1``) at ``speed`` mm/min
        with ``linear`` (then required), else point to point (``G0``).

        Every point is checked before the first byte is written (numbers, line length and, with
        a safety envelope, the whole path predicted from where the arm will be): a bad point
        raises :class:`MirobotUsageError` naming its index and nothing is written. The lines are
        then streamed with character counting (the planner never starves); the modes are stated
        once, in the first line (``M20``/``M21`` only if it changes: the firmware restarts a
        line carrying it from where the arm is; ``G4 P0`` first if the points would then read
        a joint still moving). Returns the status that shows the arm at rest at the last point.

        A line the robot refuses or rejects stops the path: :class:`PathError` names the point
        (lines already in the robot's buffer still run). ``timeout`` (default
        :data:`MOVE_TIMEOUT`) bounds the whole call (:class:`MirobotTimeoutError`). Cancelling
        stops sending at once; the lines already written still run: the arm keeps moving to
        the last point written (use :meth:`hold` or :meth:`hold_on_exit` to stop it).
        """
        points = [tuple(point) for point in poses]

        def header(mode_word: bool) -> bytes:
            return gcode.path_header(joints=False, speed=speed, linear=linear, mode_word=mode_word)

        return await self._path(points, header, joints=False, timeout=timeout)

    async def move_joint_path(
        self,
        points: Iterable[Point],
        *,
        speed: float | None = None,
        timeout: float | None = MOVE_TIMEOUT,
    ) -> StatusReport:
        """Move through joint-space ``points`` (each ``(j1, ..., j6[, rail])`` in degrees and mm,
        ``None`` entries stay), blending the moves: ``G1`` at ``speed`` deg/min, or ``G0`` (every
        joint at its max rate) without it.

        Checks (joint and rail ranges, the envelope), streaming, the result, errors, ``timeout``
        and cancellation as in :meth:`move_path`.
        """
        listed = [tuple(point) for point in points]

        def header(mode_word: bool) -> bytes:
            return gcode.path_header(joints=True, speed=speed, mode_word=mode_word)

        return await self._path(listed, header, joints=True, timeout=timeout)

    async def _path(
        self,
        points: list[tuple[float | None, ...]],
        build_header: Callable[[bool], bytes],
        *,
        joints: bool,
        timeout: float | None,
    ) -> StatusReport:
        header = build_header(True)
        if timeout == MOVE_TIMEOUT and points:  # the default: long enough for this path
            speed = parse_line(header.rstrip(b"\n")).value("F")
            timeout = path_timeout(self._poller.last_status, points, speed, joints=joints)
        deadline = deadline_after(self._running_loop(), timeout)
        if not points:
            raise MirobotUsageError("a path needs at least one point")
        motion = header.split()[2].decode("ascii")
        firmware = self._condition.firmware or "2021"
        lines = [header.rstrip(b"\n")]
        for index, point in enumerate(points):
            try:
                lines.append(
                    gcode.path_point(point, joints=joints, motion=motion, firmware=firmware).rstrip(
                        b"\n"
                    )
                )
            except MirobotUsageError as err:
                raise MirobotUsageError(f"path point {index} {point}: {err}") from None
        checks = await self._preview(lines, points, deadline, timeout)
        condition = self._condition
        condition.check_sendable(lines[0].decode("ascii"), motion=True)
        epoch, alarm_epoch = condition.reset_epoch, condition.alarm_epoch
        follow = [parse_line(line) for line in lines[1:]]
        what = f"path of {len(points)} points"
        slot = await write_move(self, build_header, not joints, deadline, timeout, what, follow)
        try:
            await self._lines.await_slot(slot, deadline, timeout)
        except MirobotError as err:
            raise PathError(0, points[0], err) from err
        stream = Stream(
            (self._lines, self._condition, self._guard), lines[1:], None, False, timeout, True, True
        )
        result = await stream.run()
        for line_result in result.errors:
            index = line_result.number - 1
            assert line_result.error is not None
            raise PathError(index, points[index], line_result.error) from line_result.error
        last = points[-1]
        if joints:
            rail = last[6] if len(last) > 6 else None
            target = Target(joints=(*last[:6], *(None,) * (6 - len(last[:6]))), rail=rail)
        else:
            padded = (*last, *(None,) * (6 - len(last)))
            target = Target(pose=absolute_pose(padded, checks[-1] if checks else None, self._guard))
        return await self._completion.wait(
            f"path of {len(points)} points",
            target,
            deadline=deadline,
            timeout=timeout,
            epoch=epoch,
            alarm_epoch=alarm_epoch,
        )

    async def _preview(
        self,
        lines: list[bytes],
        points: list[tuple[float | None, ...]],
        deadline: float | None,
        timeout: float | None,
    ) -> list[LineCheck]:
        """The envelope's verdicts on the whole path, predicted before anything is written."""
        guard = self._guard
        if guard.envelope is None:
            return []
        parsed = [parse_line(line) for line in lines]
        if any(guard.needs_firmware(line) for line in parsed):
            await self._require_firmware(deadline, timeout)
        while True:
            try:
                found = guard.preview(parsed)
            except PathRefused as err:
                if err.index == 0:
                    raise MirobotUsageError(f"path header {lines[0]!r}: {err}") from None
                index = err.index - 1
                raise MirobotUsageError(f"path point {index} {points[index]}: {err}") from None
            if not isinstance(found, NeedPosition):
                return found
            await self._lines.learn_position("a path", deadline)

    async def preview_lines(
        self, lines: Sequence[str | bytes], *, timeout: float | None = MOVE_TIMEOUT
    ) -> list[LineCheck]:
        """The safety envelope's verdicts on ``lines`` as if they were streamed now, one after
        another from where the arm is; nothing is written. A line the envelope refuses raises
        :class:`PathRefused` (a MirobotUsageError) with its 0-based :attr:`~PathRefused.index`;
        without an envelope the answer is ``[]``. May read the firmware profile (``$$``) and the
        position (``?``) first, within ``timeout`` seconds; cancelling leaves nothing behind."""
        guard = self._guard
        if guard.envelope is None:
            return []
        deadline = deadline_after(self._running_loop(), timeout)
        parsed = [parse_line(line) for line in lines]
        # A line may need the base offset only because an earlier line of the program switched
        # to M20 G90: ask as if each line with X, Y or Z were an absolute Cartesian one.
        absolute = parse_line(b"M20 G90 G0 X0")
        positions = any(any(k in line.axis_words for k in "XYZ") for line in parsed)
        if any(guard.needs_firmware(line) for line in parsed) or (
            positions and guard.needs_firmware(absolute)
        ):
            await self._require_firmware(deadline, timeout)
        while True:
            found = guard.preview(parsed)
            if not isinstance(found, NeedPosition):
                return found
            await self._lines.learn_position("a program", deadline)
