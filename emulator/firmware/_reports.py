"""What the firmware prints about itself: the status report and the banner."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Final

from .. import motion
from ..motion import Vec7
from . import _codes as c
from ._float32 import print_float, single, step_angle
from ._geometry import vec7
from ._machine import Machine
from ._scanner import c_round, uint8

NUMERIC_ZERO: Final = 1e-9
"""Below this a status number is rounding noise of our double-precision FK and prints as 0."""


def fmt(value: float) -> str:
    """A status number as the firmware prints it (float32, :func:`._float32.print_float`):
    3 decimals, ``-0.000`` for a small negative value (oracle); values within
    ``NUMERIC_ZERO`` of 0 print ``0.000``."""
    return print_float(0.0 if abs(value) < NUMERIC_ZERO else value)


INCH_PER_MM: Final = 0.0393701
"""GRBL's ``INCH_PER_MM`` (float32 arithmetic)."""


def fmt_inch(value: float) -> str:
    """A status number with ``$13=1`` (GRBL's ``printFloat_CoordValue``): times
    :data:`INCH_PER_MM` in float32, 4 decimals (tape ``scenarios-s4/status_mask_fields``: X 202
    prints ``7.9528``, Z 181 ``7.1260``, zero angles ``0.0000``; ASSUMED that angles and
    rotations go through the same conversion: the tape shows only zeros for them)."""
    if abs(value) < NUMERIC_ZERO:
        value = 0.0
    return print_float(single(single(value) * INCH_PER_MM), 4)


def step_position(q: Vec7, settings: Mapping[int, float]) -> Vec7:
    """``q`` in whole motor steps, as the firmware counts and reports it: each axis rounded
    (half away from zero) to its ``$100..$106`` steps per degree (mm for the rail), then
    divided back in float32 as the firmware does (:func:`._float32.step_angle`).

    The one place where the report quantises; it goes when the planner tracks steps itself.
    """
    out = list(q)
    for k, joint in enumerate(motion.LETTER_TO_JOINT):
        per_unit = settings[100 + k]
        if per_unit > 0.0:
            out[joint] = step_angle(c_round(q[joint] * per_unit), per_unit)
    return vec7(out)


def status_line(m: Machine, state: str | None = None) -> str:
    """The status report at this instant, without its ``\\r\\n`` (PROTOCOL 5); ``state``
    overrides the state word."""
    mask = uint8(m.settings[10])
    parts = ["<", m.state if state is None else state]
    q = step_position(m.planner.position, m.settings)
    if mask & 1:
        wire = (q[3], q[4], q[5], q[6], q[0], q[1], q[2])
        pose = m.geometry.fk(q)
        number = fmt_inch if m.settings[13] else fmt  # $13: report inches
        parts.append(",Angle(ABCDXYZ):")
        parts.append(",".join(number(v) for v in wire))
        parts.append(",Cartesian coordinate(XYZ RxRyRz):")
        parts.append(",".join(number(v) for v in pose))
    if mask & 32:
        pump = math.trunc(m.modal.pump_pwm) % 2**32
        valve = math.trunc(m.modal.valve_pwm) % 2**32
        parts.append(f",Pump PWM:{pump},Valve PWM:{valve}")
    if mask & 64:
        parts.append(f",Motion_MODE:{1 if m.modal.cart_mode else 0}")
    if mask & 4:
        parts.append(f",Buf:{len(m.planner.blocks)}")
    if mask & 8:
        parts.append(f",RX:{len(m.rx)}")
    if mask & 16:
        parts.append(f",Lim:{m.geometry.limit_pins(q):07b}")
    parts.append(">")
    return "".join(parts)


def banner(m: Machine) -> list[str]:
    """The welcome message (PROTOCOL 4.2), then the unlock hint when in Alarm; the 2024
    family's one line (EVIDENCE-NEWER.md 1: no unlock hint after it)."""
    if m.family == "2024":
        return [c.BANNER_2024.format(version=c.VERSIONS[m.family])]
    d1, a1, a2, a3, d4, el = m.geometry.dh_values()
    offsets = m.geometry.base_offset()
    pose = m.geometry.fk(motion.ZERO)
    lines = [
        "",
        f"Grbl {c.GRBL_VERSION} ['$' for help]",
        "",
        f"Qinnew Robot {c.VERSIONS[m.profile]} based on Grbl {c.GRBL_VERSION} ['$' for help]",
        "",
        f"D1: {int(d1)}",
        f"A1: {int(a1)}",
        f"A2: {int(a2)}",
        f"A3: {int(a3)}",
        f"D4: {int(d4)}",
        f"L: {int(el)}",
        f"X offset: {int(offsets[0])}",
        f"Y offset: {int(offsets[1])}",
        f"Z offset: {int(offsets[2])}",
        "Initialized Cartesian coordinates and rotation: ",
        f"X: {int(pose[0])}",
        f"Y: {int(pose[1])}",
        f"Z: {int(pose[2])}",
        f"RX: {int(pose[3])}",
        f"RY: {int(pose[4])}",
        f"RZ: {int(pose[5])}",
        "Using reset pos!",
    ]
    if m.alarm:
        lines.append(c.FEEDBACK_ALARM_LOCK)
    return lines
