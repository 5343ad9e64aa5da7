"""A URDF of the Mirobot built from the project's own kinematics (``mirobot urdf``).

The chain is the modified DH table of PROTOCOL 8.1 for a firmware profile
(:data:`~mirobot_async.kinematics.DH_2021` or :data:`~mirobot_async.kinematics.DH_CLASSIC`): joint
``i``'s origin is ``RotX(alpha) TransX(a) RotZ(offset) TransZ(d)`` and it turns about its z axis,
so the fixed frame ``flange`` is frame 6, the point and orientation that
:func:`~mirobot_async.kinematics.forward` reports (tests check it through yourdfpy to 0.05 mm):
its z axis is J6's, pointing into the wrist. ``tool0`` is the ROS-Industrial tool frame: at the
same point, turned half a turn about x, so that its z axis points out of the flange (the
approach direction) and its x axis is the flange's. The limits are the firmware's joint ranges,
the velocities its default max rates. The geometry is our own: cylinders for the joint housings
and the links between the frames, a box for the base, a short cylinder for the tool; no vendor
meshes. Each shape is both a visual and a collision element (primitives, as planners want
them). Lengths in metres, angles in radians (ROS conventions). Pure module.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import DH, DH_2021, DH_CLASSIC, JOINT_LIMITS

__all__ = ["FLANGE_LINK", "JOINT_NAMES", "TOOL_LINK", "build_urdf", "dh_of"]

JOINT_NAMES: Final = ("joint1", "joint2", "joint3", "joint4", "joint5", "joint6")
"""The revolute joints J1..J6, in order (a configuration vector follows this order)."""
FLANGE_LINK: Final = "flange"
"""The flange frame: the point and orientation ``kinematics.forward`` reports (z into the wrist)."""
TOOL_LINK: Final = "tool0"
"""The ROS-Industrial tool frame: the flange point, z out of the flange, x the flange's x."""

_MAX_RATES: Final = {  # deg/min, J1..J6: the profiles' $110..$116 defaults in joint order
    "classic": (2000.0, 2000.0, 2000.0, 1800.0, 1500.0, 2500.0),
    "2021": (1800.0, 1500.0, 1800.0, 1800.0, 1500.0, 2500.0),
    "2024": (1800.0, 1500.0, 1800.0, 1800.0, 1500.0, 2500.0),  # ASSUMED: the 2021 defaults
}
_MM: Final = 0.001
_HOUSING_RADIUS: Final = 0.024
_HOUSING_LENGTH: Final = 0.05
_LINK_RADIUS: Final = 0.016
_BASE_SIDE: Final = 0.11
_TOOL_RADIUS: Final = 0.008
_TOOL_LENGTH: Final = 0.03
_MATERIALS: Final = {
    "body": (0.62, 0.68, 0.76, 1.0),
    "housing": (0.22, 0.24, 0.28, 1.0),
    "tool": (0.90, 0.35, 0.10, 1.0),
}


def dh_of(firmware: str) -> DH:
    """The DH geometry of a firmware profile (``classic``, ``2021``, ``2024``: ASSUMED the
    2021 one, docs/2024-profile.md)."""
    if firmware == "classic":
        return DH_CLASSIC
    if firmware in ("2021", "2024"):
        return DH_2021
    raise MirobotUsageError(f"firmware={firmware!r}: expected 'classic', '2021' or '2024'")


@dataclass(frozen=True, slots=True)
class _Row:
    """One row of the modified DH table (mm, degrees)."""

    alpha: float
    a: float
    d: float
    offset: float


def _rows(dh: DH) -> tuple[_Row, ...]:
    """PROTOCOL 8.1: alpha(i-1), a(i-1), d(i), theta offset of joints 1..6."""
    return (
        _Row(0.0, 0.0, dh.d1, 0.0),
        _Row(-90.0, dh.a1, 0.0, -90.0),
        _Row(0.0, dh.a2, 0.0, 0.0),
        _Row(-90.0, dh.a3, dh.d4, 0.0),
        _Row(90.0, 0.0, 0.0, 90.0),
        _Row(90.0, 0.0, dh.l, 0.0),
    )


