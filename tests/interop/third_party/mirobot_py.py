"""Drive the emulator with the community SDK ``mirobot-py`` 1.0.52, unmodified:
``python mirobot_py.py PORT``. It opens ``serial.Serial`` itself (a device path, no URLs) and
waits for the power-on banner on connect, so the emulator runs with ``--reset-on-open``, as an
arm whose DTR line resets it. Prints one JSON line (see wire_probe.report)."""

from __future__ import annotations

import sys
from typing import Any

from mirobot import Mirobot
from wire_probe import raw_status, report

arm = Mirobot(portname=sys.argv[1])  # connect() waits for "Using reset pos!"
port = arm.device.serial_device.serialport
steps: list[dict[str, Any]] = []


def record(name: str) -> None:
    arm.update_status()  # "?" then its "ok"
    status = arm.status
    angle, pose = status.angle, status.cartesian
    steps.append(
        {
            "name": name,
            "state": status.state,
            "joints": [angle.a1, angle.a2, angle.a3, angle.a4, angle.a5, angle.a6],
            "rail": angle.rail,
            "pose": [pose.x, pose.y, pose.z, pose.a, pose.b, pose.c],
            "pump_pwm": status.pump_pwm,
            "valve_pwm": status.valve_pwm,
            "raw": raw_status(port),
        }
    )


arm.home_simultaneous()  # "$H": waits for the homing "...ok", then polls "?" until Idle
record("home")
arm.go_to_axis(10.0, 20.0, 15.0, -5.0, 12.5, 30.0)  # waits for "ok", then for Idle
record("joint")
arm.go_to_cartesian_ptp(180.0, 20.0, 150.0, 0.0, 0.0, 0.0)
record("cartesian")
arm.go_to_cartesian_lin(170.0, 0.0, 150.0, 0.0, 0.0, 0.0)
record("linear")
arm.set_air_pump(1000)  # M3S1000
record("pump")
arm.set_valve(40)  # M4E40
record("valve")
arm.disconnect()
report(steps)
