"""STEP 3 of GRBL 0.9j's parser: a scanned line checked against the modal state, its target
computed; the result (:class:`CheckedLine`) or the GRBL status of the first error."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

from ..motion import Vec7
from . import _codes as c
from ._geometry import Geometry, vec7
from ._modal import ModalState
from ._moves import Arc
from ._offsets import WorkOffsets
from ._scanner import AXIS_WORDS, NONMODAL_AXIS_COMMANDS, GBlock

ARC_ANGULAR_TRAVEL_EPSILON: Final = 5e-7  # GRBL 0.9j config.h
MAX_LINE_NUMBER: Final = 9999999  # GRBL 0.9j gcode.c
MM_PER_INCH: Final = 25.4


@dataclass
class CheckedLine:
    """A valid line: the modal values it sets and where its motion goes."""

    block: GBlock
    origin: Vec7
    """The parser's joints the line starts from."""
    cart: bool
    motion_mode: int
    distance: int
    units: int
    feed_mode: int
    feed: float
    pump: float
    valve: float
    base: tuple[float, ...]
    """Where the target is measured from: joints, or the commanded pose and the rail."""
    target: Vec7
    axis_command: bool
    arc: Arc | None


_VALUE_WORDS: Final = frozenset("NFSTE")
_AXIS_WORD_SET: Final = frozenset(AXIS_WORDS)
_VALUE_AND_AXIS_WORDS: Final = _VALUE_WORDS | _AXIS_WORD_SET
_P_WORD: Final = frozenset("P")
_L_AND_P_WORDS: Final = frozenset("LP")
_AXIS_INDEX: Final = {letter: k for k, letter in enumerate(AXIS_WORDS)}


def check_block(
    g: GBlock, modal: ModalState, q0: Vec7, geometry: Geometry, work: WorkOffsets
) -> CheckedLine | int:
    """GRBL's error checks of ``g`` in the order of its parser; ``q0`` the parser's joints,
    ``work`` the stored work offsets."""
    words = g.words
    cart = modal.cart_mode if g.coord_mode is None else g.coord_mode == 20
    motion_mode = modal.motion if g.motion is None else g.motion
    distance = modal.distance if g.distance is None else g.distance
    units = modal.units if g.units is None else g.units
    feed_mode = modal.feed_mode if g.feed_mode is None else g.feed_mode
    axis_letters = list(filter(words.__contains__, AXIS_WORDS))  # in AXIS_WORDS order
    nonmodal_axes = g.nonmodal in NONMODAL_AXIS_COMMANDS  # the axis words are G10/28/30/92's
    axis_command = not nonmodal_axes and (g.axis_command or bool(axis_letters))
    used: frozenset[str] = _VALUE_AND_AXIS_WORDS if nonmodal_axes else _VALUE_WORDS
    if g.tool_length == 431:
        return c.INVALID_TOOL_LENGTH_AXIS  # oracle: G43.1 always (no axis fits the Mirobot)

    # [non-specific] line number
    if "N" in words and words["N"] > MAX_LINE_NUMBER:
        return c.INVALID_LINE_NUMBER
    # [2, 3] feed rate mode and feed rate
    if feed_mode == 93:
        if axis_command and "F" not in words:
            return c.UNDEFINED_FEED_RATE
        feed = words.get("F", 0.0)
    elif modal.feed_mode == 94:
        scale_f = MM_PER_INCH if units == 20 else 1.0
        feed = words["F"] * scale_f if "F" in words else modal.feed
    else:
        feed = words.get("F", 0.0)
    pump = words.get("S", modal.pump_pwm)
    valve = words.get("E", modal.valve_pwm)
    nonmodal = g.nonmodal
    if nonmodal is not None:
        # [10] dwell
        if nonmodal == 4:
            if "P" not in words:
                return c.VALUE_WORD_MISSING
            used = used | _P_WORD
        # [19] G10 and G92 need their words
        if nonmodal in (10, 92) and not axis_letters:
            return c.NO_AXIS_WORDS  # oracle: 'G10' alone -> 26, 'G10 C6' -> 28
        if nonmodal == 10:
            if "L" not in words or "P" not in words:
                return c.VALUE_WORD_MISSING
            if words["L"] not in (2.0, 20.0) or words["P"] not in range(7):
                return c.UNSUPPORTED_COMMAND
            used = used | _L_AND_P_WORDS
    # [12] units; [19] target (absolute targets add the work offsets, except with G53)
    scale = MM_PER_INCH if units == 20 else 1.0
    base: tuple[float, ...]
    if cart:
        fresh = g.coord_mode == 20 or not modal.cart_mode
        base_pose = geometry.fk(q0) if fresh else modal.cart
        base = (*base_pose, q0[6])
        offset: tuple[float, ...] = (*geometry.base_offset(), 0.0, 0.0, 0.0, 0.0)
    else:
        base = q0
        offset = (0.0,) * 7
    system: Vec7 | None = None
    g92: Vec7 | None = None
    if axis_letters and nonmodal != 53:
        system = work.systems[modal.coord_select if g.coord_select is None else g.coord_select]
        g92 = modal.g92
    target_list = list(base)
    for letter in axis_letters:  # the axis words present, in AXIS_WORDS order
        k = _AXIS_INDEX[letter]
        value = words[letter] * scale
        if distance != 90:
            target_list[k] = value + base[k]
        elif system is None or g92 is None:  # G53: no work offsets
            target_list[k] = value + offset[k]
        else:  # this axis's work offsets only (each axis's sum is the same)
            target_list[k] = value + (offset[k] + system[k] + g92[k])
    target = vec7(tuple(target_list))
    # [19] G53
    if nonmodal == 53 and motion_mode not in (0, 1):
        return c.G53_INVALID_MOTION_MODE
    # [20] motion modes
    arc: Arc | None = None
    if motion_mode == 80:
        if axis_letters and not nonmodal_axes:  # oracle: 'B-5 G54 G92 G18 E50' in G80 -> ok
            return c.AXIS_WORDS_EXIST
    elif axis_command:
        if motion_mode in (2, 3) and geometry.profile == "classic":
            plane = modal.plane if g.plane is None else g.plane
            return classic_arc_status(words, axis_letters, feed, plane)
        if motion_mode in (2, 3, 5) and not cart:
            return c.UNSUPPORTED_COMMAND  # ASSUMED: no arcs / gates in joint mode
        if motion_mode == 0:
            axis_command = bool(axis_letters)
        else:
            if feed == 0.0:
                return c.UNDEFINED_FEED_RATE
            if motion_mode in (1, 5):
                axis_command = bool(axis_letters)
            else:
                result = check_arc(motion_mode, words, axis_letters, base, target, scale)
                if isinstance(result, int):
                    return result
                arc, arc_words = result
                used = used | arc_words
    if axis_command:
        used = _VALUE_AND_AXIS_WORDS if used is _VALUE_WORDS else used | _AXIS_WORD_SET
    if not used.issuperset(words):  # a word no command used
        return c.UNUSED_WORDS
    return CheckedLine(
        g, q0, cart, motion_mode, distance, units, feed_mode, feed, pump, valve,
        base, target, axis_command, arc,
    )  # fmt: skip


