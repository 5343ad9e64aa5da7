"""Drive the emulator with the vendor's newer SDK ``wlkatapython`` 0.1.1, unmodified, through its
direct-arm class (``Mirobot_UART`` with address -1: no controller box): ``python
wlkatapython_arm.py PORT_OR_URL``. Its controller-only calls (``homing`` is ``o105``, ``runFile``,
``cancellation``, ``restart``, ``version``, the GPIO calls) are left out; homing goes through its
pass-through ``sendMsg("$H")``. Prints one JSON line (see wire_probe.report)."""

from __future__ import annotations

import sys
import time
from typing import Any

import serial  # pyserial: the SDK takes an open port from its user
from Mirobot_robot.Mirobot_UART import Mirobot_UART
from wire_probe import raw_status, report

IDLE_TIMEOUT = 20.0
"""Seconds to wait for Idle after a step (the SDK's own wait has no limit)."""

port = serial.serial_for_url(sys.argv[1], 115200, timeout=1)
arm = Mirobot_UART(block_flag=False)
arm.init(port, -1)
steps: list[dict[str, Any]] = []


def wait_idle() -> None:
    """Poll the SDK's getState() (0.6 s a poll: its own sleeps) until it reads Idle."""
    deadline = time.monotonic() + IDLE_TIMEOUT
    while arm.getState() != "Idle":
        if time.monotonic() > deadline:
            raise TimeoutError(f"not Idle within {IDLE_TIMEOUT} s: {arm.mirobot_state_all}")


def record(name: str) -> None:
    """Keep what the SDK parsed at its last status poll, and a raw status line."""
    state = arm.mirobot_state_all
    steps.append(
        {
            "name": name,
            "state": state["state"],
            "joints": [float(state[f"angle_{axis}"]) for axis in "XYZABC"],
            "rail": float(state["angle_D"]),
            "pose": [
                float(state[f"coordinate_{axis}"]) for axis in ("X", "Y", "Z", "RX", "RY", "RZ")
            ],
            "pump_pwm": int(state["pump"]),
            "valve_pwm": int(state["valve"]),
            "raw": raw_status(port),
        }
    )


arm.sendMsg("$H")  # the direct arm's homing (the SDK's homing() is the controller's o105)
wait_idle()
record("home")
arm.function_block(True)  # the SDK's own wait: three Idle polls in a row
arm.writeangle(0, 10.0, 20.0, 15.0, -5.0, 12.5, 30.0)  # M21G90G00X10.0Y20.0...
arm.function_block(False)
record("joint")
arm.speed(2000)  # F2000
arm.writecoordinate(1, 0, 180.0, 20.0, 150.0, 0.0, 0.0, 0.0)  # M20G90G01X180.0...
wait_idle()
record("linear")
arm.pump(1)  # M3 S1000
arm.getStatus()
record("pump")
arm.gripper(2)  # M3 S60
arm.getStatus()
record("gripper")
port.close()
report(steps)
