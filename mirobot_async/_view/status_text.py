"""The status block of the view's panel (Markdown), shared by the pendant and the script view."""

from __future__ import annotations

from typing import Final

from mirobot_async._core import gcode
from mirobot_async._core.replies import State, StatusReport

__all__ = ["describe_status"]

_STATE_WORDS: Final = {State.HOME: "Home (homing)"}
_OUTPUT_WORDS: Final = {  # what the PWM 1 output (M3 S...) drives, by its value
    gcode.PUMP_OFF: "off",
    gcode.PUMP_SUCK: "pump sucking",
    gcode.PUMP_BLOW: "pump blowing",
    gcode.GRIPPER_OPEN: "gripper open",
    gcode.GRIPPER_CLOSE: "gripper closed",
}
_LEGACY_GRIPPER: Final = {
    0: "off",
    gcode.VALVE_GRIPPER_OPEN: "open",
    gcode.VALVE_GRIPPER_CLOSE: "closed",
}


def describe_status(report: StatusReport, running: str | None) -> str:
    """The panel's status block (Markdown); ``running``: what the view runs, if anything."""
    word = _STATE_WORDS.get(report.state, report.state.value)
    joints = "  ".join(f"J{i} {v:.2f}" for i, v in enumerate(report.joints, start=1))
    x, y, z, rx, ry, rz = report.pose
    rail = "" if report.rail is None else f"  \n**Rail:** {report.rail:.2f} mm"
    outputs = _OUTPUT_WORDS.get(report.pump_pwm, f"PWM {report.pump_pwm}")
    legacy = _LEGACY_GRIPPER.get(report.valve_pwm, f"PWM {report.valve_pwm}")
    lines = [
        f"**State:** {word}" + (f" (running: {running})" if running else ""),
        f"**Joints:** {joints}",
        f"**Tool:** x {x:.2f}  y {y:.2f}  z {z:.2f}  rx {rx:.2f}  ry {ry:.2f}  rz {rz:.2f}",
        f"**Pump/gripper:** {outputs}  **Valve/legacy gripper:** {legacy}",
    ]
    return "  \n".join(lines) + rail
