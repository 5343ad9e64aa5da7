"""Drive the emulator with the vendor's SDK ``wlkata-mirobot-python`` 0.1.14, unmodified:
``python vendor_sdk.py PORT_OR_URL``. Prints one JSON line (see wire_probe.report) with, after
each step, what the SDK parsed from its own status poll and a raw status line."""

from __future__ import annotations

import functools
import sys
from typing import Any

import serial  # pyserial, the SDK's dependency
from wire_probe import raw_status, report

URL = sys.argv[1]
if "://" in URL:
    # SDK 0.1.14 builds ``serial.Serial()`` and assigns ``.port``: pyserial opens URLs
    # (socket://, rfc2217://) only through serial_for_url, so hand the SDK that object instead.
    serial.Serial = functools.partial(serial.serial_for_url, URL, do_not_open=True)

from wlkata_mirobot import WlkataMirobot  # noqa: E402

arm = WlkataMirobot(portname=URL)  # opens, waits 1 s, sends "%" (reset)
# The SDK's own wait for the reset banner (its connect() has this call commented out). Without
# it, the "$h" below reaches the firmware while it reboots, and on the real firmware (the oracle)
# the "?" the SDK sends right after it is answered Idle before the homing starts: on a classic
# arm (Idle at power-on) home() would return at once.
arm.device.wait_for_ok(reset_expected=True)
port = arm.device.serial_device.serialport
steps: list[dict[str, Any]] = []


def record(name: str) -> None:
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


arm.home()  # "$h", then the SDK polls "?" until Idle
record("home")
# wait_ok=True: the SDK waits for the line's "ok" before polling for Idle. With the default
# (None) it polls at once and, as on the real firmware, can read the Idle from before the move.
arm.set_joint_angle({1: 10.0, 2: 20.0, 3: 15.0, 4: -5.0, 5: 12.5, 6: 30.0}, wait_ok=True)
record("joint")
arm.set_tool_pose(x=180.0, y=20.0, z=150.0, roll=0.0, pitch=0.0, yaw=0.0)  # M20 G90 G0
record("cartesian")
arm.set_tool_pose(x=170.0, y=0.0, z=150.0, roll=0.0, pitch=0.0, yaw=0.0, mode="linear")  # G1
record("linear")
arm.pump_suction()  # M3S1000
arm.get_status()
record("pump")
arm.gripper_close()  # M3S60
arm.set_valve(arm.VALVE_ON_PWM_VALUE)  # M4E40
arm.get_status()
record("gripper")
arm.disconnect()
report(steps)
