"""The arm's geometry from the settings: FK, firmware-branch IK, soft limits, limit switches.

IK failures arrive as the kinematics module's typed exceptions and leave here as
:class:`Refusal` carrying the firmware's text (:func:`kinematics_refusal`).
"""

from __future__ import annotations

import math
import operator
from collections.abc import Mapping, Sequence
from typing import Final

from mirobot_async import kinematics as kin
from mirobot_async.errors import MirobotUsageError

from .. import motion
from ..motion import AxisLimits, Steps7, Vec7
from ..motion import _axes as axes
from . import _codes as c
from ._float32 import single

Pose = tuple[float, float, float, float, float, float]

HARD_LIMIT_SWITCHES: Final[tuple[tuple[float, float], ...]] = tuple(kin.JOINT_LIMITS[:3])
"""ASSUMED: the J1..J3 limit switches sit at the factory range ends (degrees) ..."""

SWITCH_OVERTRAVEL: Final = 0.5
"""... and close once the joint is more than this many degrees beyond them (ASSUMED for a real
arm, whose switch placement nobody has measured: it is the oracle harness's switch model,
``[-100, 160]``, ``[-30, 70]``, ``[-170, 60]`` widened by 0.5, checked against the firmware's
own step count). GRBL stops the step pulses the moment a switch closes, so the arm stops on the
first whole motor step past it: J1 at 160.515 (9106 steps at 56.73/degree) or -100.511, J2 at
70.502 or -30.504, J3 at 60.516 or -170.516, the other axes where their steps are at that step
event (oracle, at any feed; ``M21 G90 X165 Y75``: J2 closes first, J1 at 155.086). A move
that starts with its switch already closed passes it (no edge, no alarm; oracle)."""

IK_CHECKS_JOINT_RANGES: Final = False
"""Whether the IK refuses angles outside the factory ranges (``There is one angle out of
limit!!!``). The oracle does not: a wrist out of range gets ``Soft limit triggered:B`` with
``$20=1`` and moves with ``$20=0``; J1 beyond 160 runs into the switch."""


def shoulder_mirrored_pose(
    pose: Sequence[float], dh: kin.DH, tool: Sequence[float]
) -> tuple[float, ...]:
    """The pose whose textbook IK gives the firmware's joints for ``pose``.

    The firmware measures the wrist centre's horizontal distance from the shoulder (J2's axis,
    ``A1`` from the base axis) without its sign: a wrist centre behind the shoulder is solved as
    if it were as far in front of it, on the same J1 azimuth, and the arm goes there (oracle:
    ``M20 G90 G0 X1 Y5 Z182 A0 B0 C0`` with ``$20=0`` ends at J2 -78.770, pose X 11.551 Y 57.749;
    the textbook J2 is -102.326, which is why ``$20=1`` names ``Y`` there, not ``B``). That
    mirrored pose is :func:`mirobot_async.kinematics.firmware_pose`; ``pose`` itself when the
    wrist centre is in front of the shoulder."""
    mirrored = kin.firmware_pose(pose, dh, tool)
    return tuple(float(v) for v in pose[:6]) if mirrored is None else mirrored


_LIMIT_SETTINGS: Final = (11, *range(100, 107), *range(110, 117), *range(120, 127))
"""The settings :meth:`Geometry.limits` is built from (junction deviation, steps, rates,
accelerations)."""

_limit_settings_of: Final = operator.itemgetter(*_LIMIT_SETTINGS)
"""The values of ``_LIMIT_SETTINGS`` as a tuple (``KeyError`` when one is missing)."""

FW_LETTERS: Final = "ABCDXYZ"  # soft-limit letters in the firmware's axis order a..g


_SOFT_LIMIT_AXES: Final = tuple(
    (letter, motion.LETTER_TO_JOINT[k], 130 + k, 140 + k) for k, letter in enumerate(FW_LETTERS)
)
"""Per firmware axis a..g: its letter, its joint index and its ``$13x``/``$14x`` settings."""

_joints_in_letter_order: Final = operator.itemgetter(*motion.LETTER_TO_JOINT)
_soft_highs_of: Final = operator.itemgetter(*(high for _, _, high, _ in _SOFT_LIMIT_AXES))
_soft_lows_of: Final = operator.itemgetter(*(low for _, _, _, low in _SOFT_LIMIT_AXES))
"""A joint vector and the ``$13x``/``$14x`` settings in the order of :data:`_SOFT_LIMIT_AXES`."""


