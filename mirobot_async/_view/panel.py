"""The control panel of ``mirobot view`` (viser GUI widgets): status, program, jog, teach.

Widgets only: every button hands its action to :class:`Actions` (the controller, which runs it
on the client's event loop). Button texts are unique on the page (``J1 +``, ``X -``...), so a
person and the browser tests find each control by its text.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import viser
from viser._gui_handles import GuiProgressBarHandle

from mirobot_async._view.holdjog import KEEPALIVE_HZ
from mirobot_async._view.jogplan import (
    CARTESIAN_AXES,
    CARTESIAN_JOINT_RATE,
    JOINT_RATE,
    LINEAR_RATE_MAX,
    TURN_RATE_MAX,
    JogAxis,
)
from mirobot_async._view.teach_ui import TeachPanel

__all__ = ["Actions", "ControlPanel"]


class Actions(Protocol):
    """What the panel's controls ask for (the controller implements it)."""

    def jog_joint(self, joint: int, sign: int) -> None: ...
    def jog_cartesian(self, axis: int, sign: int) -> None: ...
    def hold_jog(self, axis: JogAxis) -> None: ...
    def hold_release(self) -> None: ...
    def command(self, name: str) -> None: ...
    def realtime(self, name: str) -> None: ...
    def teach(self, name: str) -> None: ...


class ControlPanel:
    """The widgets and their handles; the controller reads the inputs and writes the texts."""

    def __init__(self, server: viser.ViserServer, actions: Actions, *, program: str | None) -> None:
        gui = server.gui
        gui.configure_theme(
            control_width="large", dark_mode=False, show_logo=False, show_share_button=False
        )
        self.status = gui.add_markdown("**State:** connecting ...")
        self.message = gui.add_markdown("")
        self.notice = gui.add_markdown("")  # the last refused click (a program's progress
        # overwrites the message line; a refusal must stay readable)
        with gui.add_folder("Motion"):
            stops = gui.add_button_group("Stop", ("Hold", "Resume", "Stop (reset)"))
            stops.on_click(_pick(lambda v: actions.realtime(v)))
            prepare = gui.add_button_group("Arm", ("Home", "Unlock"))
            prepare.on_click(_pick(lambda v: actions.command(v)))
            pump = gui.add_button_group("Pump", ("Pump on", "Pump blow", "Pump off"))
            pump.on_click(_pick(lambda v: actions.command(v)))
            grip = gui.add_button_group("Gripper", ("Gripper open", "Gripper close"))
            grip.on_click(_pick(lambda v: actions.command(v)))
        self.program_text: viser.GuiMarkdownHandle | None = None
        self.progress: GuiProgressBarHandle | None = None
        if program is not None:
            with gui.add_folder("Program"):
                self.program_text = gui.add_markdown(f"**{program}**")
                self.progress = gui.add_progress_bar(0.0)
                run = gui.add_button("Run program", color="green")
                run.on_click(lambda _: actions.command("Run program"))
        with gui.add_folder("Jog joints"):
            self.joint_step = gui.add_number("Step (deg)", 5.0, min=0.1, max=90.0, step=0.1)
            self.joint_speed = gui.add_number("Speed (deg/min)", 1500.0, min=10.0, max=3000.0)
            for j in range(1, 7):
                group = gui.add_button_group(f"J{j}", (f"J{j} -", f"J{j} +"))
                group.on_click(_pick(_jog(actions.jog_joint, j)))
        with gui.add_folder("Hold to jog"):
            gui.add_markdown(f"Moves while held, at {JOINT_RATE * 60:g} deg/min; stops on release.")
            for j in range(6):
                for sign in (-1, 1):
                    _hold_button(gui, actions, JogAxis("joint", j, sign))
        with gui.add_folder("Hold to jog Cartesian"):
            gui.add_markdown(
                f"Moves the tool while held, at up to {LINEAR_RATE_MAX:g} mm/s (X, Y, Z) or "
                f"{TURN_RATE_MAX:g} deg/s (RX, RY, RZ), slower where its joints would exceed "
                f"{CARTESIAN_JOINT_RATE * 60:g} deg/min; stops on release."
            )
            for i in range(6):
                for sign in (-1, 1):
                    _hold_button(gui, actions, JogAxis("pose", i, sign))
        with gui.add_folder("Jog Cartesian"):
            self.move_step = gui.add_number("Step (mm)", 10.0, min=0.1, max=100.0, step=0.1)
            self.turn_step = gui.add_number("Turn step (deg)", 5.0, min=0.1, max=90.0, step=0.1)
            self.linear_speed = gui.add_number("Speed (mm/min)", 1500.0, min=10.0, max=5000.0)
            for i, axis in enumerate(CARTESIAN_AXES):
                group = gui.add_button_group(axis, (f"{axis} -", f"{axis} +"))
                group.on_click(_pick(_jog(actions.jog_cartesian, i)))
        with gui.add_folder("Teach"):
            self.teach = TeachPanel(gui, actions.teach)

    def say(self, text: str) -> None:
        """The panel's message line (errors, refusals, what happened)."""
        self.message.content = text

    def refuse(self, text: str) -> None:
        """Say that a click was refused, and why (kept until a command is accepted)."""
        self.notice.content = f"**{text}**"
        self.message.content = f"**{text}**"


def _pick(
    handler: Callable[[str], None],
) -> Callable[[viser.GuiEvent[viser.GuiButtonGroupHandle]], None]:
    """A button group's callback: the option clicked is the group's value."""

    def callback(event: viser.GuiEvent[viser.GuiButtonGroupHandle]) -> None:
        handler(event.target.value)

    return callback


def _jog(action: Callable[[int, int], None], which: int) -> Callable[[str], None]:
    """A jog group's handler: ``action(which, -1 or +1)`` for the option ``... -``/``... +``."""

    def handler(option: str) -> None:
        action(which, -1 if option.endswith("-") else 1)

    return handler


def _hold_button(gui: viser.GuiApi, actions: Actions, axis: JogAxis) -> None:
    """A hold button: its keep-alives and its release go to ``actions`` on viser's event loop
    as they arrive (async callbacks; plain ones would wait for viser's thread pool)."""

    async def held(_: viser.GuiEvent[viser.GuiButtonHandle]) -> None:
        actions.hold_jog(axis)

    async def released(_: viser.GuiEvent[viser.GuiButtonHandle]) -> None:
        actions.hold_release()

    button = gui.add_button(f"{axis.label} (hold)")
    button.on_hold(held, callback_hz=KEEPALIVE_HZ)
    button.on_click(released)
