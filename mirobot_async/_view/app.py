"""``mirobot view``: a live 3D twin and a teach pendant in the browser.

One viser server (its own thread and event loop, its web client from the wheel: nothing is
fetched from elsewhere) shows :class:`~mirobot_async._view.scene.ArmScene` and
:class:`~mirobot_async._view.panel.ControlPanel`; :class:`ViewController` follows the status
stream (every :data:`STATUS_INTERVAL` s) and runs what the panel asks on the client's event
loop, one command at a time (jogs, homing, taught points, the program); Hold, Resume and Stop
are written at once, whatever runs. An envelope given to the client checks every jog and every
streamed line before it is written.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import viser

from mirobot_async._core.replies import StatusReport
from mirobot_async._view.holdjog import HoldJog
from mirobot_async._view.jogplan import CARTESIAN_AXES, JogAxis
from mirobot_async._view.panel import ControlPanel
from mirobot_async._view.preview import ProgramPreview
from mirobot_async._view.scene import ArmScene
from mirobot_async._view.status_text import describe_status
from mirobot_async._view.teach_ui import PLAY, Teacher
from mirobot_async.errors import MirobotConnectionError, MirobotError, MirobotTimeoutError

if TYPE_CHECKING:
    from mirobot_async._client.client import Mirobot
    from mirobot_async._safety.envelope import Envelope

__all__ = ["STATUS_INTERVAL", "ProgramSource", "ViewController"]

_log = logging.getLogger("mirobot_async.view")

STATUS_INTERVAL: Final = 0.05
"""Seconds between status reports the view asks for (20 Hz; the page follows each one)."""
_QUEUE_LIMIT: Final = 8
"""Commands waiting behind the running one; clicks beyond are refused (a stuck arm)."""
_PUMP: Final = {"Pump on": "suction_on", "Pump blow": "blow", "Pump off": "pump_off"}


@dataclass(frozen=True, slots=True)
class ProgramSource:
    """A program to preview and run: its name, raw lines, the commands to stream."""

    name: str
    lines: list[str]
    commands: list[tuple[int, str]]
    """(file line number, command text) of each non-empty command."""


class ViewController:
    """The view's behaviour: status following, the command queue, the program, the teach table."""

    def __init__(
        self,
        server: viser.ViserServer,
        arm: Mirobot,
        *,
        firmware: str,
        program: ProgramSource | None,
        preview: ProgramPreview | None,
        envelope: Envelope | None,
        export_dir: Path,
    ) -> None:
        self.server = server
        self.arm = arm
        self.firmware = firmware
        self.program = program
        self.preview = preview
        self.export_dir = export_dir
        self.link_lost = asyncio.Event()
        """Set when the link to the arm is gone (the page says so; the command exits)."""
        self.link_error: str | None = None
        self.loop = asyncio.get_running_loop()
        self.scene = ArmScene(server, firmware)
        self.panel = ControlPanel(server, self, program=None if program is None else program.name)
        self.teacher = Teacher(server, self.panel.teach, firmware=firmware, export_dir=export_dir)
        self.holdjog = HoldJog(arm, self.panel.say, firmware)
        server.on_client_disconnect(self._page_gone)
        self.last: StatusReport | None = None
        self.reports = 0
        self.current: str | None = None
        self._programs = 0
        """Programs ("Run program", "Run all points") queued or running."""
        self._queue: asyncio.Queue[tuple[str, Callable[[], Awaitable[object]], bool]] = (
            asyncio.Queue()
        )
        if envelope is not None:
            self.scene.show_envelope(envelope)
        if preview is not None and program is not None:
            self.scene.show_preview(preview)
            self.panel.program_text.content = describe_preview(program, preview)  # type: ignore[union-attr]

    # ------------------------------------------------------------------------------------
    # Tasks: status following and the command worker

    async def follow_status(self) -> None:
        """Show every status report (about :data:`STATUS_INTERVAL` apart) until cancelled. The
        firmware answers no ``?`` while it homes: the view says so and keeps asking. When the
        link is gone the page says so at once and :attr:`link_lost` is set (the command exits)."""
        while True:
            try:
                async with contextlib.aclosing(self.arm.statuses(STATUS_INTERVAL)) as reports:
                    async for report in reports:
                        self.last = report
                        self.reports += 1
                        self.scene.show_status(report)
                        self.panel.status.content = describe_status(report, self.current)
            except MirobotTimeoutError:
                self.panel.status.content = "**State:** no status reply (homing?)"
            except MirobotConnectionError as err:
                self.lose_link(str(err))
                return

    def lose_link(self, why: str) -> None:
        """Say on the page that the link is lost (state, joints and tool no longer known)."""
        self.link_error = why
        self.panel.status.content = (
            f"**State: LINK LOST** ({why}). The arm's state is unknown; mirobot view has "
            "stopped: start it again once the arm is connected."
        )
        self.panel.say("**Link to the arm lost: nothing more can be sent.**")
        self.link_lost.set()

    async def work(self) -> None:
        """Run queued commands one at a time until cancelled; a failure is shown, not raised."""
        while True:
            name, action, program = await self._queue.get()
            self.current = name
            try:
                outcome = await action()
                self.panel.say(outcome if isinstance(outcome, str) else f"{name}: done")
            except MirobotConnectionError as err:
                self.lose_link(str(err))
            except MirobotError as err:
                self.panel.say(f"**{name}: {err}**")
            except Exception as err:  # a bug must not kill the pendant; it is logged
                _log.exception("view command %s failed", name)
                self.panel.say(f"**{name}: {type(err).__name__}: {err}**")
            finally:
                self.current = None
                if program:
                    self._programs -= 1

    def _submit(
        self,
        name: str,
        action: Callable[[], Awaitable[object]],
        *,
        program: bool = False,
        refused: Callable[[], None] | None = None,
    ) -> None:
        """Queue ``action`` on the client's loop (from viser's threads). Refused, said on the
        page, when the link is lost, when a program (``program=True``) is queued or running
        (a jog would wait behind it and run after it: Hold, Resume and Stop are not queued),
        or when :data:`_QUEUE_LIMIT` commands wait (then ``refused()`` is called)."""

        def put() -> None:
            if refused is not None and (
                self.link_lost.is_set() or self._programs or self._queue.qsize() >= _QUEUE_LIMIT
            ):
                refused()
            if self.link_lost.is_set():
                self.panel.refuse(f"{name}: refused, the link to the arm is lost")
            elif self._programs:
                self.panel.refuse(
                    f"{name}: refused, a program is running (it would run after the "
                    "program; Hold, Resume and Stop (reset) work at once)"
                )
            elif self._queue.qsize() >= _QUEUE_LIMIT:
                self.panel.refuse(f"{name}: refused, {self._queue.qsize()} commands still waiting")
            else:
                self.panel.notice.content = ""
                self._programs += program
                self._queue.put_nowait((name, action, program))

        self.loop.call_soon_threadsafe(put)

    # ------------------------------------------------------------------------------------
    # The panel's actions (called in viser's threads)

    def jog_joint(self, joint: int, sign: int) -> None:
        step = float(self.panel.joint_step.value) * sign
        speed = float(self.panel.joint_speed.value)
        steps: list[float | None] = [None] * 6
        steps[joint - 1] = step
        self._submit(
            f"J{joint} {'+' if sign > 0 else '-'}{abs(step):g} deg",
            lambda: self.arm.move_joints(*steps, relative=True, speed=speed),
        )

    def jog_cartesian(self, axis: int, sign: int) -> None:
        name = CARTESIAN_AXES[axis]
        step = float(self.panel.move_step.value if axis < 3 else self.panel.turn_step.value) * sign
        speed = float(self.panel.linear_speed.value)
        steps: list[float | None] = [None] * 6
        steps[axis] = step
        self._submit(
            f"{name} {'+' if sign > 0 else '-'}{abs(step):g}",
            lambda: self.arm.move_pose(*steps, relative=True, linear=True, speed=speed),
        )

    def hold_jog(self, axis: JogAxis) -> None:
        """A keep-alive of a held jog button (any thread: returns at once); the first one
        queues the jog."""
        if self.holdjog.press(axis):
            self._start_hold(axis)

    def hold_release(self) -> None:
        """A hold button was let go (any thread: returns at once)."""
        self.holdjog.release()

    async def _page_gone(self, _: viser.ClientHandle) -> None:
        # async: viser runs it on its event loop at once (a page gone mid-jog: stop)
        self.holdjog.release("page closed")

    def _start_hold(self, axis: JogAxis) -> None:
        async def jog() -> str:
            outcome = await self.holdjog.run(axis)
            follow = self.holdjog.take_next()  # another hold button pressed meanwhile
            if follow is not None:
                self._start_hold(follow)
            return outcome

        self._submit(f"{axis.label} (hold)", jog, refused=self.holdjog.refused)

    def command(self, name: str) -> None:
        arm = self.arm
        if name == "Home":
            self._submit(name, arm.home)
        elif name == "Unlock":
            self._submit(name, arm.unlock)
        elif name in _PUMP:
            self._submit(name, getattr(arm, _PUMP[name]))
        elif name == "Gripper open":
            self._submit(name, arm.gripper_open)
        elif name == "Gripper close":
            self._submit(name, arm.gripper_close)
        elif name == "Run program":
            self._submit(name, self.run_program, program=True)

    def realtime(self, name: str) -> None:
        """Hold, Resume, Stop (reset): written at once (they jump the queue); Stop also drops
        the commands waiting."""
        arm = self.arm

        async def act() -> None:
            try:
                if name == "Hold":
                    await arm.hold()
                elif name == "Resume":
                    await arm.resume()
                else:
                    while not self._queue.empty():
                        if self._queue.get_nowait()[2]:
                            self._programs -= 1
                    await arm.reset()
                self.panel.say(f"{name}: sent")
            except MirobotError as err:
                self.panel.say(f"**{name}: {err}**")

        asyncio.run_coroutine_threadsafe(act(), self.loop)

    def teach(self, name: str) -> None:
        """The teach table's buttons (table changes happen on the loop, in order)."""

        self._submit(name, lambda: self.teacher.act(name, self.arm), program=name == PLAY)

    # ------------------------------------------------------------------------------------
    # The program

    async def run_program(self) -> str:
        """Stream the program with progress (refused, nothing sent, when lines are flagged)."""
        program, preview = self.program, self.preview
        if program is None or preview is None:
            raise _ViewError("no program given")
        if preview.flagged:
            raise _ViewError(
                f"{len(preview.flagged)} flagged line(s) in {program.name}: nothing was sent"
            )
        bar = self.panel.progress
        assert bar is not None
        total = len(program.commands)
        _set_value(bar, 0.0)

        def progress(result: object) -> None:
            number = getattr(result, "number", 0)
            _set_value(bar, 100.0 * number / max(total, 1))
            # acknowledged, not yet run: the arm queues up to 127 bytes of lines ahead
            self.panel.say(f"{number}/{total} lines acknowledged by the arm; it runs them in order")

        result = await self.arm.stream(
            [text for _, text in program.commands], on_progress=progress, wait=True
        )
        if result.errors:
            failed = result.errors[0]
            line = program.commands[failed.number - 1][0]
            raise _ViewError(f"{program.name}:{line}: {failed.error or 'failed'}")
        _set_value(bar, 100.0)
        return f"{program.name}: {total} lines done"


def _set_value(handle: Any, value: object) -> None:
    """Set an input's value (viser's typing declares ``value`` read-only on some handles;
    the setter exists and sends the new value to the page)."""
    handle.value = value


class _ViewError(MirobotError):
    """A pendant action that cannot be done (shown on the page)."""


def describe_preview(program: ProgramSource, preview: ProgramPreview) -> str:
    """The program folder's text: size, flagged lines with their numbers."""
    head = f"**{program.name}**: {len(program.commands)} commands, path predicted before sending"
    if not preview.flagged:
        text = f"{head}  \nNo flagged lines."
    else:
        rows = "\n".join(f"- line {f.number}: `{f.text}`: {f.message}" for f in preview.flagged)
        text = (
            f"{head}  \n**Flagged lines ({len(preview.flagged)})**, marked red in the view:\n{rows}"
        )
    if preview.unknown:
        first = preview.unknown[0]
        text += f"  \nPath not drawn after line {first.number}: {first.message}"
    return text
