"""What the MCP tools do to the arm, independent of the MCP SDK: each call returns the exact
outcome as plain data (the final status, the firmware's words) or raises a
:class:`~mirobot_async.errors.MirobotError` whose message says why (for a refusal: also what
the envelope allows, and that nothing was sent).

Rules kept here: the arm's connection carries the safety envelope, so every motion is checked
before a byte of it is written; one command at a time (a second one while a motion tool runs is
refused at once, not queued); :meth:`ArmService.hold`, :meth:`~ArmService.resume`,
:meth:`~ArmService.reset` and :meth:`~ArmService.status` never wait for the running command, so
they act while it runs. With a *twin* (``--dry-run``: a virtual Mirobot, the embedded
emulator), every motion tool runs first on the twin, brought to the arm's state, and only then
on the arm; a failure on the twin is a refusal with nothing sent to the arm. A motion is refused
while the arm is locked (Alarm) or held with moves queued (Hold); a motion call that the client
cancels leaves the arm in feed hold rather than running on unwatched.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from typing import TYPE_CHECKING, Any, Final, TypeAlias

from mirobot_async._cli.envelope_file import describe_envelope
from mirobot_async._cli.programs import strip_comments
from mirobot_async._client.guard import PathRefused
from mirobot_async._core import gcode, validation
from mirobot_async._core.replies import State, StatusReport
from mirobot_async._safety.envelope import Envelope
from mirobot_async.errors import MirobotError, MirobotUsageError
from mirobot_async.kinematics import DH_2021, DH_CLASSIC

if TYPE_CHECKING:
    from mirobot_async._client.client import Mirobot

__all__ = [
    "DEFAULT_BOX",
    "ArmService",
    "default_envelope",
    "envelope_dict",
    "program_lines",
    "status_dict",
]

DEFAULT_BOX: Final[dict[str, tuple[float, float]]] = {
    "x": (50.0, 300.0),
    "y": (-250.0, 250.0),
    "z": (20.0, 300.0),
}
"""The envelope without ``--envelope``: the tool point in front of the base (never behind or
over it), at most 250 mm to either side and between 20 mm above the table and 300 mm."""
JOINT_NAMES: Final = ("j1", "j2", "j3", "j4", "j5", "j6")
POSE_NAMES: Final = ("x", "y", "z", "rx", "ry", "rz")
_SAME_ANGLE: Final = 0.05
"""Degrees (half a motor step): the twin stands where the arm does."""
Six: TypeAlias = tuple[
    float | None, float | None, float | None, float | None, float | None, float | None
]
"""Six optional numbers: j1..j6 or x, y, z, rx, ry, rz (None: stays)."""


def default_envelope(firmware: str) -> Envelope:
    """The conservative default envelope (:data:`DEFAULT_BOX`) on the profile's model."""
    model = DH_CLASSIC if firmware == "classic" else DH_2021
    return Envelope(x=DEFAULT_BOX["x"], y=DEFAULT_BOX["y"], z=DEFAULT_BOX["z"], dh=model)


def status_dict(report: StatusReport) -> dict[str, Any]:
    """A status report as data: state, joints (deg), rail (mm), pose, outputs, the firmware's
    own line."""
    return {
        "state": report.state.value,
        "joints": dict(zip(JOINT_NAMES, report.joints, strict=True)),
        "rail": report.rail,
        "pose": dict(zip(POSE_NAMES, report.pose, strict=True)),
        "pump_pwm": report.pump_pwm,
        "valve_pwm": report.valve_pwm,
        "firmware_line": report.to_line(),
    }


def envelope_dict(envelope: Envelope) -> dict[str, Any]:
    """The envelope as data: box sides (``None``: open), joint ranges, rail, tool, a summary."""

    def pair(bound: tuple[float | None, float | None] | None) -> list[float | None] | None:
        return None if bound is None else [bound[0], bound[1]]

    return {
        "box_mm": {axis: pair(getattr(envelope, axis)) for axis in ("x", "y", "z")},
        "joints_deg": {
            name: [lo, hi]
            for name, (lo, hi) in zip(JOINT_NAMES, envelope.joint_limits, strict=True)
        },
        "rail_mm": pair(envelope.rail),
        "tool_mm": list(envelope.tool),
        "summary": describe_envelope(envelope),
    }


def program_lines(program: str) -> list[tuple[int, str]]:
    """The commands of a G-code text: (1-based line number, text without comments)."""
    commands = []
    for number, raw in enumerate(program.splitlines(), start=1):
        text = strip_comments(raw)
        if text:
            commands.append((number, text))
    return commands


