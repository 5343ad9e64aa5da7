"""Motion commands of :class:`~mirobot_async._client.client.Mirobot` (a mixin): ``move_joints``,
``move_pose``, ``home``, ``unlock``, ``clear_alarm``.

A structured move states ``M21``/``M20`` only when the coordinate mode changes (or is unknown):
the firmware restarts a line that carries one from where the arm is when it reads the line, not
from where the queued motion ends (:class:`~mirobot_async._core.modal.Chaining`, oracle), so moves
sent with ``wait=False`` chain as they do one at a time. When the mode word is needed and the
joints the line reads may still be moving, ``G4 P0`` goes first (the firmware answers it once
the arm has stopped). ``G90``/``G91``, ``G0``/``G1`` and ``G21`` are always stated (they do not
restart anything)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Final

from mirobot_async._client.completion import RELATIVE_JOINT_TOLERANCE, Target
from mirobot_async._client.deadline import deadline_after
from mirobot_async._client.guard import EnvelopeGuard, NullGuard
from mirobot_async._client.parts import DEFAULT_TIMEOUT, HOME_TIMEOUT, MOVE_TIMEOUT, ClientParts
from mirobot_async._client.scheduler import SendRules, Slot, StreamStopped
from mirobot_async._core import gcode
from mirobot_async._core.acceptance import update_modes
from mirobot_async._core.line import ParsedLine, parse_line
from mirobot_async._core.modal import Chaining, MotionModes
from mirobot_async._core.outgoing import OutgoingLine
from mirobot_async._core.replies import StatusReport
from mirobot_async.errors import MirobotUsageError

if TYPE_CHECKING:
    from mirobot_async._safety.envelope import LineCheck

__all__ = ["ARM_STOPPED", "MotionCommands", "absolute_pose", "write_move"]

ARM_STOPPED: Final = b"G4 P0"
_STOPPED: Final = ARM_STOPPED.decode("ascii")
_MOTION: Final = SendRules(motion=True)
"""Written before a move whose mode word would restart it from where the moving arm is: the
firmware answers a dwell only once its planner is empty, and reads the next line after it."""
_ATTEMPTS: Final = 3


class MotionCommands(ClientParts):
    """Structured moves, homing and unlocking."""

    async def _move(
        self,
        build: Callable[[bool], bytes],
        *,
        cartesian: bool,
        target: Callable[[StatusReport | None, LineCheck | None], Target | None],
        relative: bool,
        wait: bool,
        deadline: float | None,
        timeout: float | None,
        what: str,
    ) -> StatusReport | None:
        """Send a motion line; with ``wait`` await its completion at ``target``.

        ``build(mode_word)`` gives the line with or without its ``M20``/``M21`` (stated only
        when the mode changes, see the module docstring). ``target(baseline, check)`` gives the
        goal; for relative moves from ``check`` (the envelope's verdict: the absolute target)
        or else ``baseline`` (a status read before sending while the arm was at rest), or
        ``None`` (completion = Idle after the ``ok``).
        """
        condition = self._condition
        command = build(True).rstrip(b"\n").decode("ascii").strip()
        condition.check_sendable(command, motion=True)
        use_baseline = wait and relative and self._guard.envelope is None
        baseline = await self._lines.baseline(deadline) if use_baseline else None
        epoch, alarm_epoch = condition.reset_epoch, condition.alarm_epoch
        slot = await write_move(self, build, cartesian, deadline, timeout, what)
        await self._lines.await_slot(slot, deadline, timeout)
        if not wait:
            return None
        command = slot.command
        epoch = slot.reply_epoch  # (a line in doubt after a reset ran after it)
        known = not relative or baseline is not None or slot.check is not None
        goal = target(baseline, slot.check) if known else None
        report = await self._completion.wait(
            command,
            goal,
            deadline=deadline,
            timeout=timeout,
            epoch=epoch,
            alarm_epoch=alarm_epoch,
        )
        self._guard.move_completed(slot.pending.id)
        return report

    async def move_joints(
        self,
        j1: float | None = None,
        j2: float | None = None,
        j3: float | None = None,
        j4: float | None = None,
        j5: float | None = None,
        j6: float | None = None,
        rail: float | None = None,
        *,
        speed: float | None = None,
        relative: bool = False,
        wait: bool = True,
        timeout: float | None = MOVE_TIMEOUT,
    ) -> StatusReport | None:
        """Joint move (degrees; ``rail`` in mm); omitted joints stay where they are.

        ``speed`` in deg/min (``None``: every joint at its max rate, ``G0``). ``relative`` adds
        to the current angles. The line states its units (``G21``, millimetres and degrees), so
        an earlier ``G20`` (inches) cannot change its meaning. Absolute targets outside the
        joint (and rail) ranges raise :class:`MirobotUsageError` before anything is sent, and so
        does a move that leaves the safety envelope (target, or the tool point along the
        joint-space path from the predicted position; see the module docstring).

        With ``wait`` (default) returns the status report that shows the move finished: ``ok``
        received and a later status ``Idle`` at the target (within 0.05 deg, half a motor
        step), or ``Idle`` after the arm was seen moving; for relative moves the target is the
        envelope's predicted one, or without an envelope computed from a status read just
        before sending when the arm is at rest (else completion is ``Idle`` after the ``ok``).
        Without ``wait`` returns ``None`` once the line is queued (``ok``); such moves chain
        as waited ones do: the line carries ``M21`` only when the mode changes, and when it
        must while joints it reads may still be moving, ``G4 P0`` goes first, so the ``ok``
        comes once the earlier motion has ended (the firmware restarts an ``M21`` line from
        where the arm is).

        Raises :class:`MotionRefusedError` (locked, soft limit...), :class:`MirobotAlarmError`
        (an alarm is remembered or raised meanwhile), :class:`MirobotResetError`,
        :class:`MirobotTimeoutError` after ``timeout`` seconds (default :data:`MOVE_TIMEOUT`).
        Cancelling keeps the link in step (as :meth:`send`) but does not stop the arm (use
        :meth:`hold`, :meth:`reset` or :meth:`hold_on_exit`).
        """
        values = (j1, j2, j3, j4, j5, j6)
        if timeout == MOVE_TIMEOUT:  # the default: long enough for this move at its speed
            timeout = motion_timeout(
                self._poller.last_status, values, rail, speed, relative, joints=True
            )
        deadline = deadline_after(self._running_loop(), timeout)
        # Argument errors first (the rail range depends on the firmware: checked below).
        if rail is None or any(v is not None for v in values):
            gcode.move_joints(j1, j2, j3, j4, j5, j6, speed=speed, relative=relative)
        if rail is not None:
            gcode.move_joints(rail=rail, speed=speed, relative=True)  # a finite number
        firmware: str = self._condition.firmware or "2021"
        if rail is not None and self._condition.firmware is None and not relative:
            firmware = await self._require_firmware(deadline, timeout)

        def build(mode_word: bool) -> bytes:
            line = gcode.move_joints(
                j1,
                j2,
                j3,
                j4,
                j5,
                j6,
                rail,
                speed=speed,
                relative=relative,
                firmware=firmware,
                mode_word=mode_word,
            )
            return _with_units(line)

        build(True)  # argument errors before anything is sent

        def target(base: StatusReport | None, check: LineCheck | None) -> Target:
            if not relative:
                return Target(joints=values, rail=rail)
            if check is not None and check.joints is not None:
                joints = tuple(
                    None if v is None else q for v, q in zip(values, check.joints, strict=True)
                )
                return Target(joints=joints, rail=None if rail is None else check.rail)
            assert base is not None
            joints = tuple(
                None if v is None else b + v for v, b in zip(values, base.joints, strict=True)
            )
            new_rail = None if rail is None or base.rail is None else base.rail + rail
            return Target(joints=joints, rail=new_rail, joint_tolerance=RELATIVE_JOINT_TOLERANCE)

        return await self._move(
            build,
            cartesian=False,
            target=target,
            relative=relative,
            wait=wait,
            deadline=deadline,
            timeout=timeout,
            what="move_joints",
        )

    async def move_pose(
        self,
        x: float | None = None,
        y: float | None = None,
        z: float | None = None,
        rx: float | None = None,
        ry: float | None = None,
        rz: float | None = None,
        *,
        speed: float | None = None,
        linear: bool = False,
        relative: bool = False,
        wait: bool = True,
        timeout: float | None = MOVE_TIMEOUT,
    ) -> StatusReport | None:
        """Cartesian move of the tool point (mm) and orientation (roll, pitch, yaw in degrees).

        ``linear=False``: point to point (``G0``); ``linear=True``: straight line (``G1``) at
        ``speed`` mm/min, which is then required. ``relative`` adds to the current pose
        (orientation component-wise, as the firmware does). Omitted coordinates stay. The line
        states ``G21`` (millimetres). With a safety envelope the target (``G0``: and the
        joint-space path to it) or the sampled straight line is checked first:
        :class:`MirobotUsageError`, nothing sent.

        ``wait`` as in :meth:`move_joints` (the pose must read back within 0.1 mm / 0.1 deg).
        Unreachable targets raise :class:`MotionRefusedError` (``reason`` UNREACHABLE or
        ANGLE_OUT_OF_LIMIT); other errors and ``timeout`` (default :data:`MOVE_TIMEOUT`) as in
        :meth:`move_joints`.
        """
        values = (x, y, z, rx, ry, rz)
        if timeout == MOVE_TIMEOUT:  # the default: long enough for this move at its speed
            timeout = motion_timeout(
                self._poller.last_status, values, None, speed, relative, joints=False
            )
        deadline = deadline_after(self._running_loop(), timeout)

        def build(mode_word: bool) -> bytes:
            line = gcode.move_pose(
                x,
                y,
                z,
                rx,
                ry,
                rz,
                speed=speed,
                linear=linear,
                relative=relative,
                mode_word=mode_word,
            )
            return _with_units(line)

        build(True)  # argument errors before anything is sent

        def target(base: StatusReport | None, check: LineCheck | None) -> Target:
            if not relative:
                return Target(pose=absolute_pose(values, check, self._guard))
            if check is not None and check.pose is not None:
                pose = tuple(
                    None if v is None else p for v, p in zip(values, check.pose, strict=True)
                )
                return Target(pose=pose)
            assert base is not None
            pose = tuple(
                None if v is None else b + v for v, b in zip(values, base.pose, strict=True)
            )
            return Target(pose=pose)

        return await self._move(
            build,
            cartesian=True,
            target=target,
            relative=relative,
            wait=wait,
            deadline=deadline,
            timeout=timeout,
            what="move_pose",
        )

    async def home(
        self, sequential: bool = False, *, timeout: float | None = HOME_TIMEOUT
    ) -> StatusReport:
        """Home the arm (``$H``; ``sequential=True``: ``$HH``, one axis after another).

        Returns when a status after the ``ok`` shows ``Idle`` with all joints at zero. Homing
        unlocks the axes and clears a remembered alarm. Raises :class:`MirobotTimeoutError`
        after ``timeout`` seconds (default :data:`HOME_TIMEOUT`), :class:`MirobotAlarmError` if
        homing fails, :class:`MirobotResetError` on a reset. Cancelling does not stop homing.
        """
        data = gcode.home(sequential)
        deadline = deadline_after(self._running_loop(), timeout)
        condition = self._condition
        condition.check_sendable("$HH" if sequential else "$H", motion=False)
        epoch, alarm_epoch = condition.reset_epoch, condition.alarm_epoch
        await self._command(data, deadline=deadline, timeout=timeout)
        return await self._completion.wait(
            data.decode("ascii").strip(),
            None,
            deadline=deadline,
            timeout=timeout,
            epoch=epoch,
            alarm_epoch=alarm_epoch,
            homing=True,
        )

    async def unlock(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """Release the axis lock without homing: ``$X`` (leave Alarm), then ``M50`` (unlock).

        Clears a remembered alarm (not a hard limit: that needs :meth:`reset`). Errors and
        cancellation as in :meth:`send`; ``timeout`` (default :data:`DEFAULT_TIMEOUT`) covers both
        lines.
        """
        deadline = deadline_after(self._running_loop(), timeout)
        self._condition.check_sendable("$X", motion=False)
        await self._command(gcode.clear_alarm(), deadline=deadline, timeout=timeout)
        await self._command(gcode.unlock_axes(), deadline=deadline, timeout=timeout)

    async def clear_alarm(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """``$X``: leave Alarm (the power-on axis lock stays: see :meth:`unlock`).

        Clears a remembered alarm (not a hard limit). Errors, ``timeout`` (default
        :data:`DEFAULT_TIMEOUT`) and cancellation as in :meth:`send`.
        """
        await self._command_within(gcode.clear_alarm(), timeout)


async def write_move(
    parts: ClientParts,
    build: Callable[[bool], bytes],
    cartesian: bool,
    deadline: float | None,
    timeout: float | None,
    what: str,
    follow: Sequence[ParsedLine] = (),
) -> Slot:
    """Write a move's line: its mode word only if the mode differs, ``G4 P0`` first if the
    line (or the lines ``follow`` that come right after it, e.g. a path's points) would
    otherwise restart from where the moving arm is. Rebuilt if another line changes the mode
    before it is written (checked right before the write). Returns its slot (not awaited)."""
    guard = parts._guard
    for _attempt in range(_ATTEMPTS):
        mode_word = _needs_mode_word(parts, build, cartesian, follow)
        data = build(mode_word).rstrip(b"\n")
        command = data.decode("ascii")
        line = OutgoingLine.of(data, f"{what} {command!r}")
        parsed = line.parsed
        firmware = parts._condition.firmware
        barrier: Slot | None = None
        if _restarts(guard.chain, guard.modes, [parsed, *follow], firmware):
            stopped = OutgoingLine.of(
                ARM_STOPPED, f"{_STOPPED!r} (the arm stops before {command!r})"
            )
            barrier = await parts._lines.submit(stopped, deadline=deadline, timeout=timeout)

        def changed(mode_word: bool = mode_word, parsed: ParsedLine = parsed) -> bool:
            stated = _needs_mode_word(parts, build, cartesian, follow)
            lines = [parsed, *follow]
            return stated != mode_word or _restarts(
                guard.chain, guard.modes, lines, parts._condition.firmware
            )

        try:
            return await parts._lines.submit(
                line, deadline=deadline, timeout=timeout, rules=_MOTION, should_stop=changed
            )
        except StreamStopped:
            continue  # another line changed the mode meanwhile: build it again
        finally:
            if barrier is not None and not barrier.fut.done():
                barrier.fut.cancel()  # its reply is consumed and discarded
    raise MirobotUsageError(
        f"{what}: other lines sent at the same time kept changing the coordinate mode "
        "(M20/M21); nothing was sent"
    )


def _needs_mode_word(
    parts: ClientParts,
    build: Callable[[bool], bytes],
    cartesian: bool,
    follow: Sequence[ParsedLine],
) -> bool:
    """State ``M20``/``M21``: the mode differs or is unknown, or the line (or ``follow``)
    without it would read a joint the parser has elsewhere (after a refused line, or an
    earlier mode word parsed while the arm moved)."""
    guard = parts._guard
    if guard.modes.cartesian is not cartesian or guard.parser_apart:
        return True
    chain, modes, firmware = guard.chain, guard.modes, parts._condition.firmware
    for parsed in [parse_line(build(False).rstrip(b"\n")), *follow]:
        if chain.needs_restart(parsed, modes, firmware):
            return True
        chain = chain.after(parsed, modes, firmware)
        modes = update_modes(parsed, modes, firmware)
    return False


def _restarts(
    chain: Chaining, modes: MotionModes, lines: Sequence[ParsedLine], firmware: str | None
) -> bool:
    """Some of ``lines``, written one after another from ``chain``, would restart from where
    the moving arm is (:meth:`Chaining.problem`)."""
    for parsed in lines:
        if chain.problem(parsed, modes, firmware) is not None:
            return True
        chain = chain.after(parsed, modes, firmware)
        modes = update_modes(parsed, modes, firmware)
    return False


def absolute_pose(
    values: tuple[float | None, ...], check: LineCheck | None, guard: EnvelopeGuard | NullGuard
) -> tuple[float | None, ...]:
    """Where an absolute ``M20`` move reads back: the firmware adds the 2021 base offset
    ``$41..$43`` to X/Y/Z. Known from the envelope's verdict on the line, else from the guard
    (the one store: a ``$$`` listing, zero on a classic arm); otherwise X/Y/Z are not checked
    (completion: ``Idle`` after the arm moved)."""
    offset = check.base_offset if check is not None else None
    if offset is None:
        offset = guard.base_offset
    if offset is None:
        return (None, None, None, *values[3:])
    xyz = tuple(None if v is None else v + o for v, o in zip(values[:3], offset, strict=True))
    return (*xyz, *values[3:])


def _with_units(data: bytes) -> bytes:
    """A structured move stating ``G21`` (millimetres): ``G20`` left by an earlier session
    would make the firmware read its numbers as inches."""
    line = data.rstrip(b"\n")
    return line if b"G21" in line.split() else line + b" G21"


_FAR: Final = (270.0, 1000.0)  # degrees of the widest joint range; mm across the workspace


def motion_timeout(
    last: StatusReport | None,
    values: Sequence[float | None],
    rail: float | None,
    speed: float | None,
    relative: bool,
    *,
    joints: bool,
) -> float:
    """The default ``timeout`` of a move: :data:`MOVE_TIMEOUT`, or twice the time the farthest
    axis needs at ``speed`` (deg/min or mm/min) plus 10 s when that is longer, so that a slow
    move is never given up while the arm is still on its way (J1 over 260 deg at F100: 156 s).
    The start is the last status when one was seen, else the farthest an axis can be."""
    if speed is None or speed <= 0:
        return MOVE_TIMEOUT  # G0: every axis at its maximum rate
    current = (last.joints if joints else last.pose) if last is not None else None
    travel = 0.0
    for index, value in enumerate(values):
        if value is None:
            continue
        if relative:
            travel = max(travel, abs(value))
        elif current is not None:
            travel = max(travel, abs(value - current[index]))
        else:
            travel = max(travel, _FAR[0] if joints else _FAR[1])
    if rail is not None:
        start = last.rail if last is not None and last.rail is not None else None
        travel = max(travel, abs(rail) if relative or start is None else abs(rail - start))
    if not joints and not relative and current is not None:
        travel = max(
            travel,
            sum((v - c) ** 2 for v, c in zip(values[:3], current[:3], strict=True) if v is not None)
            ** 0.5,
        )
    return max(MOVE_TIMEOUT, 2.0 * travel / speed * 60.0 + 10.0)


def path_timeout(
    last: StatusReport | None,
    points: Sequence[Sequence[float | None]],
    speed: float | None,
    *,
    joints: bool,
) -> float:
    """The default ``timeout`` of a path: :data:`MOVE_TIMEOUT`, or twice its length over its
    feed plus 10 s when that is longer (each leg counted as its farthest axis for joint paths,
    its straight length in x, y, z for poses; from the last status, else from far away)."""
    if speed is None or speed <= 0 or not points:
        return MOVE_TIMEOUT
    current = (last.joints if joints else last.pose) if last is not None else None
    total = 0.0 if current is not None else (_FAR[0] if joints else _FAR[1])
    previous: Sequence[float | None] | None = current
    for point in points:
        if previous is not None:
            pairs = [(a, b) for a, b in zip(point, previous, strict=False) if a is not None]
            if joints:
                total += max((abs(a - (b or 0.0)) for a, b in pairs), default=0.0)
            else:
                total += sum((a - (b or 0.0)) ** 2 for a, b in pairs[:3]) ** 0.5
        previous = [
            p if p is not None else (q or 0.0)
            for p, q in zip(point, previous or point, strict=False)
        ]
    return max(MOVE_TIMEOUT, 2.0 * total / speed * 60.0 + 10.0)
