"""The modal words that decide what a raw motion line means, tracked line by line.

:class:`MotionModes` is what the client knows of the firmware's parser state (``M20``/``M21``,
``G90``/``G91``, the motion code, ``G20``/``G21``); any part may be unknown (``None``), e.g. on
connecting to an arm that another session left in inches; :mod:`~mirobot_async._core.acceptance`
follows it through every line written, checked or not. :class:`Chaining` follows whether each
line still continues from where the lines before it end when they are streamed (the
``M20``/``M21`` restart, see there). Pure module (no numpy): the client imports it without an
envelope.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Final

from mirobot_async._core.line import ParsedLine

__all__ = [
    "HOMED",
    "JOINT_LETTERS",
    "MM_PER_INCH",
    "POWER_ON_FEED",
    "Chaining",
    "LineCheck",
    "LockProbe",
    "MotionModes",
    "line_feed",
    "lock_probe",
    "modes_after",
    "modes_of",
]

POWER_ON_FEED: Final = 200.0
"""The feed rate after power-on and after a reset (GRBL's ``gc_init`` on the Mirobot)."""
MM_PER_INCH: Final = 25.4


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
    feed: float | None = POWER_ON_FEED
    """The feed rate in effect (firmware units: mm or deg per minute; 0 after homing, 200 after
    power-on and a reset): a ``G1``/``G2``/``G3``/``G5`` with feed 0 is refused."""
    inverse_time: bool | None = False
    """``G93`` in effect (every feed move must state F; else ``G94``)."""

    @classmethod
    def unknown(cls) -> MotionModes:
        """Nothing known: every motion line must state M20/M21, G90/G91, G0..G3 and G21, and a
        feed move its F. ASSUMED: not ``G93`` (no Mirobot program uses inverse time, and the
        client's checks refuse it; a line sent unchecked that states it is followed)."""
        return cls(None, None, None, None, None, False)

    def missing(self) -> list[str]:
        """Names of the unknown modes, for a refusal message."""
        names = (
            ("coordinate mode (M20/M21)", self.cartesian),
            ("distance mode (G90/G91)", self.relative),
            ("motion mode (G0/G1/G2/G3)", self.motion),
            ("units (G21/G20)", self.inches),
        )
        return [name for name, value in names if value is None]


HOMED: Final = MotionModes(feed=0.0)
"""The modes after homing: GRBL's ``gc_init`` with feed 0 (a ``G1`` needs an ``F`` then)."""


def modes_of(parsed: ParsedLine, modes: MotionModes) -> MotionModes:
    """The modes in effect for the motion of ``parsed`` (its own modal words applied), as the
    firmware computes them for a line it accepts (the feed rate too)."""
    coordinate = parsed.coordinate_mode
    distance = parsed.distance
    motion = parsed.motion
    units = parsed.units
    cartesian = modes.cartesian if coordinate is None else coordinate == 20
    relative = modes.relative if distance is None else distance == 91
    motion = modes.motion if motion is None else motion
    inches = modes.inches if units is None else units == 20
    feed, inverse_time = line_feed(parsed, modes, inches)
    if (cartesian, relative, motion, inches, feed, inverse_time) == (
        modes.cartesian,
        modes.relative,
        modes.motion,
        modes.inches,
        modes.feed,
        modes.inverse_time,
    ):
        return modes  # the line restates the modes in effect (most lines of a program)
    return MotionModes(cartesian, relative, motion, inches, feed, inverse_time)


def line_feed(
    parsed: ParsedLine, modes: MotionModes, inches: bool | None
) -> tuple[float | None, bool | None]:
    """(feed rate, ``G93`` in effect) for ``parsed`` as GRBL 0.9j computes them, ``inches`` the
    units in effect for it: in ``G93`` a line's feed is its ``F`` or 0; in ``G94`` an ``F``
    (scaled by the units) or the feed in effect, but 0 when the line leaves ``G93`` without an
    ``F`` (and unscaled with one)."""
    g_codes = parsed.g_codes
    inverse = modes.inverse_time
    if 93 in g_codes or 94 in g_codes:
        inverse = 93 in g_codes
    f = parsed.value("F")
    if inverse is True:
        return (0.0 if f is None else f), True
    old = modes.inverse_time
    if old is True:  # leaving G93: no feed carried over
        return (0.0 if f is None else f), inverse
    if f is None:
        return (modes.feed if old is False else None), inverse
    if inches is None:
        return None, inverse
    scaled = f * MM_PER_INCH if inches else f
    return (scaled if old is False or not inches else None), inverse


def modes_after(parsed: ParsedLine, modes: MotionModes) -> MotionModes:
    """The modes after ``parsed`` ran (accepted by the firmware): program end resets some."""
    new = modes_of(parsed, modes)
    if parsed.program_end:  # GRBL: M2/M30 reset the distance mode and make the motion G1
        return replace(new, relative=False, motion=1, inverse_time=False)
    return new


@dataclass(frozen=True, slots=True)
class LockProbe:
    """Lines that ask the firmware whether its axes are locked, moving nothing (see
    :func:`lock_probe`)."""

    line: str
    """A relative joint move of zero length: a locked arm answers it ``Locked status of each
    axis!`` then ``ok`` (its motion dropped); an unlocked one ``ok``, without a motor step."""
    restore: str | None
    """The line that puts back the coordinate and distance modes the probe changed (None: none
    to put back)."""
    after: MotionModes
    """The modes after both lines, accepted: those before, with any unknown part known."""


def lock_probe(modes: MotionModes) -> LockProbe:
    """The lock probe from the parser modes ``modes`` (oracle, both profiles: ``M21 G91 X0``).

    The zero-length move keeps the motion mode when a zero-length move in it is accepted (``G0``,
    or ``G1`` at a known feed rate), else states ``G0`` (``G1`` at feed 0 would be refused as
    ``Undefined feed rate``, arcs and ``G05`` in ``M21`` as ``Unsupported command``); it states
    ``G21`` when the units are unknown. The restore line puts back ``M20`` and ``G90`` (after the
    probe's ``M21 G91``); a mode that was unknown is left known: ``M21``, ``G90``, ``G0``,
    ``G21``. Feed rate and feed mode are not touched."""
    keep_motion = modes.motion == 0 or (
        modes.motion == 1 and modes.inverse_time is False and bool(modes.feed)
    )
    words = ["M21", "G91"]
    if modes.inches is None:
        words.append("G21")
    if not keep_motion:
        words.append("G0")
    back = ["M20"] if modes.cartesian is True else []
    if modes.relative is not True:
        back.append("G90")
    after = replace(
        modes,
        cartesian=modes.cartesian is True,
        relative=modes.relative is True,
        motion=modes.motion if keep_motion else 0,
        inches=modes.inches is True,
    )
    return LockProbe(" ".join([*words, "X0"]), " ".join(back) or None, after)


_Six = tuple[float, float, float, float, float, float]


@dataclass(frozen=True, slots=True)
class LineCheck:
    """The envelope's verdict on a line (:func:`~mirobot_async._safety.prediction.predict`, as
    the client's guard reads it): the new modes and where the arm ends up.

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


# --------------------------------------------------------------------------------------------
# Chaining: does a streamed line still start where the lines before it end?

JOINT_LETTERS: Final = "XYZABCD"
"""The joint-mode axis letters: J1..J6 (``X``..``C``) and the rail (``D``)."""
_WRIST_AND_ARM: Final = frozenset("XYZABC")
_POSE_LETTERS: Final = frozenset("XYZABC")


@dataclass(frozen=True, slots=True)
class Chaining:
    """Whether the firmware's parser position is where the motion queued before a line ends.

    The rule (firmware oracle, classic ``20191228_2``; the emulator models it): **a line that
    carries ``M20`` or ``M21`` first sets the parser's position to the machine position, where
    the arm is at the instant the line is parsed, not where the queued motion ends.** Every
    mode-dependent part of a line, and of the lines after it, is then measured from there.
    ``G90``/``G91``, ``G0``/``G1``, ``G21`` and ``F`` do not do this. Measured, streamed (all
    lines parsed before the arm moved) vs stepped (each line after the arm stopped), J1 in deg:

    - ``M21 G91 G0 X1 F2000`` x4: 1.005 vs 4.019; ``M21 G91 G0 X1`` then ``G91 G0 X1``,
      ``G91 X1``, ``X1``: 4.001 both (the mode stated once chains);
    - ``M21 G90 G0 X10``, ``M21``, ``G91 X1``: 1.005 vs 10.999 (a bare ``M21``, same mode);
    - ``M21 G90 G0 Y20``, ``M21 G90 G0 X10``: J2 0 vs 20.004 (an absolute line takes the
      axes it omits from where the arm is); the rail ``D`` likewise (``D20`` then
      ``M21 G90 G0 X10``: D 0 vs 20);
    - absolute lines that give every axis (``M21 G90 G0 X.. Y.. Z.. A.. B.. C..``, and classic
      ``M20 G90 G0|G1 X.. Y.. Z.. A.. B.. C..``, also from a different wrist J4/J6) end at the
      same place both ways;
    - ``M20 G91 G0 X5`` x3 and ``M20 G91 G1``: the Cartesian increments add to the pose of where
      the arm is (X 207.005 vs 217.006); ``M20 G90 G0 Z120`` after a full pose: the omitted
      X, Y, A, B, C come from there too;
    - the restart is permanent: ``M21 G90 G0 X30``, ``M20``, ``G4 P0``, ``G91 X1`` ends near
      J1 0 (vs 29.861); ``G4 P0`` before the mode word avoids it (the dwell is answered once
      the planner is empty: the mode word is then parsed at rest).

    So a line is judged by the joints it *reads* from the parser: every joint it does not set
    to an absolute value (a relative line adds to the parser and keeps the axes it omits where
    the parser has them: ``M21 G90 G0 X5``, ``M21 G91 G0 Y1`` streamed ends at J1 0, not 5.006;
    a whole ``M20`` pose, then ``M21 G91 G0 D5``: every joint back to 0), every pose
    coordinate of a Cartesian line that does not give all six, and on the 2021 firmware the
    start of an ``M20`` ``G1``/``G2``/``G3``/``G5`` path, which is cut from
    the parser's pose. Reading a :attr:`stale` joint makes the streamed program end elsewhere
    than the stepped one. ``moving`` joints become stale when a mode word is parsed.
    """

    moving: frozenset[str] = frozenset()
    """Joint letters (:data:`JOINT_LETTERS`) that motion written before may still move."""
    stale: frozenset[str] = frozenset()
    """Joint letters whose parser value is where the arm was when :attr:`resync` was parsed."""
    resync: str | None = None
    """The line whose ``M20``/``M21`` made :attr:`stale` (as written)."""
    refused: bool = False
    """:attr:`resync` is a motion line the firmware refused ("ok" but dropped): it moved the
    parser's position, not the arm (oracle: locked ``G91 X10``, ``M50``, ``G91 X1`` -> 10.999)."""

    def at_rest(self) -> Chaining:
        """The arm stopped with nothing queued (a ``G4`` answered, a status at rest with nothing
        in flight): a mode word now restarts from where the motion ended. Stale joints stay."""
        return replace(self, moving=frozenset())

    def after_refusal(self, parsed: ParsedLine) -> Chaining:
        """``parsed`` was refused ("ok" but dropped): the joints it would have moved are where
        the parser, not the arm, went (any mode: the modes it ran in are not known here)."""
        coordinate = parsed.coordinate_mode
        moved = _moves(parsed, None if coordinate is None else coordinate == 20)
        if not moved:
            return self
        text = parsed.source.strip() or parsed.text
        return replace(self, stale=self.stale | moved, resync=text, refused=True)

    def moved_anything(self) -> Chaining:
        """A line of unknown fate (its reply was lost) may have queued motion of any joint."""
        return replace(self, moving=frozenset(JOINT_LETTERS))

    def problem(
        self, parsed: ParsedLine, modes: MotionModes, firmware: str | None = None
    ) -> str | None:
        """Why ``parsed``, written now (after the modes ``modes``), would end elsewhere when
        streamed than when sent after the arm stopped (or than intended, after a refused line),
        with the fix; ``None`` when it would not."""
        stale = self._stale_at(parsed)
        if not stale:
            return None
        read = _reads(parsed, *_line_modes(parsed, modes), firmware) & stale
        if not read:
            return None
        joints = ", ".join(_joint_name(k) for k in JOINT_LETTERS if k in read)
        word = f"M{parsed.coordinate_mode}" if parsed.coordinate_mode is not None else None
        if word is not None and parsed.coordinate_mode is not None and self.moving & read:
            return (
                f"{word} makes the firmware restart this line from where the arm is when it "
                f"reads the line, not from where the motion queued before it ends ({joints} "
                f"may still be moving): streamed, it ends elsewhere than sent after the arm "
                f"stopped. State {word} once at the top and leave it out of this line, or put "
                "G4 P0 before it (the arm stops first)"
            )
        source = self.resync or "an earlier M20/M21 line"
        if self.refused:
            return (
                f"this line takes {joints} from where the refused line {source!r} left the "
                "firmware's parser, not from where the arm is: it ends elsewhere than "
                "intended. Wait for the arm to stop and state the mode again (M21 or M20: it "
                "restarts from where the arm is)"
            )
        return (
            f"this line takes {joints} from where the arm was when {source!r} was read (its "
            "M20/M21 restarts from where the arm is, not from where the motion queued before "
            "it ends): streamed, it ends elsewhere than sent after the arm stopped. State the "
            f"mode once at the top and leave it out of {source!r}, or put G4 P0 before it"
        )

    def needs_restart(
        self, parsed: ParsedLine, modes: MotionModes, firmware: str | None = None
    ) -> bool:
        """``parsed`` (without a mode word) reads a joint the parser has elsewhere: a mode word
        on it, parsed at rest, would set the parser to where the arm is first."""
        if not self.stale:
            return False
        return bool(_reads(parsed, *_line_modes(parsed, modes), firmware) & self.stale)

    def _stale_at(self, parsed: ParsedLine) -> frozenset[str]:
        """The stale joints while ``parsed`` is executed (its own mode word restarts first)."""
        if parsed.kind == "gcode" and parsed.coordinate_mode is not None:
            return self.moving
        return self.stale

    def after(
        self, parsed: ParsedLine, modes: MotionModes, firmware: str | None = None
    ) -> Chaining:
        """The chaining after ``parsed`` was written (``modes``: before it). Homing and a reset
        (:class:`Chaining` ``()``) leave nothing stale or moving; a dwell waits for the planner."""
        if parsed.is_homing:
            return Chaining()
        if parsed.kind != "gcode" or parsed.syntax_error is not None:
            if parsed.dollar is not None and parsed.dollar.kind in ("zero", "jog", "unknown"):
                return replace(self, moving=self.moving | _WRIST_AND_ARM)
            return self
        stale, resync, refused = self.stale, self.resync, self.refused
        if parsed.coordinate_mode is not None:
            stale, resync, refused = self.moving, parsed.source.strip() or parsed.text, False
        moving = _NONE if 4 in parsed.g_codes else self.moving
        if parsed.axis_letters:
            cartesian, relative, motion = _line_modes(parsed, modes)
            # reported once: what the line read is set by it (as the firmware does, from there on)
            if stale:
                stale = (
                    stale
                    - _reads(parsed, cartesian, relative, motion, firmware)
                    - _writes(parsed, cartesian, relative)
                )
            moving = moving | _moves(parsed, cartesian)
        if not stale:
            resync, refused = None, False
        if (
            moving == self.moving
            and stale == self.stale
            and resync == self.resync
            and refused == self.refused
        ):
            return self  # the same value (most lines of a program change nothing here)
        return Chaining(moving, stale, resync, refused)


def _joint_name(letter: str) -> str:
    return "the rail" if letter == "D" else f"J{JOINT_LETTERS.index(letter) + 1}"


_NONE: Final = frozenset[str]()
_JOINTS: Final = frozenset(JOINT_LETTERS)
_RAIL: Final = frozenset("D")


def _line_modes(
    parsed: ParsedLine, modes: MotionModes
) -> tuple[bool | None, bool | None, int | None]:
    """(Cartesian, relative, motion code) in effect for the line: :func:`modes_of`, without
    building a :class:`MotionModes`."""
    coordinate, distance, motion = parsed.coordinate_mode, parsed.distance, parsed.motion
    return (
        modes.cartesian if coordinate is None else coordinate == 20,
        modes.relative if distance is None else distance == 91,
        modes.motion if motion is None else motion,
    )


def _either(mode: bool | None) -> tuple[bool, ...]:
    """The values a mode may have: both when it is unknown."""
    return (True, False) if mode is None else (mode,)


def _reads(
    parsed: ParsedLine,
    cartesian: bool | None,
    relative: bool | None,
    motion: int | None,
    firmware: str | None,
) -> frozenset[str]:
    """The joints whose parser value decides where ``parsed`` ends (see :class:`Chaining`);
    the modes are those it runs in (:func:`_line_modes`)."""
    if parsed.kind != "gcode" or parsed.syntax_error is not None:
        return _NONE
    axes = parsed.axis_letters
    if not axes:
        return _NONE
    if relative is True:  # the words add to the parser, the omitted axes stay there
        return _JOINTS
    if cartesian is False and relative is False:
        return _JOINTS - axes
    read: set[str] = set()
    for frame in _either(cartesian):
        for adds in _either(relative):
            if adds:
                read |= _JOINTS
                continue
            if not frame:
                read |= _JOINTS - axes
                continue
            read |= _RAIL - axes
            path = firmware != "classic" and motion != 0
            if axes & _POSE_LETTERS != _POSE_LETTERS or path:
                read |= _WRIST_AND_ARM
    return frozenset(read)


def _writes(parsed: ParsedLine, cartesian: bool | None, relative: bool | None) -> frozenset[str]:
    """The joints an absolute line sets regardless of the parser (given axes; a full pose);
    the modes as in :func:`_reads`."""
    if parsed.kind != "gcode" or parsed.syntax_error is not None:
        return _NONE
    if relative is not False or cartesian is None:
        return _NONE
    axes = parsed.axis_letters
    if not cartesian:
        return axes
    written = _RAIL & axes
    if axes >= _POSE_LETTERS:
        written |= _WRIST_AND_ARM
    return written


def _moves(parsed: ParsedLine, cartesian: bool | None) -> frozenset[str]:
    """The joints the line's motion may move (conservative); ``cartesian`` as in
    :func:`_reads`."""
    axes = parsed.axis_letters
    if not axes:
        return _NONE
    if cartesian is False:
        return axes
    moved = (_RAIL & axes) | (_WRIST_AND_ARM if axes & _POSE_LETTERS else _NONE)
    return moved if cartesian else moved | axes