class Refusal(Exception):
    """A motion refused with one of the "ok but dropped" texts (``then``: a second text the
    firmware prints after it, see :meth:`MoveBuilder.plan`)."""

    def __init__(self, text: str, then: str | None = None) -> None:
        super().__init__(text)
        self.text = text
        self.then = then


def _shoulder_front(pose: Sequence[float], q1: float, dh: kin.DH, tool: Sequence[float]) -> bool:
    """Whether ``q1`` faces the wrist centre of ``pose`` (the shoulder-front branch)."""
    rot = kin.rpy_to_matrix(pose[3], pose[4], pose[5])
    wx = pose[0] - (rot[0][0] * tool[0] + rot[0][1] * tool[1] + rot[0][2] * tool[2])
    wy = pose[1] - (rot[1][0] * tool[0] + rot[1][1] * tool[1] + rot[1][2] * tool[2])
    wx, wy = wx - dh.l * rot[0][2], wy - dh.l * rot[1][2]
    if math.hypot(wx, wy) < 1e-9:
        return True  # on the base axis: any J1 faces it
    facing = math.degrees(math.atan2(wy, wx))
    return abs((q1 - facing + 180.0) % 360.0 - 180.0) < 90.0


def kinematics_refusal(exc: kin.Unreachable | kin.OutOfLimits) -> Refusal:
    """The firmware's text for a typed IK failure."""
    if isinstance(exc, kin.OutOfLimits):
        return Refusal(c.TEXT_OUT_OF_LIMIT)
    return Refusal(c.TEXT_UNREACHABLE)


def lerp(a: Sequence[float], b: Sequence[float], u: float) -> tuple[float, ...]:
    """The point ``u`` of the way from ``a`` to ``b``."""
    return tuple(x + (y - x) * u for x, y in zip(a, b, strict=True))


def vec7(values: Sequence[float]) -> Vec7:
    """The first seven numbers of ``values`` as a joint vector."""
    if type(values) is tuple and len(values) == motion.AXES:
        return axes.vec7(values)  # seven floats: the same tuple (no copy)
    return (
        float(values[0]),
        float(values[1]),
        float(values[2]),
        float(values[3]),
        float(values[4]),
        float(values[5]),
        float(values[6]),
    )


def pose6(values: Sequence[float]) -> Pose:
    """The first six numbers of ``values`` as a pose."""
    return (
        float(values[0]),
        float(values[1]),
        float(values[2]),
        float(values[3]),
        float(values[4]),
        float(values[5]),
    )


def switch_pins(joint: int) -> int:
    """The firmware's axis bit (a..g = J4, J5, J6, rail, J1, J2, J3) of joint ``joint`` (1..6,
    7 = rail); 0 for any other number."""
    if not 1 <= joint <= motion.AXES:
        return 0
    return 1 << motion.LETTER_TO_JOINT.index(joint - 1)