Matrix = tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]


def _rot_x(deg: float) -> Matrix:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return ((1.0, 0.0, 0.0), (0.0, c, -s), (0.0, s, c))


def _rot_z(deg: float) -> Matrix:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return ((c, -s, 0.0), (s, c, 0.0), (0.0, 0.0, 1.0))


def _mul(p: Matrix, q: Matrix) -> Matrix:
    r = [[sum(p[i][k] * q[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    return ((r[0][0], r[0][1], r[0][2]), (r[1][0], r[1][1], r[1][2]), (r[2][0], r[2][1], r[2][2]))


def _rpy(m: Matrix) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw (radians, ``Rz Ry Rx``) of ``m``; at gimbal lock yaw is 0."""
    sy = -m[2][0]
    if abs(sy) > 1.0 - 1e-12:
        pitch = math.copysign(math.pi / 2, sy)
        return math.atan2(-m[1][2], m[1][1]), pitch, 0.0
    roll = math.atan2(m[2][1], m[2][2])
    pitch = math.atan2(sy, math.hypot(m[2][1], m[2][2]))
    yaw = math.atan2(m[1][0], m[0][0])
    return roll, pitch, yaw


def _num(value: float) -> str:
    """Full precision (repr), -0 as 0: the chain must reproduce the kinematics to rounding."""
    return repr(value + 0.0)


def _vec(values: Sequence[float]) -> str:
    return " ".join(_num(v) for v in values)


def _align_z(vector: Sequence[float]) -> tuple[float, float, float]:
    """rpy of a rotation that turns the z axis onto ``vector`` (for a cylinder along it)."""
    x, y, z = vector
    norm = math.sqrt(x * x + y * y + z * z)
    ux, uy, uz = x / norm, y / norm, z / norm
    pitch = math.acos(max(-1.0, min(1.0, uz)))  # about y, then yaw about z
    yaw = math.atan2(uy, ux) if math.hypot(ux, uy) > 1e-12 else 0.0
    m = _mul(_rot_z(math.degrees(yaw)), _rot_y(math.degrees(pitch)))
    return _rpy(m)


def _rot_y(deg: float) -> Matrix:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return ((c, 0.0, s), (0.0, 1.0, 0.0), (-s, 0.0, c))


def _shape(origin: str, geometry: str, material: str) -> str:
    """One shape as a visual (with its material) and as a collision element."""
    return (
        f"    <visual>\n      {origin}\n      {geometry}\n"
        f'      <material name="{material}"/>\n    </visual>\n'
        f"    <collision>\n      {origin}\n      {geometry}\n    </collision>\n"
    )


def _cylinder(start: Sequence[float], end: Sequence[float], radius: float, material: str) -> str:
    """A cylinder from ``start`` to ``end`` (metres, in the link's frame)."""
    delta = [b - a for a, b in zip(start, end, strict=True)]
    length = math.sqrt(sum(v * v for v in delta))
    centre = [(a + b) / 2 for a, b in zip(start, end, strict=True)]
    return _shape(
        f'<origin xyz="{_vec(centre)}" rpy="{_vec(_align_z(delta))}"/>',
        f'<geometry><cylinder radius="{_num(radius)}" length="{_num(length)}"/></geometry>',
        material,
    )


def _link_visuals(index: int, rows: Sequence[_Row]) -> str:
    """Link ``index`` (1..6): its joint housing and the bones to the next joint's origin."""
    parts = []
    half = _HOUSING_LENGTH / 2 if index <= 3 else _HOUSING_LENGTH / 3
    radius = _HOUSING_RADIUS if index <= 3 else _HOUSING_RADIUS * 0.75
    parts.append(_cylinder((0.0, 0.0, -half), (0.0, 0.0, half), radius, "housing"))
    if index < 6:
        nxt = rows[index]
        sa, ca = math.sin(math.radians(nxt.alpha)), math.cos(math.radians(nxt.alpha))
        elbow = (nxt.a * _MM, 0.0, 0.0)
        end = (nxt.a * _MM, -sa * nxt.d * _MM, ca * nxt.d * _MM)
        if abs(nxt.a) > 1e-9:
            parts.append(_cylinder((0.0, 0.0, 0.0), elbow, _LINK_RADIUS, "body"))
        if abs(nxt.d) > 1e-9:
            parts.append(_cylinder(elbow, end, _LINK_RADIUS * 0.85, "body"))
    else:  # the tool: the flange points away from the wrist, along -z6
        parts.append(_cylinder((0.0, 0.0, 0.0), (0.0, 0.0, -_TOOL_LENGTH), _TOOL_RADIUS, "tool"))
    return "".join(parts)


def build_urdf(firmware: str = "2021", *, name: str = "mirobot") -> str:
    """The URDF (XML text) of the arm with the ``firmware`` profile's geometry and limits."""
    dh = dh_of(firmware)
    rows = _rows(dh)
    rates = _MAX_RATES[firmware]
    out = [
        '<?xml version="1.0"?>\n',
        f"<!-- Mirobot ({firmware} firmware geometry), generated by mirobot-async from its own\n"
        "     kinematics (modified DH, PROTOCOL 8.1); simple geometry, no vendor meshes. -->\n",
        f'<robot name="{name}">\n',
    ]
    for material, rgba in _MATERIALS.items():
        out.append(f'  <material name="{material}"><color rgba="{_vec(rgba)}"/></material>\n')
    base_height = dh.d1 * _MM - _HOUSING_LENGTH / 2
    base = _shape(
        f'<origin xyz="0 0 {_num(base_height / 2)}" rpy="0 0 0"/>',
        f'<geometry><box size="{_vec((_BASE_SIDE, _BASE_SIDE, base_height))}"/></geometry>',
        "body",
    )
    out.append(f'  <link name="base_link">\n{base}  </link>\n')
    for index in range(1, len(rows) + 1):
        out.append(f'  <link name="link{index}">\n{_link_visuals(index, rows)}  </link>\n')
    parent = "base_link"
    for index, (row, joint) in enumerate(zip(rows, JOINT_NAMES, strict=True), start=1):
        sa, ca = math.sin(math.radians(row.alpha)), math.cos(math.radians(row.alpha))
        xyz = (row.a * _MM, -sa * row.d * _MM, ca * row.d * _MM)
        rpy = _rpy(_mul(_rot_x(row.alpha), _rot_z(row.offset)))
        low, high = JOINT_LIMITS[index - 1]
        velocity = math.radians(rates[index - 1]) / 60.0
        out.append(
            f'  <joint name="{joint}" type="revolute">\n'
            f'    <parent link="{parent}"/>\n    <child link="link{index}"/>\n'
            f'    <origin xyz="{_vec(xyz)}" rpy="{_vec(rpy)}"/>\n    <axis xyz="0 0 1"/>\n'
            f'    <limit lower="{_num(math.radians(low))}" upper="{_num(math.radians(high))}" '
            f'effort="10" velocity="{_num(velocity)}"/>\n  </joint>\n'
        )
        parent = f"link{index}"
    out.append(
        f'  <link name="{FLANGE_LINK}"/>\n'
        f'  <joint name="link6-{FLANGE_LINK}" type="fixed">\n    <parent link="link6"/>\n'
        f'    <child link="{FLANGE_LINK}"/>\n    <origin xyz="0 0 0" rpy="0 0 0"/>\n  </joint>\n'
        f'  <link name="{TOOL_LINK}"/>\n'
        f'  <joint name="{FLANGE_LINK}-{TOOL_LINK}" type="fixed">\n'
        f'    <parent link="{FLANGE_LINK}"/>\n    <child link="{TOOL_LINK}"/>\n'
        f'    <origin xyz="0 0 0" rpy="{_num(math.pi)} 0 0"/>\n  </joint>\n'
        "</robot>\n"
    )
    return "".join(out)