class ArmService:
    """The arm behind the MCP tools (see the module docstring)."""

    def __init__(self, arm: Mirobot, twin: Mirobot | None = None) -> None:
        self.arm = arm
        self.twin = twin
        self._running: str | None = None
        self._twin_said: str | None = None

    # ---- one command at a time ----

    @property
    def running(self) -> str | None:
        """The tool running now (holding the arm), or None."""
        return self._running

    @contextlib.contextmanager
    def _exclusive(self, name: str) -> Iterator[None]:
        """The arm for ``name`` alone; a second command while one runs is refused at once."""
        if self._running is not None:
            raise MirobotUsageError(
                f"refused, nothing was sent: {self._running} is still running (one "
                "command at a time); wait for it, or stop it with hold or reset"
            )
        self._running = name
        self._twin_said = None
        try:
            yield
        finally:
            self._running = None

    @contextlib.asynccontextmanager
    async def _held_if_cancelled(self) -> AsyncIterator[None]:
        """A motion call cancelled by the client (its request cancelled, or the client gone)
        leaves the arm in feed hold: ``!`` is written at once, so that the arm decelerates to a
        stop instead of running on with nobody watching (resume or reset go on from there)."""
        try:
            yield
        except asyncio.CancelledError:
            async with self.arm.hold_on_exit():  # writes "!" without awaiting, then re-raises
                raise

    def _refusal(self, err: MirobotUsageError) -> MirobotUsageError:
        """A refusal that says why, that nothing was sent, and what the envelope allows."""
        envelope = self.arm.envelope
        text = str(err)
        if "nothing was sent" not in text:
            text += "; nothing was sent"
        if envelope is not None and "envelope" in text:
            text += f". The safety envelope allows: {describe_envelope(envelope)}"
        return MirobotUsageError(text)

    async def _final(self, outcome: str, **more: Any) -> dict[str, Any]:
        report = await self.arm.status()
        result = {"outcome": outcome, **more, "status": status_dict(report)}
        said, self._twin_said = self._twin_said, None
        if said is not None:
            result["dry_run"] = said
        return result

    # ---- reading ----

    async def status(self) -> dict[str, Any]:
        """A fresh status report (``?``); never waits for the running command."""
        result = status_dict(await self.arm.status())
        result["busy_with"] = self._running
        return result

    def envelope(self) -> dict[str, Any]:
        """The envelope every motion is checked against."""
        envelope = self.arm.envelope
        assert envelope is not None  # the server always connects with one
        return envelope_dict(envelope)

    async def settings(self) -> dict[str, float]:
        """The firmware's settings (``$$``), as ``{"$0": value, ...}``."""
        with self._exclusive("settings"):
            values = await self.arm.settings()
        return {f"${key}": value for key, value in sorted(values.items())}

    # ---- the twin (--dry-run) ----

    async def _preflight(self) -> None:
        """A motion is refused, with nothing sent, while the arm is locked (Alarm) or holds
        queued moves (Hold): it would fail, or be queued behind moves nobody is watching."""
        report = await self.arm.status()
        if report.state is State.ALARM:
            raise MirobotUsageError(
                "refused, nothing was sent: the arm is locked (Alarm, as after power-on or a "
                "reset): call home (or unlock) first"
            )
        if report.state is State.HOLD:
            raise MirobotUsageError(
                "refused, nothing was sent: the arm is in Hold with moves still queued: resume "
                "finishes them, reset drops them"
            )

    async def _twin_first(self, step: Callable[[Mirobot], Awaitable[object]]) -> None:
        """Run ``step(twin)`` on the twin brought to the arm's state; a failure there is a
        refusal: nothing is sent to the arm."""
        twin = self.twin
        if twin is None:
            return
        self._twin_said = None
        try:
            await self._sync_twin(twin)
            await step(twin)
            report = await twin.status()
            self._twin_said = f"ran first on the virtual twin: ok, it ended {report.to_line()}"
        except MirobotError as err:
            raise MirobotUsageError(
                f"refused by the dry run on the virtual twin, nothing was sent to the arm: {err}"
            ) from None

    async def _sync_twin(self, twin: Mirobot) -> None:
        """Put the twin where the arm is: locked if the arm is, else unlocked at its joints."""
        arm = await self.arm.status()
        seen = await twin.status()
        if arm.state is State.ALARM:
            if seen.state is not State.ALARM:
                await twin.reset()
            return
        if seen.state in (State.ALARM, State.HOLD):
            if seen.state is State.HOLD:
                await twin.reset()
            await twin.unlock()
        moved = any(abs(a - b) > _SAME_ANGLE for a, b in zip(arm.joints, seen.joints, strict=True))
        rail = None if arm.rail is None or seen.rail is None else arm.rail
        if moved or (rail is not None and seen.rail is not None and abs(rail - seen.rail) > 0.05):
            await twin.move_joints(*arm.joints, rail=rail)

    # ---- motion ----

    async def home(self, sequential: bool = False) -> dict[str, Any]:
        """Homing cycle (``$H``, or ``$HH`` one axis after another)."""
        with self._exclusive("home"):
            await self._twin_first(lambda twin: twin.home(sequential))
            await self.arm.home(sequential)
            line = "$HH" if sequential else "$H"
            return await self._final(f"homed ({line}: ok, Idle at all joints 0)")

    async def unlock(self) -> dict[str, Any]:
        """``$X`` then ``M50``: leave Alarm without homing."""
        with self._exclusive("unlock"):
            await self.arm.unlock()
            return await self._final("unlocked ($X: ok, M50: ok)")

    async def move_joints(
        self,
        joints: Six,
        rail: float | None,
        speed: float | None,
        relative: bool,
    ) -> dict[str, Any]:
        """A joint move, checked by the envelope before anything is sent."""
        with self._exclusive("move_joints"):
            await self._preflight()
            if self.twin is not None:  # the envelope first: the twin must not move either
                await self._preview(
                    gcode.move_joints(
                        *joints, rail, speed=speed, relative=relative, firmware=self._firmware()
                    ),
                )
            await self._twin_first(
                lambda twin: twin.move_joints(*joints, rail, speed=speed, relative=relative),
            )
            try:
                async with self._held_if_cancelled():
                    await self.arm.move_joints(*joints, rail, speed=speed, relative=relative)
            except MirobotUsageError as err:
                raise self._refusal(err) from None
            return await self._final("done (ok; the arm is at rest at the target)")

    async def move_pose(
        self,
        pose: Six,
        speed: float | None,
        linear: bool,
        relative: bool,
    ) -> dict[str, Any]:
        """A Cartesian move, checked by the envelope before anything is sent."""
        with self._exclusive("move_pose"):
            await self._preflight()
            if linear and speed is None:
                speed = 2000.0
            if self.twin is not None:
                await self._preview(
                    gcode.move_pose(*pose, speed=speed, linear=linear, relative=relative),
                )
            await self._twin_first(
                lambda twin: twin.move_pose(*pose, speed=speed, linear=linear, relative=relative),
            )
            try:
                async with self._held_if_cancelled():
                    await self.arm.move_pose(*pose, speed=speed, linear=linear, relative=relative)
            except MirobotUsageError as err:
                raise self._refusal(err) from None
            return await self._final("done (ok; the arm is at rest at the target)")

    async def _preview(self, line: bytes) -> None:
        """The envelope's verdict on a structured move (stating ``G21``, as the client sends
        it), before the twin runs it."""
        text = line.rstrip(b"\n")
        try:
            await self.arm.preview_lines([text if b"G21" in text.split() else text + b" G21"])
        except MirobotUsageError as err:
            raise self._refusal(err) from None

    def _firmware(self) -> str:
        return self.arm.firmware or "2021"

    # ---- accessories ----

    async def set_pump(self, pwm: int) -> dict[str, Any]:
        """``M3 S<pwm>``."""
        with self._exclusive("set_pump"):
            await self.arm.set_pump(pwm)
            return await self._final(f"M3 S{pwm}: ok")

    async def gripper(self, close: bool, legacy: bool) -> dict[str, Any]:
        """Open or close the gripper."""
        with self._exclusive("gripper"):
            line = gcode.set_gripper(close, legacy=legacy).decode("ascii").strip()
            if close:
                await self.arm.gripper_close(legacy=legacy)
            else:
                await self.arm.gripper_open(legacy=legacy)
            return await self._final(f"{line}: ok")

    # ---- programs ----

    async def check_program(self, program: str) -> dict[str, Any]:
        """What ``mirobot check`` finds, and the envelope's prediction from where the arm is
        (its verdict and the predicted end pose); nothing is sent but ``?`` (and ``$$``)."""
        commands = program_lines(program)
        firmware = self._firmware()
        problems = [
            {"line": number, "problem": problem}
            for number, problem in validation.check_program(program.splitlines(), firmware=firmware)
        ]
        result: dict[str, Any] = {
            "commands": len(commands),
            "firmware": firmware,
            "problems": problems,
        }
        if not commands:
            result["envelope"] = "no commands"
            return result
        try:
            checks = await self.arm.preview_lines([text for _, text in commands])
        except PathRefused as err:
            number, text = commands[err.index]
            result["envelope"] = f"refused at line {number} ({text}): {err}"
            result["envelope_allows"] = self.envelope()["summary"]
            return result
        result["envelope"] = "every line is inside the safety envelope"
        end = checks[-1] if checks else None
        if end is not None and end.pose is not None:
            result["predicted_end_pose"] = dict(zip(POSE_NAMES, end.pose, strict=True))
        if end is not None and end.joints is not None:
            result["predicted_end_joints"] = dict(zip(JOINT_NAMES, end.joints, strict=True))
        return result

    async def run_program(self, program: str, continue_on_error: bool = False) -> dict[str, Any]:
        """Stream a program, checked whole by the envelope first; the outcome of every line."""
        commands = program_lines(program)
        if not commands:
            raise MirobotUsageError("no commands in the program; nothing was sent")
        with self._exclusive("run_program"):
            await self._preflight()
            texts = [text for _, text in commands]
            # as `mirobot run` checks: the commands that will be sent, without their comments
            problems = validation.check_program(texts, firmware=self._firmware())
            if problems:
                listed = "; ".join(f"line {commands[n - 1][0]}: {p}" for n, p in problems[:5])
                raise MirobotUsageError(
                    f"refused, nothing was sent: {len(problems)} problem(s): {listed}"
                )
            try:
                await self.arm.preview_lines(texts)
            except PathRefused as err:
                number, text = commands[err.index]
                raise self._refusal(MirobotUsageError(f"line {number} ({text}): {err}")) from None

            async def on_twin(twin: Mirobot) -> None:
                result = await twin.stream(texts, continue_on_error=continue_on_error, wait=True)
                if result.errors:
                    failed = result.errors[0]
                    raise MirobotUsageError(
                        f"line {commands[failed.number - 1][0]} ({failed.line}): {failed.error}"
                    )

            await self._twin_first(on_twin)
            outcomes: list[dict[str, Any]] = []
            stream = self.arm.stream(texts, continue_on_error=continue_on_error, wait=True)
            async with self._held_if_cancelled():
                async for line in stream:
                    number = commands[line.number - 1][0]
                    entry: dict[str, Any] = {"line": number, "text": line.line}
                    entry["outcome"] = "ok" if line.ok else f"failed: {line.error}"
                    if line.output:
                        entry["firmware_output"] = list(line.output)
                    outcomes.append(entry)
            result = stream.result
            unsent = [number for number, _ in commands[result.sent :]]
            summary = "done" if result.ok else "stopped" if result.stopped else "done, with errors"
            return await self._final(
                summary,
                sent=result.sent,
                acknowledged=result.acknowledged,
                lines=outcomes,
                not_sent=unsent,
            )

    # ---- stopping: never queued behind the running command ----

    async def hold(self) -> dict[str, Any]:
        """Feed hold (``!``): acts at once, even while a motion tool runs."""
        if self._running == "home":
            raise MirobotUsageError(
                "refused, nothing was sent: the arm is homing, and the firmware ignores feed "
                "hold (!) while it homes: reset (%) is the only thing that stops homing"
            )
        report = await self.arm.hold()
        if self.twin is not None:
            with contextlib.suppress(MirobotError):
                await self.twin.hold()
        return {
            "outcome": f"feed hold sent (!): the arm is {report.state.value}",
            "interrupted": self._running,
            "status": status_dict(report),
        }

    async def resume(self) -> dict[str, Any]:
        """Cycle start (``~``) after a hold."""
        report = await self.arm.resume()
        return {
            "outcome": f"cycle start sent (~): the arm is {report.state.value}",
            "status": status_dict(report),
        }

    async def reset(self) -> dict[str, Any]:
        """Soft reset (``%``): stops at once and clears the queue (a reset that stops motion
        leaves the arm in Alarm)."""
        banner = await self.arm.reset()
        if self.twin is not None:
            with contextlib.suppress(MirobotError):
                await self.twin.reset()
        report = await self.arm.status()
        locked = (
            "the reset stopped motion, so the arm is in Alarm (home or unlock)"
            if report.state is State.ALARM
            else f"the arm is {report.state.value}"
        )
        return {
            "outcome": f"soft reset sent (%): the arm stopped and its queue was cleared; {locked}",
            "banner": list(banner),
            "status": status_dict(report),
        }