CLASSIC_ARC_PLANES: Final = {17: "AB", 18: "CA", 19: "BC"}
"""The classic firmware's arc planes: GRBL's axes 0, 1, 2 are its a, b, c = J4, J5, J6."""


def classic_arc_status(
    words: dict[str, float], axis_letters: list[str], feed: float, plane: int
) -> int:
    """The classic firmware's reply to ``G2``/``G3`` (oracle: ``G2 X210 Y10 R10 F1000`` ->
    ``Invalid gcode ID:32``, X and Y are not its arc plane). ASSUMED: an arc in its real plane
    (wrist joints) is refused as unsupported."""
    if feed == 0.0:
        return c.UNDEFINED_FEED_RATE
    if not axis_letters:
        return c.NO_AXIS_WORDS  # oracle: 'M20 G2' -> 'Invalid gcode ID:26'
    if not any(letter in words for letter in CLASSIC_ARC_PLANES[plane]):
        return c.NO_AXIS_WORDS_IN_PLANE
    return c.UNSUPPORTED_COMMAND


def check_arc(
    motion_mode: int,
    words: dict[str, float],
    axis_letters: list[str],
    base: Sequence[float],
    target: Vec7,
    scale: float,
) -> tuple[Arc, set[str]] | int:
    """GRBL's G2/G3 checks in the XY plane of the commanded pose; the arc or a status."""
    if not axis_letters:
        return c.NO_AXIS_WORDS
    if "X" not in words and "Y" not in words:
        return c.NO_AXIS_WORDS_IN_PLANE
    x0, y0 = base[0], base[1]
    x = target[0] - x0
    y = target[1] - y0
    if "R" in words:
        if x == 0.0 and y == 0.0:
            return c.INVALID_TARGET
        r = words["R"] * scale
        h2 = 4.0 * r * r - x * x - y * y
        if h2 < 0:
            return c.ARC_RADIUS_ERROR
        h_x2_div_d = -math.sqrt(h2) / math.hypot(x, y)
        if motion_mode == 3:
            h_x2_div_d = -h_x2_div_d
        if r < 0:
            h_x2_div_d = -h_x2_div_d
            r = -r
        i_off = 0.5 * (x - y * h_x2_div_d)
        j_off = 0.5 * (y + x * h_x2_div_d)
        used = {"R"}
    else:
        if "I" not in words and "J" not in words:
            return c.NO_OFFSETS_IN_PLANE
        i_off = words.get("I", 0.0) * scale
        j_off = words.get("J", 0.0) * scale
        target_r = math.hypot(x - i_off, y - j_off)
        r = math.hypot(i_off, j_off)
        delta_r = abs(target_r - r)
        if delta_r > 0.005 and (delta_r > 0.5 or delta_r > 0.001 * r):
            return c.INVALID_TARGET
        if r == 0.0:
            return c.INVALID_TARGET
        used = {"I", "J", "K"} & set(words)
    rx0, ry0 = -i_off, -j_off  # centre -> start
    rtx, rty = x - i_off, y - j_off  # centre -> end
    travel = math.atan2(rx0 * rty - ry0 * rtx, rx0 * rtx + ry0 * rty)
    if motion_mode == 2:
        if travel >= -ARC_ANGULAR_TRAVEL_EPSILON:
            travel -= 2.0 * math.pi
    elif travel <= ARC_ANGULAR_TRAVEL_EPSILON:
        travel += 2.0 * math.pi
    arc = Arc(x0 + i_off, y0 + j_off, r, math.atan2(ry0, rx0), travel)
    return arc, used