class Geometry:
    """FK, IK and limits of one profile, read from the live ``settings`` mapping."""

    def __init__(self, profile: str, settings: Mapping[int, float]) -> None:
        self.profile = profile
        self.settings = settings
        self._limits: AxisLimits | None = None
        self._limits_key: tuple[float | None, ...] = ()
        self._switch_steps: tuple[tuple[int, int], ...] | None = None
        """:meth:`switch_steps` of ``_limits`` (cleared when the limits are rebuilt)."""

    def dh_values(self) -> tuple[float, float, float, float, float, float]:
        """D1, A1, A2, A3, D4, L (classic: fixed; 2021: ``$29..$34``)."""
        if self.profile == "classic":
            dh = kin.DH_CLASSIC
            return (dh.d1, dh.a1, dh.a2, dh.a3, dh.d4, dh.l)
        s = self.settings
        return (s[29], s[30], s[31], s[32], s[33], s[34])

    def dh(self) -> kin.DH:
        return kin.DH(*self.dh_values())

    def tool(self) -> tuple[float, float, float]:
        """The tool offset (2021 ``$46..$48``)."""
        if self.profile == "classic":
            return (0.0, 0.0, 0.0)
        return (self.settings[46], self.settings[47], self.settings[48])

    def base_offset(self) -> tuple[float, float, float]:
        """The base offset added to absolute ``M20`` targets (2021 ``$41..$43``)."""
        if self.profile == "classic":
            return (0.0, 0.0, 0.0)
        return (self.settings[41], self.settings[42], self.settings[43])

    def fk(self, q: Sequence[float]) -> Pose:
        return pose6(kin.forward(tuple(q[:6]), self.dh(), self.tool()))

    def ik(
        self, pose: Sequence[float], *, check_limits: bool = IK_CHECKS_JOINT_RANGES
    ) -> tuple[float, ...]:
        """Firmware-branch IK, raising :class:`Refusal` with the firmware's text. The oracle
        checks no joint range here: the soft limits (``$20``) or the switches do; a wrist centre
        behind the shoulder is solved mirrored (:func:`shoulder_mirrored_pose`)."""
        dh = self.dh()
        try:
            solved = shoulder_mirrored_pose(pose, dh, self.tool())
            q = tuple(
                kin.inverse(
                    solved,
                    dh,
                    "firmware",
                    tool=self.tool(),
                    limits=kin.JOINT_LIMITS if check_limits else None,
                )
            )
        except (kin.Unreachable, kin.OutOfLimits) as exc:
            raise kinematics_refusal(exc) from None
        except MirobotUsageError:  # a geometry the IK cannot solve at all ($31=0: A2 = 0)
            raise Refusal(c.TEXT_UNREACHABLE) from None  # ASSUMED: the firmware finds no THETA3
        if not _shoulder_front(solved, q[0], dh, self.tool()):
            # the firmware solves the shoulder-front branch only (oracle: X50 Y0 Z100 A0 B0 C0,
            # whose only solutions reach over the back with J1 = 180, has no THETA3)
            raise Refusal(c.TEXT_UNREACHABLE)
        return q

    def limits(self) -> AxisLimits:
        """The planner's axis limits from the current settings (rebuilt when they change)."""
        settings = self.settings
        try:
            key = _limit_settings_of(settings)
        except KeyError:  # a setting missing: read as None, as ``settings.get`` reads it
            key = tuple(map(settings.get, _LIMIT_SETTINGS))
        limits = self._limits
        if limits is None or key != self._limits_key:
            limits = self._limits = AxisLimits.from_settings(settings)
            self._limits_key = key
            self._switch_steps = None
        return limits

    def soft_violation(self, q: Sequence[float]) -> str | None:
        """The firmware letter of the first axis (order a..g) outside its ``$13x/$14x`` range."""
        settings = self.settings
        if settings[20] == 0:
            return None
        try:  # every axis within its range (compared without a Python loop): none is outside
            values = _joints_in_letter_order(q)
            if all(map(operator.le, values, _soft_highs_of(settings))) and all(
                map(operator.le, map(operator.neg, values), _soft_lows_of(settings))
            ):
                return None
        except (KeyError, IndexError):
            pass  # a setting or joint missing: the loop meets it where the firmware order does
        for letter, joint, high, low in _SOFT_LIMIT_AXES:
            value = q[joint]
            if value > settings[high] or value < -settings[low]:
                # the firmware compares float32 numbers (tape scenarios-s4/limit_edges_numbers:
                # X5.0000001 is 5.0 there, within $134=5)
                value = single(value)
                if value > single(settings[high]) or value < -single(settings[low]):
                    return letter
        return None

    def switch_steps(self) -> list[tuple[int, int]]:
        """Per J1..J3, the motor steps (low, high) at and beyond which its switch is closed:
        the first whole steps past the switch positions (``SWITCH_OVERTRAVEL``)."""
        return list(self._switch_table(self.limits()))

    def _switch_table(self, limits: AxisLimits) -> tuple[tuple[int, int], ...]:
        """:meth:`switch_steps` of ``limits`` (the current ones), computed once per limits."""
        table = self._switch_steps
        if table is None:
            table = self._switch_steps = self._switch_steps_of(limits)
        return table

    @staticmethod
    def _switch_steps_of(limits: AxisLimits) -> tuple[tuple[int, int], ...]:
        steps = limits.steps
        out = []
        for j, (lo, hi) in enumerate(HARD_LIMIT_SWITCHES):
            per = steps[j] if steps is not None else 1e6  # an ideal machine: a fine grid
            out.append(
                (
                    math.ceil((lo - SWITCH_OVERTRAVEL) * per) - 1,
                    math.floor((hi + SWITCH_OVERTRAVEL) * per) + 1,
                )
            )
        return tuple(out)

    def _to_steps(self, q: Sequence[float]) -> list[int]:
        limits = self.limits()
        if limits.steps is not None:
            return list(limits.to_steps(vec7(q)))
        return [round(v * 1e6) for v in q[:3]]

    def limit_pins(self, q: Sequence[float]) -> int:
        """The ``Lim`` bits of the J1..J3 switches closed at ``q``."""
        at = self._to_steps(q)
        pins = 0
        for j, (lo, hi) in enumerate(self._switch_table(self.limits())):
            if at[j] <= lo or at[j] >= hi:
                pins |= switch_pins(j + 1)
        return pins

    def switch_crossing(
        self,
        start: Sequence[float],
        end: Sequence[float],
        limits: AxisLimits | None = None,
        steps: tuple[Steps7, Steps7] | None = None,
    ) -> Vec7 | None:
        """Where a joint move from ``start`` to ``end`` stops on a J1..J3 switch (``$21=1``):
        the step event of GRBL's Bresenham line at which the first switch closes, or None.
        ``limits``: :meth:`limits` when the caller has just read them; ``steps``: the ends in
        their whole steps, likewise."""
        if not self.settings[21]:
            return None
        if limits is None:
            limits = self.limits()
        if limits.steps is None:  # an ideal machine: the first switch position on the line
            return self._ideal_crossing(start, end)
        if steps is None:
            steps = limits.to_steps(start), limits.to_steps(end)
        first, last = steps
        table = self._switch_table(limits)
        (lo1, hi1), (lo2, hi2), (lo3, hi3) = table  # J1..J3
        if lo1 < last[0] < hi1 and lo2 < last[1] < hi2 and lo3 < last[2] < hi3:
            return None  # the move ends with every switch open: it closes none on the way
        candidates: list[tuple[int, int]] = []  # (axis, steps to its switch edge)
        for j, (lo, hi) in enumerate(table):
            a, b = first[j], last[j]
            if not lo < a < hi:
                continue  # closed already: no edge while it stays closed
            if b >= hi:
                candidates.append((j, hi - a))
            elif b <= lo:
                candidates.append((j, a - lo))
        if not candidates:
            return None
        delta = [b - a for a, b in zip(first, last, strict=True)]
        events = max(abs(d) for d in delta)
        half = events // 2
        best: int | None = None
        for j, need in candidates:
            # axis j has made (k |d| + half) // events steps after step event k
            k = -((half - need * events) // abs(delta[j]))
            best = k if best is None else min(best, k)
        assert best is not None
        done = [(best * abs(d) + half) // events for d in delta]
        cut = [a + (n if d >= 0 else -n) for a, n, d in zip(first, done, delta, strict=True)]
        return limits.from_steps(cut)

    def _ideal_crossing(self, start: Sequence[float], end: Sequence[float]) -> Vec7 | None:
        best: float | None = None
        for j, (low, high) in enumerate(HARD_LIMIT_SWITCHES):
            lo, hi = low - SWITCH_OVERTRAVEL, high + SWITCH_OVERTRAVEL
            a, b = start[j], end[j]
            if lo < a < hi and not lo < b < hi:
                f = ((hi if b >= hi else lo) - a) / (b - a)
                best = f if best is None else min(best, f)
        return None if best is None else vec7(lerp(start, end, best))

    @staticmethod
    def unwrap(q: Sequence[float], ref: Sequence[float]) -> tuple[float, ...]:
        """Shift J4 and J6 by whole turns to lie nearest to ``ref`` (within their ranges)."""
        out = list(q[:6])
        for j in (3, 5):
            lo, hi = kin.JOINT_LIMITS[j]
            shifted = out[j] + 360.0 * round((ref[j] - out[j]) / 360.0)
            if lo <= shifted <= hi:
                out[j] = shifted
        return tuple(out)
