"""The modal words that decide what a raw motion line means, tracked line by line.

:class:`MotionModes` is what the client knows of the firmware's parser state (``M20``/``M21``,
``G90``/``G91``, the motion code, ``G20``/``G21``); any part may be unknown (``None``), e.g. on
connecting to an arm that another session left in inches. :func:`update_modes` follows every line
written, checked or not. Pure module (no numpy): the client imports it without an envelope.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from mirobot_async._core.line import ParsedLine, parse_line

__all__ = ["LineCheck", "MotionModes", "modes_after", "modes_of", "update_modes"]


@dataclass(frozen=True, slots=True)
class MotionModes:
    """The modal words that decide what a raw motion line means (power-on defaults).

    ``None`` means unknown (:meth:`unknown`, e.g. when connecting to an arm already in use): a
    motion line that relies on an unknown mode is refused until the mode is stated again.
    Reset it (``MotionModes()``) after a ``%`` reset, a reset banner and homing; ``cartesian``
    may also be taken from a status report's ``Motion_MODE`` (1 = M20).
    """

    cartesian: bool | None = False
    """``M20`` in effect (else ``M21``, joint mode)."""
    relative: bool | None = False
    """``G91`` in effect (else ``G90``)."""
    motion: int | None = 0
    """The motion code in effect: 0, 1, 2, 3 (or 5, the 2021 jump; 80, motion cancelled)."""
    inches: bool | None = False
    """``G20`` in effect (every axis word and F in inches; else ``G21``, mm)."""

    @classmethod
    def unknown(cls) -> MotionModes:
        """Nothing known: every motion line must state M20/M21, G90/G91, G0..G3 and G21."""
        return cls(None, None, None, None)

    def missing(self) -> list[str]:
        """Names of the unknown modes, for a refusal message."""
        names = (
            ("coordinate mode (M20/M21)", self.cartesian),
            ("distance mode (G90/G91)", self.relative),
            ("motion mode (G0/G1/G2/G3)", self.motion),
            ("units (G21/G20)", self.inches),
        )
        return [name for name, value in names if value is None]


def modes_of(parsed: ParsedLine, modes: MotionModes) -> MotionModes:
    """The modes in effect for the motion of ``parsed`` (its own modal words applied)."""
    coordinate = parsed.coordinate_mode
    distance = parsed.distance
    motion = parsed.motion
    units = parsed.units
    return MotionModes(
        modes.cartesian if coordinate is None else coordinate == 20,
        modes.relative if distance is None else distance == 91,
        modes.motion if motion is None else motion,
        modes.inches if units is None else units == 20,
    )


def modes_after(parsed: ParsedLine, modes: MotionModes) -> MotionModes:
    """The modes after ``parsed`` ran (accepted by the firmware): program end resets some."""
    new = modes_of(parsed, modes)
    if parsed.program_end:  # GRBL: M2/M30 reset the distance mode and make the motion G1
        return replace(new, relative=False, motion=1)
    return new


def _group_conflict(parsed: ParsedLine) -> bool:
    """Two words of one modal group (motion, distance, units, coordinate mode) in the line."""
    groups = (
        frozenset({0, 1, 2, 3, 5, 80}),
        frozenset({90, 91}),
        frozenset({20, 21}),
    )
    g_codes = parsed.g_codes
    if any(sum(code in group for code in g_codes) > 1 for group in groups):
        return True
    return sum(code in (20, 21) for code in parsed.m_codes) > 1


def update_modes(line: str | bytes | ParsedLine, modes: MotionModes) -> MotionModes:
    """The modes after ``line`` is executed, without any envelope check; never raises.

    For every line the client sends (checked or not). Homing resets the modes. A line whose
    words are odd (numbers the firmware reads differently, refused forms) makes the modes it
    touches unknown, since the firmware may have acted on part of it.
    """
    parsed = line if isinstance(line, ParsedLine) else parse_line(line)
    if parsed.is_homing:
        return MotionModes()
    if parsed.kind != "gcode":
        if parsed.dollar is not None and parsed.dollar.kind in ("startup", "restore", "unknown"):
            return MotionModes.unknown()
        return modes
    if parsed.syntax_error is not None:
        return modes
    if parsed.has_odd_numbers or parsed.repeated:
        return MotionModes.unknown()
    if parsed.coordinate_conflict is not None or _group_conflict(parsed):
        # the firmware refuses the line; an M20/M21 in it may take effect all the same
        return modes if parsed.coordinate_mode is None else replace(modes, cartesian=None)
    return modes_after(parsed, modes)


_Six = tuple[float, float, float, float, float, float]


@dataclass(frozen=True, slots=True)
class LineCheck:
    """The result of :meth:`Envelope.check_line`: the new modes and where the arm ends up.

    ``joints``/``pose``/``rail`` are the target when computable, else the current values passed in
    (for lines that do not move) or ``None`` (unknown, e.g. after homing). ``base_offset`` is
    the ``$41..$43`` base offset after the line (``None``: unknown).
    """

    modes: MotionModes
    moves: bool
    joints: _Six | None
    pose: _Six | None
    rail: float | None
    base_offset: tuple[float, float, float] | None = (0.0, 0.0, 0.0)
