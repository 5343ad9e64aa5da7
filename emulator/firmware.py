"""The pure firmware model of the virtual Mirobot: bytes in, bytes out, an explicit clock.

:class:`Firmware` behaves like the arm's GRBL 0.9j based firmware (PROTOCOL.md is the reference
for every byte; where PROTOCOL.md is silent, the vendor's open firmware source and GRBL 0.9j
decide). No asyncio, no OS calls: the host feeds bytes with :meth:`Firmware.receive`, runs the
simulated clock with :meth:`Firmware.advance` and collects what the robot prints with
:meth:`Firmware.read_output`. Motion timing is :mod:`mirobot_emulator.motion`; kinematics are
:mod:`mirobot_async.kinematics` (the only module of the client it uses).

What is modelled
----------------
* Line discipline (PROTOCOL 2): ``\\r`` or ``\\n`` end a line, every empty line gets ``ok``, bytes
  ``<= 0x20`` and ``/`` (GRBL's unsupported block delete) are dropped, letters upper-cased,
  ``(...)`` and ``;`` comments removed, a line longer than 80 bytes after filtering gets one
  ``Line overflow`` error; a 128-byte receive ring whose overflow bytes are lost
  (:attr:`Firmware.rx_lost` counts them); the 18-block planner with its back-pressure.
* Realtime bytes ``?`` ``!`` ``~`` ``%`` anywhere in the stream (PROTOCOL 3); ``0x18`` is an
  ordinary (dropped) byte.
* The G-code grammar with GRBL 0.9j's modal groups and checks (PROTOCOL 6), the error texts of
  PROTOCOL 4.1 for both profiles, the Mirobot texts of PROTOCOL 4.3, settings and ``$$``,
  ``$G``, ``$#``, ``$I``, ``$N``, ``$C``, ``$X``, ``$RST``, homing, the status report (PROTOCOL 5),
  power-on lock, Alarm, soft and hard limits, feed hold, soft reset, the two profiles.

Not modelled
------------
GRBL's look-ahead and step quantisation (see :mod:`mirobot_emulator.motion`); work coordinate
systems, ``G10``/``G28``/``G30``/``G92``, tool length offsets (``G43.1``/``G49``) and probing
(``G38.x``): they answer ``Unsupported command`` (GRBL would accept them; no Mirobot client sends
them); ``G54..G59`` are accepted with all offsets zero; stored startup lines (``$N0=``) are kept
but never executed; the limit-switch physics of homing (homing cannot fail except by ``%``);
``$50`` tool presets; the ``$36`` point count (lines are exact); EEPROM persistence (settings
live as long as the object); the 500 ms stall GRBL adds after printing an alarm; the firmware
bugs visible in the open source (a stale modal-group bit for ``M3``/``M20``, parser positions
updated by refused moves, ``M20``/``M50`` executed by lines that then fail).

ASSUMED points implemented (each in one constant or function, named here)
------------------------------------------------------------------------
* ``RX_BUFFER_SIZE`` = 128 usable bytes (GRBL's ring holds one less; PROTOCOL says 128).
* ``LINE_BUFFER_SIZE``: 80 filtered bytes are accepted, the 81st makes the line an overflow; the
  whole line (up to its end) then gets a single error (GRBL 0.9 would parse the rest as a new line;
  the vectors show one reply).
* ``_error_line``: 2021 errors are ``Error, E1nn,<text>`` with ``nn`` the GRBL 0.9 status number,
  except the manual's ``E113 Undefined feed rate`` (GRBL 22) and ``E116 Arc radius error``
  (GRBL 34); every other text is the classic one.
* ``_refusal``: the four "ok but dropped" texts (locked, soft limit, out of workspace, angle out of
  limit) are printed as an empty line then the text (as the open firmware's ``"\\r\\n..."``), then
  ``ok``.
* ``_power_on_condition``: after power-on **and after every** ``%`` the axes are locked
  (PROTOCOL 6.1); the 2021 profile is then also in ``Alarm`` (its power-on state), the classic
  profile only when the reset interrupted motion.
* ``_m50_allowed_in_alarm``: on 2021 a bare ``M50`` line is accepted in ``Alarm`` and clears it
  (the 2021 manual unlocks with ``M50`` right after power-on, when the arm is in ``Alarm``);
  on classic ``M50`` in ``Alarm`` gets ``error: Alarm lock`` like any G-code.
* Only a valid line has effects: ``M20``/``M21``/``M50`` act and print only when the whole line
  is accepted (so ``M20 G1 X200`` with feed 0 prints just the error, as in the vectors).
* ``M20`` re-reads the Cartesian pose from the FK of the planned joints (the end of queued
  motion); ``M20`` ``G91`` increments add to the last *commanded* pose (as the firmware does).
* The 2021 base offset ``$41..$43`` is added to absolute ``M20`` X/Y/Z targets (open firmware);
  the status report prints the pose in the robot frame (FK with the ``$46..$48`` tool offset).
* IK uses the firmware branch and the factory joint ranges (``kinematics.JOINT_LIMITS``), as the
  firmware's IK has fixed ranges; the soft limits (``$20``) use the ``$130..$146`` settings.
* ``M20 G1`` lines, ``G2``/``G3`` arcs and ``G05`` are checked sample by sample (every 2 mm /
  2 degrees) before any motion; J4 and J6 are kept continuous along a path (they may pass
  +-180 degrees) where the firmware's per-segment IK would spin them; if the current joints are
  not the firmware IK branch of the current pose, a rapid joint move to it comes first.
* ``HARD_LIMIT_SWITCHES``: J1..J3 switches sit at the factory range ends; a joint-space move that
  would carry J1..J3 out of them (``$21=1``; possible with ``$20=0`` or widened ``$13x``/``$14x``)
  is cut at the switch: the arm stops there and ``ALARM: Hard limit``, ``[Reset to continue]``
  are printed at that instant; nothing but ``%`` is processed until reset, not even ``?``
  (``STATUS_DURING_CRITICAL_ALARM``, as GRBL 0.9j). Cartesian moves cannot reach a switch: their
  IK refuses angles outside those ranges.
  :meth:`Firmware.trigger_hard_limit` raises the same alarm at once in any state (fault
  injection).
* 2021 ``G2``/``G3`` arcs are always in the XY plane (2021 manual), Z and orientation move
  linearly (helix); ``G2``/``G3``/``G05`` in ``M21`` (joint) mode answer ``Unsupported command``.
  An arc whose end has the start's X and Y answers ``Invalid gcode ID:33``.
* ``G05`` (2021 gate move): straight up to ``max(z_start, z_end) + $49``, across, straight down,
  all at the feed rate F (so F is required, E113 otherwise); orientation and rail change on the
  way across.
* ``$M`` (2021): rapid joint move of J1..J6 to 0 (rail unchanged), needs Idle (``Not idle``),
  refuses in ``Alarm`` (``Alarm lock``) and prints ``Locked status`` while locked.
* Homing: ``homing_seconds`` (default ``DEFAULT_HOMING_SECONDS``) is the switch search of ``$H``;
  ``$HH`` and ``$HE`` are sequential (:mod:`mirobot_emulator.motion`); ``$H0`` (arm + rail)
  searches ``HOMING_RAIL_FACTOR`` times as long, ``$H1..$H7`` (one axis; 7 = rail) for
  ``HOMING_SINGLE_AXIS_FACTOR`` of it. PROTOCOL's ``$H0`` = arm + rail and ``$H7`` = rail only
  (the 2021 manual calls ``$H7`` "arm, then axis 7"). Any homing unlocks and re-initialises the
  parser (feed 0, ``M21``, PWM 0) when the search ends; ``$H`` and ``$HH`` leave the rail alone.
  The classic profile accepts any ``$H...`` as ``$H`` except ``$HH`` (open firmware). Classic
  prints ``""``, ``Free memory: 2036`` at the start; 2021 prints only its final line (vectors).
* ``G4`` waits for the planner to empty, then dwells (a planner block, state ``Run``); its ``ok``
  comes after the dwell (GRBL). ``M2``/``M30`` wait for the planner, reset the modal state as GRBL
  does and print ``[Pgm End]``; ``M0`` waits, then holds; its ``ok`` follows the ``~``.
* A soft reset during a dwell or a completed feed hold is not "during motion" (no alarm), as in
  GRBL; during homing it is ``ALARM: Homing fail``.
* The banner's last line is followed by ``['$H'|'$X' to unlock]`` whenever the state is Alarm
  (GRBL), so always on 2021; the banner's numbers are the integer parts (truncated) of the DH
  settings, the base offsets and the FK at zero joints (with the tool offset).
* ``_fmt``: status reports follow the ``$10`` mask like the open firmware (bit 0 angles and pose,
  bit 5 the PWMs, bit 6 ``Motion_MODE``, bits 2/3/4 ``Buf``/``RX``/``Lim``); a number that would
  print as ``-0.000`` prints ``0.000`` (the vectors never show ``-0.000``).
* A line with both a refusal (IK) and a lock prints only the first refusal (IK first, as the
  firmware computes IK before its lock check).

Taken from GRBL 0.9j / the open firmware where PROTOCOL.md is silent
--------------------------------------------------------------------
* ``$X`` prints ``[Caution: Unlocked]`` only in Alarm (otherwise just ``ok``).
* ``$`` commands other than ``$$``, ``$G``, ``$C``, ``$X`` need Idle or Alarm: ``$H`` or a
  setting sent while the arm moves answers ``Not idle``; ``$$`` too while moving or held.
* ``!`` while idle enters ``Hold`` as well; while held, received lines wait until ``~``.
* ``Pump PWM`` / ``Valve PWM`` are the last ``S`` / ``E`` words (with or without ``M3``/``M4``;
  ``M5`` does not clear them); a reset and a homing set both to 0 (GRBL's ``gc_init``).
* ``Soft limit triggered:<axis>`` names the first offending axis in the firmware's order
  a..g = J4, J5, J6, D, J1, J2, J3 (letters A B C D X Y Z).
* On 2021 every line with an ``M20``/``M21`` word prints its ``Info`` line (the firmware runs
  ``M20``/``M21`` each time); classic prints nothing for them.
* ``$20=1`` needs ``$22=1`` (``Homing not enabled``); ``$22=0`` turns soft limits off.
* Error texts of GRBL 0.9j beyond PROTOCOL 4.1: ``Value < 3 usec`` (``$0``), ``Homing not
  enabled``, ``EEPROM read fail. Using defaults``.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Final

import numpy as np

from mirobot_async import kinematics as kin

from . import motion
from . import settings as cfg
from .motion import AxisLimits, Block, Planner, Vec7

__all__ = [
    "DEFAULT_HOMING_SECONDS",
    "HARD_LIMIT_SWITCHES",
    "LINE_BUFFER_SIZE",
    "PROFILES",
    "RX_BUFFER_SIZE",
    "Firmware",
    "error_text",
]

PROFILES: Final = ("classic", "2021")

RX_BUFFER_SIZE: Final = 128
"""Receive ring in bytes (ASSUMED: all 128 usable)."""

LINE_BUFFER_SIZE: Final = 80
"""Longest accepted line after filtering, in bytes (ASSUMED: 80 accepted, 81 overflow)."""

DEFAULT_HOMING_SECONDS: Final = 10.0
"""Switch search of ``$H`` when the constructor is not told otherwise (PROTOCOL 9)."""

MOTION_END_HISTORY: Final = 64
"""How many ends of motion :attr:`Firmware.motion_end_times` keeps."""

HOMING_RAIL_FACTOR: Final = 1.5
"""ASSUMED: ``$H0`` (arm and rail) searches this many times ``homing_seconds``."""

HOMING_SINGLE_AXIS_FACTOR: Final = 0.4
"""ASSUMED: ``$H1..$H7`` (a single axis) search this fraction of ``homing_seconds``."""

FREE_MEMORY: Final = 2036
"""The number of the classic ``Free memory:`` line (any number, PROTOCOL 4.3)."""

HARD_LIMIT_SWITCHES: Final[tuple[tuple[float, float], ...]] = tuple(kin.JOINT_LIMITS[:3])
"""ASSUMED: positions (deg) of the J1..J3 limit switches: the factory range ends."""

PATH_SAMPLE_MM: Final = 2.0
"""Cartesian paths are checked (IK, limits) every this many mm ..."""
PATH_SAMPLE_DEG: Final = 2.0
"""... and every this many degrees of orientation change."""

MAX_PATH_CHECK_SAMPLES: Final = 2000
"""ASSUMED cap on the check samples of one path (a huge re-orientation is sampled coarser)."""

STATUS_DURING_CRITICAL_ALARM: Final = False
"""Whether ``?`` is answered after a hard limit, before the reset. GRBL 0.9j's critical-event
loop does not answer it (its status report there is commented out as a TODO); PROTOCOL 6.1:
"nothing but ``%`` is processed until reset"."""

MAX_FEED: Final = 1e12
MIN_FEED: Final = 1e-9
"""Clamps for G93 inverse-time feeds that overflow or vanish (units/min)."""

SNAP_TOLERANCE: Final = 1e-4
"""Largest joint gap (deg) between the arm and the IK of its pose that needs no snap move."""

VERSIONS: Final = {"classic": "20191228_2", "2021": "20210516"}
GRBL_VERSION: Final = "0.9j"
BUILD_DATES: Final = {"classic": "20191228", "2021": "20210516"}  # ASSUMED ($I)

ARC_ANGULAR_TRAVEL_EPSILON: Final = 5e-7  # GRBL 0.9j config.h
MAX_LINE_NUMBER: Final = 9999999  # GRBL 0.9j gcode.c
N_STARTUP_LINE: Final = 2  # GRBL 0.9j config.h

# --- GRBL 0.9j status codes ---------------------------------------------------------------
EXPECTED_COMMAND_LETTER: Final = 1
BAD_NUMBER_FORMAT: Final = 2
INVALID_STATEMENT: Final = 3
NEGATIVE_VALUE: Final = 4
SETTING_DISABLED: Final = 5
SETTING_STEP_PULSE_MIN: Final = 6
IDLE_ERROR: Final = 8
ALARM_LOCK: Final = 9
SOFT_LIMIT_ERROR: Final = 10
OVERFLOW: Final = 11
UNSUPPORTED_COMMAND: Final = 20
MODAL_GROUP_VIOLATION: Final = 21
UNDEFINED_FEED_RATE: Final = 22
COMMAND_VALUE_NOT_INTEGER: Final = 23
AXIS_COMMAND_CONFLICT: Final = 24
WORD_REPEATED: Final = 25
NO_AXIS_WORDS: Final = 26
INVALID_LINE_NUMBER: Final = 27
VALUE_WORD_MISSING: Final = 28
G53_INVALID_MOTION_MODE: Final = 30
AXIS_WORDS_EXIST: Final = 31
NO_AXIS_WORDS_IN_PLANE: Final = 32
INVALID_TARGET: Final = 33
ARC_RADIUS_ERROR: Final = 34
NO_OFFSETS_IN_PLANE: Final = 35
UNUSED_WORDS: Final = 36

_STATUS_TEXT: Final = {
    EXPECTED_COMMAND_LETTER: "Expected command letter",
    BAD_NUMBER_FORMAT: "Bad number format",
    INVALID_STATEMENT: "Invalid statement",
    NEGATIVE_VALUE: "Value < 0",
    SETTING_DISABLED: "Setting disabled",
    SETTING_STEP_PULSE_MIN: "Value < 3 usec",
    7: "EEPROM read fail. Using defaults",
    IDLE_ERROR: "Not idle",
    ALARM_LOCK: "Alarm lock",
    SOFT_LIMIT_ERROR: "Homing not enabled",
    OVERFLOW: "Line overflow",
    UNSUPPORTED_COMMAND: "Unsupported command",
    MODAL_GROUP_VIOLATION: "Modal group violation",
    UNDEFINED_FEED_RATE: "Undefined feed rate",
}

_CODES_2021: Final = {
    UNDEFINED_FEED_RATE: (113, "Undefined feed rate"),  # 2021 manual 2.1.3
    ARC_RADIUS_ERROR: (116, "Arc radius error"),  # 2021 manual 2.1.9
}

# --- Mirobot texts (PROTOCOL 4.3, exact) ------------------------------------------------------
TEXT_LOCKED: Final = "Locked status of each axis!"
TEXT_SOFT_LIMIT: Final = "Soft limit triggered:"
TEXT_UNREACHABLE: Final = "GOAL OUT OF WORKSPACE, THERE IS NO VAILD VALUS FOR  THETA3!"
TEXT_OUT_OF_LIMIT: Final = "There is one angle out of limit!!!"
TEXT_M50: Final = "M50: Unlock each axis."
TEXT_M20: Final = "M20: Cartesian mode start."
TEXT_M21: Final = "M21: Angle mode start."
TEXT_HOMED: Final = {"classic": "in homeing moving...ok", "2021": "Info, in homing moving...ok"}
FEEDBACK_RESET_TO_CONTINUE: Final = "[Reset to continue]"
FEEDBACK_ALARM_LOCK: Final = "['$H'|'$X' to unlock]"
FEEDBACK_UNLOCKED: Final = "[Caution: Unlocked]"

_HELP: Final = (
    "$$ (view Grbl settings)",
    "$# (view # parameters)",
    "$G (view parser state)",
    "$I (view build info)",
    "$N (view startup blocks)",
    "$x=value (save Grbl setting)",
    "$Nx=line (save startup block)",
    "$C (check gcode mode)",
    "$X (kill alarm lock)",
    "$H (run homing cycle)",
    "~ (cycle start)",
    "! (feed hold)",
    "? (current status)",
    "ctrl-x (reset Grbl)",
)

_REALTIME: Final = frozenset(b"?!~%")
_AXIS_WORDS: Final = "XYZABCD"  # index = joint (M21: J1..J6, rail) or pose component (M20)
_VALUE_WORDS: Final = frozenset("FIJKLNPRSETXYZABCD")
_NON_NEGATIVE_WORDS: Final = frozenset("FNPTSE")
_FW_LETTERS: Final = "ABCDXYZ"  # soft-limit letters in the firmware's axis order a..g
_LETTER_TO_JOINT: Final = motion.LETTER_TO_JOINT
_MM_PER_INCH: Final = 25.4

Pose = tuple[float, float, float, float, float, float]


def error_text(status: int) -> str:
    """The classic text of GRBL 0.9j status ``status`` (PROTOCOL 4.1)."""
    return _STATUS_TEXT.get(status, f"Invalid gcode ID:{status}")


def _error_line(profile: str, status: int) -> str:
    """The final reply of a failed line, per profile (ASSUMED code rule for 2021)."""
    if profile == "classic":
        return f"error: {error_text(status)}"
    code, text = _CODES_2021.get(status, (100 + status, error_text(status)))
    return f"Error, E{code},{text}"


def _read_float(line: str, i: int) -> tuple[float, int] | None:
    """GRBL 0.9j ``read_float``: sign, digits, one point, at most 8 significant digits kept.

    Returns the value and the index after it, or None when no digit was read.
    """
    n = len(line)
    negative = False
    if i < n and line[i] in "+-":
        negative = line[i] == "-"
        i += 1
    intval = 0
    exp = 0
    ndigit = 0
    decimal = False
    while i < n:
        ch = line[i]
        if "0" <= ch <= "9":
            ndigit += 1
            if ndigit <= 8:
                if decimal:
                    exp -= 1
                intval = intval * 10 + (ord(ch) - 48)
            elif not decimal:
                exp += 1
        elif ch == "." and not decimal:
            decimal = True
        else:
            break
        i += 1
    if ndigit == 0:
        return None
    value = float(intval) * 10.0**exp if intval else 0.0
    return (-value if negative else value), i


def _sample_count(length: float, turn: float) -> int:
    """Check samples of a path of ``length`` mm turning ``turn`` degrees (capped)."""
    n = max(
        1,
        math.ceil(length / PATH_SAMPLE_MM - 1e-9),
        math.ceil(turn / PATH_SAMPLE_DEG - 1e-9),
    )
    return min(n, MAX_PATH_CHECK_SAMPLES)


def _c_round(x: float) -> int:
    """C ``round``: half away from zero."""
    return math.floor(x + 0.5) if x >= 0 else -math.floor(-x + 0.5)


def _uint8(value: float) -> int:
    """C conversion of a float to ``uint8_t`` as GRBL does it for command numbers."""
    return math.trunc(value) % 256


def _lerp(a: Sequence[float], b: Sequence[float], u: float) -> tuple[float, ...]:
    return tuple(x + (y - x) * u for x, y in zip(a, b, strict=True))


def _vec7(values: Sequence[float]) -> Vec7:
    return (
        float(values[0]),
        float(values[1]),
        float(values[2]),
        float(values[3]),
        float(values[4]),
        float(values[5]),
        float(values[6]),
    )


def _pose(values: Sequence[float]) -> Pose:
    return (
        float(values[0]),
        float(values[1]),
        float(values[2]),
        float(values[3]),
        float(values[4]),
        float(values[5]),
    )


class _Refusal(Exception):
    """A motion refused with one of the "ok but dropped" texts."""

    def __init__(self, text: str) -> None:
        super().__init__(text)
        self.text = text


@dataclass
class _Pending:
    """A line whose final reply waits for the planner (the parser is blocked meanwhile).

    ``blocks`` are pushed as slots free up; then ``until`` must hold: ``"queued"`` (nothing
    more), ``"idle"`` (the planner is empty), ``"searched"`` (no homing search left) or
    ``"released"`` (the feed hold is released). ``finish`` then acts and returns the lines to
    print (the final reply last); ``then`` is the next stage, if any.
    """

    blocks: list[Block]
    until: str
    finish: Callable[[], list[str]]
    then: _Pending | None = None
    hard_limit: Block | None = None


@dataclass
class _GBlock:
    """The words of one G-code line (GRBL's ``parser_block_t``)."""

    nonmodal: int | None = None  # 4 (dwell) or 53 (absolute override)
    motion: int | None = None  # 0, 1, 2, 3, 5 (2021 gate), 80
    axis_command: bool = False  # an explicit G0..G3/G5 in the line
    plane: int | None = None
    distance: int | None = None
    feed_mode: int | None = None
    units: int | None = None
    coord_select: int | None = None
    flow: int | None = None  # M0, M1, M2, M30
    spindle: int | None = None  # M3, M4, M5
    coolant: int | None = None  # M8, M9
    coord_mode: int | None = None  # M20, M21
    unlock: bool = False  # M50
    words: dict[str, float] = field(default_factory=dict)


@dataclass
class _Arc:
    """An XY arc of the commanded pose: centre, radius, start angle and signed travel."""

    cx: float
    cy: float
    radius: float
    start_angle: float
    travel: float


class Firmware:
    """A virtual Mirobot controller: call :meth:`receive`, :meth:`advance`, :meth:`read_output`.

    ``profile`` is ``"classic"`` (20191228_2) or ``"2021"`` (20210516); ``homing_seconds`` the
    switch search of ``$H`` (default :data:`DEFAULT_HOMING_SECONDS`). The arm is powered on at
    construction: the banner is already in the output.
    """

    def __init__(self, profile: str = "2021", *, homing_seconds: float | None = None) -> None:
        if profile not in PROFILES:
            raise ValueError(f"unknown firmware profile {profile!r} (use 'classic' or '2021')")
        if homing_seconds is None:
            homing_seconds = DEFAULT_HOMING_SECONDS
        if not (math.isfinite(homing_seconds) and homing_seconds >= 0.0):
            raise ValueError(f"homing_seconds must be finite and >= 0, got {homing_seconds}")
        self.profile: str = profile
        self.homing_seconds: float = float(homing_seconds)
        self.now: float = 0.0
        """Simulated seconds since power-on."""
        self.motion_end_times: deque[float] = deque(maxlen=MOTION_END_HISTORY)
        """Simulated instants at which the planner last went from busy to empty (newest last)."""
        self.motion_ends: int = 0
        """How many such instants there have been (``motion_end_times`` keeps the last ones)."""
        self.settings: dict[int, float] = cfg.default_settings(profile)
        self.rx_lost: int = 0
        """Bytes lost so far because the receive ring was full."""
        self._out = bytearray()
        self._ring = bytearray()
        self._line = bytearray()
        self._comment = 0  # 0 none, 1 parentheses, 2 semicolon
        self._line_overflow = False
        self._planner = Planner(motion.ZERO)
        self._pending: _Pending | None = None
        self._limit_blocks: list[Block] = []
        self._startup_lines = [""] * N_STARTUP_LINE
        self._build_info = ""
        # machine state
        self._alarm = False
        self._critical = False
        self._locked = True
        self._hold = False
        self._check = False
        self._check_q: Vec7 = motion.ZERO
        # parser state: modal groups, feed, PWMs (all set by _parser_init below)
        self._cart_mode = False
        self._cart: Pose = (0.0,) * 6
        self._power_on_condition(interrupted=False)
        self._parser_init(feed=200.0)
        self._banner()

    # ------------------------------------------------------------------------------------------
    # public API

    def receive(self, data: bytes) -> None:
        """Bytes from the host. Realtime bytes act at once wherever they are; the others enter
        the 128-byte receive ring (lost when it is full) and complete lines are executed as soon
        as the parser is free (not waiting for the planner, a homing search, a dwell or a hold).
        """
        for c in bytes(data):
            if c in _REALTIME:
                self._realtime(c)
                continue
            if len(self._ring) >= RX_BUFFER_SIZE:
                self.rx_lost += 1
                continue
            self._ring.append(c)
            if not self._blocked():
                self._pump()

    def advance(self, dt: float) -> None:
        """Run the simulated clock ``dt`` seconds (``math.inf``: until nothing changes by itself).

        Lines waiting for the planner are executed as blocks finish, their replies printed.
        """
        if not dt >= 0.0:
            raise ValueError(f"dt must be >= 0, got {dt}")
        end = self.now + dt
        self._service()
        zero_steps = 0
        while True:
            ttc = self._planner.time_to_next_change()
            if ttc is None:
                if not math.isinf(end):
                    self.now = end
                break
            left = end - self.now
            if ttc > left:
                self._planner.advance(left)
                self.now = end
                break
            self._planner.advance(ttc)
            self.now += ttc
            zero_steps = zero_steps + 1 if ttc == 0.0 else 0
            self._after_step()
            if not self._planner.busy:
                self.motion_end_times.append(self.now)
                self.motion_ends += 1
            if zero_steps > 100_000:  # pragma: no cover - a planner bug, never loop forever
                break
        self._service()

    def read_output(self) -> bytes:
        """Everything printed since the last call (each line ends ``\\r\\n``)."""
        out = bytes(self._out)
        self._out.clear()
        return out

    def next_deadline(self) -> float | None:
        """Simulated time of the next internal change, None when nothing changes by itself."""
        ttc = self._planner.time_to_next_change()
        return None if ttc is None else self.now + ttc

    def reset(self) -> None:
        """Soft reset, exactly as if ``%`` had arrived."""
        interrupted = False
        if not self._critical:
            running = self._planner.running
            if running is not None and running.kind == "home_search":
                self._emit("ALARM: Homing fail")
                interrupted = True
            elif self._moving():
                self._emit("ALARM: Abort during cycle")
                interrupted = True
        else:
            interrupted = True  # the hard-limit alarm survives the reset
        self._planner.abort()
        self._ring.clear()
        self._line.clear()
        self._comment = 0
        self._line_overflow = False
        self._pending = None
        self._limit_blocks.clear()
        self._hold = False
        self._check = False
        self._critical = False
        self._power_on_condition(interrupted=interrupted)
        self._parser_init(feed=200.0)
        self._banner()

    def trigger_hard_limit(self, axis: int = 1) -> None:
        """Fault injection: a limit switch (``axis``, informative) closes now.

        Motion stops at once, ``ALARM: Hard limit`` and ``[Reset to continue]`` are printed and
        nothing but ``%`` is processed until a reset. Ignored while already in that state.
        """
        del axis  # the firmware does not say which switch
        if not self._critical:
            self._hard_limit_alarm()

    def status_line(self) -> str:
        """The status report at this instant, without its ``\\r\\n`` (PROTOCOL 5)."""
        mask = _uint8(self.settings[10])
        parts = ["<", self.state]
        q = self._planner.position
        if mask & 1:
            wire = (q[3], q[4], q[5], q[6], q[0], q[1], q[2])
            parts.append(",Angle(ABCDXYZ):")
            parts.append(",".join(self._fmt(v) for v in wire))
            pose = self._fk(q)
            parts.append(",Cartesian coordinate(XYZ RxRyRz):")
            parts.append(",".join(self._fmt(v) for v in pose))
        if mask & 32:
            pump = math.trunc(self._pump_pwm) % 2**32
            valve = math.trunc(self._valve_pwm) % 2**32
            parts.append(f",Pump PWM:{pump},Valve PWM:{valve}")
        if mask & 64:
            parts.append(f",Motion_MODE:{1 if self._cart_mode else 0}")
        if mask & 4:
            parts.append(f",Buf:{len(self._planner.blocks)}")
        if mask & 8:
            parts.append(f",RX:{len(self._ring)}")
        if mask & 16:
            parts.append(f",Lim:{self._limit_pins(q):07b}")
        parts.append(">")
        return "".join(parts)

    @property
    def state(self) -> str:
        """The state word of the status report (``Idle``, ``Run``, ``Hold``, ``Home``, ...)."""
        if self._alarm or self._critical:
            return "Alarm"
        if self._hold:
            return "Hold"
        planner_state = self._planner.state
        if planner_state == "home":
            return "Home"
        if planner_state == "hold":
            return "Hold"
        if self._check:
            return "Check"
        if planner_state == "run":
            return "Run"
        return "Idle"

    @property
    def joints(self) -> Vec7:
        """Current joint position: J1..J6 (degrees) and the rail (mm)."""
        return self._planner.position

    @property
    def rx_free(self) -> int:
        """Free bytes in the 128-byte receive ring."""
        return RX_BUFFER_SIZE - len(self._ring)

    @property
    def locked(self) -> bool:
        """True while the axes are locked (power-on / reset lock; ``M50`` or homing clears it)."""
        return self._locked

    @property
    def parser_blocked(self) -> bool:
        """True while received lines wait (planner full, homing search, dwell, hold, alarm)."""
        return self._blocked()

    # ------------------------------------------------------------------------------------------
    # output

    def _emit(self, line: str) -> None:
        self._out += line.encode("latin-1", "replace") + b"\r\n"

    def _emit_lines(self, lines: Sequence[str]) -> None:
        for line in lines:
            self._emit(line)

    def _error(self, status: int) -> None:
        self._emit(_error_line(self.profile, status))

    def _info(self, text: str) -> str:
        return text if self.profile == "classic" else f"Info, {text}"

    @staticmethod
    def _refusal(text: str) -> list[str]:
        """ASSUMED shape of the "ok but dropped" texts: an empty line, then the text."""
        return ["", text]

    def _banner(self) -> None:
        """The welcome message (PROTOCOL 4.2), then the unlock hint when in Alarm."""
        d1, a1, a2, a3, d4, el = self._dh_values()
        offsets = self._base_offset()
        pose = self._fk(motion.ZERO)
        lines = [
            "",
            f"Grbl {GRBL_VERSION} ['$' for help]",
            "",
            f"Qinnew Robot {VERSIONS[self.profile]} based on Grbl {GRBL_VERSION} ['$' for help]",
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
        self._emit_lines(lines)
        if self._alarm:
            self._emit(FEEDBACK_ALARM_LOCK)

    @staticmethod
    def _fmt(value: float) -> str:
        """A status number: 3 decimals; ASSUMED ``0.000`` rather than ``-0.000``."""
        text = cfg.grbl_float(value)
        return "0.000" if text == "-0.000" else text

    # ------------------------------------------------------------------------------------------
    # geometry from the settings

    def _dh_values(self) -> tuple[float, float, float, float, float, float]:
        if self.profile == "classic":
            dh = kin.DH_CLASSIC
            return (dh.d1, dh.a1, dh.a2, dh.a3, dh.d4, dh.l)
        s = self.settings
        return (s[29], s[30], s[31], s[32], s[33], s[34])

    def _dh(self) -> kin.DH:
        return kin.DH(*self._dh_values())

    def _tool(self) -> tuple[float, float, float]:
        if self.profile == "classic":
            return (0.0, 0.0, 0.0)
        return (self.settings[46], self.settings[47], self.settings[48])

    def _base_offset(self) -> tuple[float, float, float]:
        if self.profile == "classic":
            return (0.0, 0.0, 0.0)
        return (self.settings[41], self.settings[42], self.settings[43])

    def _fk(self, q: Sequence[float]) -> Pose:
        return _pose(kin.forward(tuple(q[:6]), self._dh(), self._tool()))

    def _ik(self, pose: Sequence[float], *, check_limits: bool = True) -> tuple[float, ...]:
        """Firmware-branch IK, raising :class:`_Refusal` with the firmware's text."""
        try:
            return tuple(
                kin.inverse(
                    tuple(float(v) for v in pose),
                    self._dh(),
                    "firmware",
                    tool=self._tool(),
                    limits=kin.JOINT_LIMITS if check_limits else None,
                )
            )
        except ValueError as exc:
            if isinstance(exc, kin.OutOfLimits) or "out of limit" in str(exc).lower():
                raise _Refusal(TEXT_OUT_OF_LIMIT) from None
            raise _Refusal(TEXT_UNREACHABLE) from None

    def _limits(self) -> AxisLimits:
        return AxisLimits.from_settings(self.settings)

    def _soft_violation(self, q: Sequence[float]) -> str | None:
        """The firmware letter of the first axis (order a..g) outside its ``$13x/$14x`` range."""
        if self.settings[20] == 0:
            return None
        for k, letter in enumerate(_FW_LETTERS):
            value = q[_LETTER_TO_JOINT[k]]
            if value > self.settings[130 + k] or value < -self.settings[140 + k]:
                return letter
        return None

    def _limit_pins(self, q: Sequence[float]) -> int:
        pins = 0
        for j, (lo, hi) in enumerate(HARD_LIMIT_SWITCHES):
            if q[j] <= lo + 1e-9 or q[j] >= hi - 1e-9:
                pins |= 1 << (j + 4)  # J1..J3 are the firmware axes e, f, g (bits 4..6)
        return pins

    # ------------------------------------------------------------------------------------------
    # state helpers

    def _power_on_condition(self, *, interrupted: bool) -> None:
        """ASSUMED: locked after power-on and every reset; 2021 then in Alarm too."""
        self._locked = True
        self._alarm = interrupted or self.profile == "2021"

    def _parser_init(self, *, feed: float) -> None:
        """GRBL ``gc_init`` plus the Mirobot defaults (G0, G90, M21, PWM 0) and ``feed``."""
        self._motion = 0
        self._plane = 17
        self._units = 21
        self._distance = 90
        self._feed_mode = 94
        self._coord_select = 54
        self._spindle = 5
        self._coolant = 9
        self._feed = feed
        self._pump_pwm = 0.0
        self._valve_pwm = 0.0
        self._cart_mode = False
        self._cart = self._fk(self._planner.planned_position)

    def _moving(self) -> bool:
        """True when the arm is physically in motion (a reset then loses position)."""
        running = self._planner.running
        if running is None or running.kind == "dwell":
            return False
        if self._planner.held:
            return self._planner.time_to_next_change() is not None
        return True

    def _blocked(self) -> bool:
        return self._pending is not None or self._hold or self._critical

    def _parser_q(self) -> Vec7:
        """The joints the parser works from (the end of queued motion)."""
        return self._check_q if self._check else self._planner.planned_position

    # ------------------------------------------------------------------------------------------
    # realtime bytes

    def _realtime(self, c: int) -> None:
        if c == 0x25:  # %
            self.reset()
            self._service()
            return
        if self._critical and not (c == 0x3F and STATUS_DURING_CRITICAL_ALARM):
            return  # nothing but % until reset (GRBL's critical-event loop)
        if c == 0x3F:  # ?
            self._emit(self.status_line())
        elif c == 0x21:  # !
            running = self._planner.running
            if (
                self._alarm
                or self._check
                or (running is not None and running.kind not in motion.HOLDABLE_KINDS)
            ):
                return  # GRBL ignores a feed hold in Alarm, check mode and homing
            self._hold = True
            self._planner.hold()
        elif c == 0x7E and self._hold:  # ~
            self._hold = False
            self._planner.resume()
            self._service()

    def _hard_limit_alarm(self) -> None:
        self._emit("ALARM: Hard limit")
        self._emit(FEEDBACK_RESET_TO_CONTINUE)
        self._planner.abort()
        self._limit_blocks.clear()
        self._pending = None
        self._hold = False
        self._alarm = True
        self._critical = True

    # ------------------------------------------------------------------------------------------
    # the main loop: pending lines, received bytes

    def _after_step(self) -> None:
        if self._limit_blocks:
            queued = self._planner.blocks
            for block in self._limit_blocks:
                if not any(b is block for b in queued):
                    self._hard_limit_alarm()
                    return
        self._service()

    def _service(self) -> None:
        """Push waiting blocks, finish waiting lines, then execute received lines."""
        while True:
            if self._pending is not None and not self._progress_pending():
                return
            if self._blocked() or not self._ring:
                return
            self._pump()

    def _progress_pending(self) -> bool:
        """Advance the waiting line; True when it is finished (the parser is free again)."""
        while self._pending is not None:
            p = self._pending
            while p.blocks and self._planner.free > 0:
                block = p.blocks.pop(0)
                self._planner.push(block)
            if p.blocks:
                return False
            if p.hard_limit is not None:
                self._limit_blocks.append(p.hard_limit)
                p.hard_limit = None
            if not self._pending_done(p.until):
                return False
            self._pending = p.then
            self._emit_lines(p.finish())
        return True

    def _pending_done(self, until: str) -> bool:
        if until == "queued":
            return True
        if until == "idle":
            return not self._planner.busy
        if until == "searched":
            return not any(b.kind == "home_search" for b in self._planner.blocks)
        if until == "released":
            return not self._hold
        raise AssertionError(until)  # pragma: no cover

    def _wait(self, pending: _Pending) -> None:
        """Make ``pending`` the waiting line and progress it as far as possible now."""
        self._pending = pending
        self._progress_pending()

    def _pump(self) -> None:
        """Move bytes from the ring into the line buffer; execute complete lines."""
        ring = self._ring
        while ring and not self._blocked():
            c = ring[0]
            del ring[0]
            if c in (0x0A, 0x0D):
                line = self._line.decode("latin-1")
                overflow = self._line_overflow
                self._line.clear()
                self._comment = 0
                self._line_overflow = False
                if overflow:
                    self._error(OVERFLOW)
                else:
                    self._execute_line(line)
                continue
            if self._comment:
                if c == 0x29 and self._comment == 1:  # ')'
                    self._comment = 0
            elif c <= 0x20 or c == 0x2F:  # whitespace, control bytes, '/' (block delete)
                pass
            elif c == 0x28:  # '('
                self._comment = 1
            elif c == 0x3B:  # ';'
                self._comment = 2
            elif len(self._line) >= LINE_BUFFER_SIZE:
                self._line_overflow = True
            elif 0x61 <= c <= 0x7A:
                self._line.append(c - 0x20)
            else:
                self._line.append(c)

    def _execute_line(self, line: str) -> None:
        if not line:
            self._emit("ok")
        elif line[0] == "$":
            self._system_command(line)
        elif self._alarm and not self._m50_allowed_in_alarm(line):
            self._error(ALARM_LOCK)
        else:
            self._gcode(line)

    def _m50_allowed_in_alarm(self, line: str) -> bool:
        """ASSUMED: on 2021 a bare ``M50`` unlocks even in Alarm (the manual's power-on use)."""
        if self.profile != "2021" or line[:1] != "M":
            return False
        parsed = _read_float(line, 1)
        return parsed is not None and parsed == (50.0, len(line))

    # ------------------------------------------------------------------------------------------
    # $ commands

    def _idle_or_alarm(self) -> bool:
        return self.state in ("Idle", "Alarm")

    def _system_command(self, line: str) -> None:
        if len(line) == 1:
            self._emit_lines(_HELP)
            self._emit("ok")
            return
        kind = line[1]
        if kind in "$GCX":
            if len(line) > 2 and line[2] != "H":
                self._error(INVALID_STATEMENT)
                return
            if kind == "$":
                if self.state in ("Run", "Hold"):
                    self._error(IDLE_ERROR)
                    return
                self._emit_lines(cfg.format_dump(self.settings, self.profile))
            elif kind == "G":
                self._emit(self._parser_state_line())
            elif kind == "C":
                if self._check:
                    self._emit("[Disabled]")
                    self._emit("ok")
                    self.reset()
                    return
                if self.state != "Idle":
                    self._error(IDLE_ERROR)
                    return
                self._check = True
                self._check_q = self._planner.planned_position
                self._emit("[Enabled]")
            elif self._alarm:  # $X
                self._emit(FEEDBACK_UNLOCKED)
                self._alarm = False
            self._emit("ok")
            return
        if not self._idle_or_alarm():
            self._error(IDLE_ERROR)
            return
        if kind == "#":
            if len(line) != 2:
                self._error(INVALID_STATEMENT)
                return
            self._emit_lines(self._ngc_parameters())
            self._emit("ok")
        elif kind == "H":
            self._home(line)
        elif kind == "I":
            if len(line) == 2:
                self._emit(f"[{GRBL_VERSION}.{BUILD_DATES[self.profile]}:{self._build_info}]")
            elif line[2] != "=":
                self._error(INVALID_STATEMENT)
                return
            else:
                self._build_info = line[3:]
            self._emit("ok")
        elif kind == "R":
            if len(line) != 6 or line[2:5] != "ST=" or line[5] not in "$#*":
                self._error(INVALID_STATEMENT)
                return
            if line[5] in "$*":
                self.settings.clear()  # in place: holders of ``settings`` see the change
                self.settings.update(cfg.default_settings(self.profile))
            if line[5] == "*":
                self._startup_lines = [""] * N_STARTUP_LINE
                self._build_info = ""
            self._emit("[Restoring defaults]")
            self._emit("ok")
            self.reset()
        elif kind == "N" and len(line) == 2:
            for n, text in enumerate(self._startup_lines):
                self._emit(f"$N{n}={text}")
            self._emit("ok")
        elif kind == "N":
            self._store_startup_line(line)
        elif kind == "M" and self.profile == "2021":
            self._zero_move(line)
        else:
            self._store_setting(line)

    def _store_startup_line(self, line: str) -> None:
        parsed = _read_float(line, 2)
        if parsed is None:
            self._error(BAD_NUMBER_FORMAT)
            return
        number, i = parsed
        if i >= len(line) or line[i] != "=":
            self._error(INVALID_STATEMENT)
            return
        if self.state != "Idle":
            self._error(IDLE_ERROR)
            return
        n = math.trunc(number)
        if not 0 <= n < N_STARTUP_LINE:
            self._error(INVALID_STATEMENT)
            return
        self._startup_lines[n] = line[i + 1 :]
        self._emit("ok")

    def _store_setting(self, line: str) -> None:
        parsed = _read_float(line, 1)
        if parsed is None:
            self._error(BAD_NUMBER_FORMAT)
            return
        parameter, i = parsed
        if i >= len(line) or line[i] != "=":
            self._error(INVALID_STATEMENT)
            return
        parsed = _read_float(line, i + 1)
        if parsed is None:
            self._error(BAD_NUMBER_FORMAT)
            return
        value, i = parsed
        if i != len(line) or parameter > 255:
            self._error(INVALID_STATEMENT)
            return
        self._reply(self._set_setting(_uint8(parameter), value))

    def _set_setting(self, number: int, value: float) -> int:
        """Store setting ``number``; the GRBL status (0 = ok)."""
        if value < 0 and not (self.profile == "2021" and number in cfg.SIGNED_2021):
            return NEGATIVE_VALUE
        spec = cfg.spec(self.profile, number)
        if spec is None:
            return INVALID_STATEMENT
        if spec.kind != "float":
            ivalue = math.trunc(value)
            if number == 0 and ivalue % 256 < 3:
                return SETTING_STEP_PULSE_MIN
            if number in (20, 21, 22):
                ivalue = 1 if ivalue % 256 else 0
            value = float(ivalue % 65536 if number == 26 else ivalue % 256)
        if number == 20 and value and not self.settings[22]:
            return SOFT_LIMIT_ERROR
        self.settings[number] = value
        if number == 22 and not value:
            self.settings[20] = 0.0  # GRBL: disabling homing disables soft limits
        return 0

    def _reply(self, status: int) -> None:
        if status:
            self._error(status)
        else:
            self._emit("ok")

    def _parser_state_line(self) -> str:
        """``$G`` (GRBL 0.9j ``report_gcode_modes``)."""
        motion_word = {0: "G0", 1: "G1", 2: "G2", 3: "G3", 5: "G5", 80: "G80"}[self._motion]
        parts = [
            motion_word,
            f"G{self._coord_select}",
            f"G{self._plane}",
            f"G{self._units}",
            f"G{self._distance}",
            f"G{self._feed_mode}",
            "M0",
            f"M{self._spindle}",
            f"M{self._coolant}",
            "T0",
            f"F{cfg.grbl_float(self._feed, 0)}",
            f"S{cfg.grbl_float(self._pump_pwm, 0)}",
        ]
        return "[" + " ".join(parts) + "]"

    @staticmethod
    def _ngc_parameters() -> list[str]:
        zeros = ",".join(["0.000"] * motion.AXES)
        lines = [f"[G{n}:{zeros}]" for n in range(54, 60)]
        lines += [f"[G28:{zeros}]", f"[G30:{zeros}]", f"[G92:{zeros}]", "[TLO:0.000]"]
        lines.append(f"[PRB:{zeros}:0]")
        return lines

    # ------------------------------------------------------------------------------------------
    # homing and $M

    def _home(self, line: str) -> None:
        if not self.settings[22]:
            self._error(SETTING_DISABLED)
            return
        suffix = line[2:]
        seconds = self.homing_seconds
        sequential = suffix[:1] == "H"
        order: tuple[tuple[int, ...], ...] | None = None
        axes: tuple[int, ...] = motion.ARM_AXES
        home_rail = False
        if self.profile == "2021" and not sequential:
            if suffix == "E":
                sequential = True
                order = ((1, 2), (0, 3, 4))
            elif suffix == "0":
                home_rail = True
                seconds *= HOMING_RAIL_FACTOR
            elif len(suffix) == 1 and "1" <= suffix <= "7":
                axis = int(suffix) - 1
                seconds *= HOMING_SINGLE_AXIS_FACTOR
                if axis == motion.RAIL:
                    axes = ()
                    home_rail = True
                else:
                    axes = (axis,)
        blocks = motion.homing_blocks(
            self._planner.planned_position,
            seconds,
            self._limits(),
            sequential,
            order=order,
            axes=axes,
            home_rail=home_rail,
        )
        self._alarm = False
        if self.profile == "classic":
            self._emit_lines(["", f"Free memory: {FREE_MEMORY}"])

        def finish() -> list[str]:
            self._locked = False
            self._parser_init(feed=0.0)
            return [TEXT_HOMED[self.profile]]

        self._wait(_Pending(blocks, "searched", finish))

    def _zero_move(self, line: str) -> None:
        """2021 ``$M``: rapid move of J1..J6 to zero (ASSUMED details in the module doc)."""
        if line != "$M":
            self._error(INVALID_STATEMENT)
            return
        if self._alarm:
            self._error(ALARM_LOCK)
            return
        if self._locked:
            self._emit_lines([*self._refusal(TEXT_LOCKED), "ok"])
            return
        start = self._planner.planned_position
        target = _vec7((0.0, 0.0, 0.0, 0.0, 0.0, 0.0, start[6]))
        block = motion.joint_block(start, target, None, self._limits())
        self._cart = self._fk(target)
        if block.length == 0.0:
            self._emit("ok")
            return
        self._wait(_Pending([block], "queued", lambda: ["ok"]))

    # ------------------------------------------------------------------------------------------
    # G-code

    def _scan(self, line: str) -> _GBlock | int:
        """STEP 2 of GRBL's parser: import the words, check groups, repeats and signs."""
        g = _GBlock()
        groups: set[str] = set()
        i = 0
        n = len(line)
        while i < n:
            letter = line[i]
            if not "A" <= letter <= "Z":
                return EXPECTED_COMMAND_LETTER
            parsed = _read_float(line, i + 1)
            if parsed is None:
                return BAD_NUMBER_FORMAT
            value, i = parsed
            int_value = _uint8(value)
            mantissa = _c_round(100.0 * (value - int_value)) % 65536
            if letter == "G":
                status = self._g_word(g, int_value, mantissa, groups)
                if status:
                    return status
            elif letter == "M":
                if mantissa:
                    return COMMAND_VALUE_NOT_INTEGER
                if int_value in (0, 1, 2, 30):
                    group = "M4"
                    g.flow = int_value
                elif int_value in (3, 4, 5):
                    group = "M7"
                    g.spindle = int_value
                elif int_value in (8, 9):
                    group = "M8"
                    g.coolant = int_value
                elif int_value in (20, 21):
                    group = "M20"
                    g.coord_mode = int_value
                elif int_value == 50:
                    group = "M50"
                    g.unlock = True
                else:
                    return UNSUPPORTED_COMMAND
                if group in groups:
                    return MODAL_GROUP_VIOLATION
                groups.add(group)
            else:
                if letter not in _VALUE_WORDS:
                    return UNSUPPORTED_COMMAND
                if letter in g.words:
                    return WORD_REPEATED
                if letter in _NON_NEGATIVE_WORDS and value < 0:
                    return NEGATIVE_VALUE
                g.words[letter] = value
        return g

    def _g_word(self, g: _GBlock, code: int, mantissa: int, groups: set[str]) -> int:
        if code in (10, 28, 30, 38, 43, 49, 92):
            return UNSUPPORTED_COMMAND  # not modelled (see the module docstring)
        if code in (4, 53):
            group = "G0"
            g.nonmodal = code
        elif code in (0, 1, 2, 3, 5, 80):
            if code in (2, 3, 5) and self.profile == "classic":
                return UNSUPPORTED_COMMAND
            if code != 80:
                if g.axis_command:
                    return AXIS_COMMAND_CONFLICT
                g.axis_command = True
            group = "G1"
            g.motion = code
        elif code in (17, 18, 19):
            group = "G2"
            g.plane = code
        elif code in (90, 91):
            if mantissa == 0:
                group = "G3"
                g.distance = code
            else:
                group = "G4"
                if mantissa != 10 or code == 90:
                    return UNSUPPORTED_COMMAND
                mantissa = 0
        elif code in (93, 94):
            group = "G5"
            g.feed_mode = code
        elif code in (20, 21):
            group = "G6"
            g.units = code
        elif code == 40:
            group = "G7"
        elif 54 <= code <= 59:
            group = "G12"
            g.coord_select = code
        elif code == 61:
            group = "G13"
            if mantissa:
                return UNSUPPORTED_COMMAND
        else:
            return UNSUPPORTED_COMMAND
        if mantissa:
            return COMMAND_VALUE_NOT_INTEGER
        if group in groups:
            return MODAL_GROUP_VIOLATION
        groups.add(group)
        return 0

    def _gcode(self, line: str) -> None:
        scanned = self._scan(line)
        if isinstance(scanned, int):
            self._error(scanned)
            return
        g = scanned
        words = g.words
        cart = self._cart_mode if g.coord_mode is None else g.coord_mode == 20
        motion_mode = self._motion if g.motion is None else g.motion
        distance = self._distance if g.distance is None else g.distance
        units = self._units if g.units is None else g.units
        feed_mode = self._feed_mode if g.feed_mode is None else g.feed_mode
        axis_letters = [letter for letter in _AXIS_WORDS if letter in words]
        axis_command = g.axis_command or bool(axis_letters)
        used = set("NFSTE")

        # [non-specific] line number
        if "N" in words and words["N"] > MAX_LINE_NUMBER:
            self._error(INVALID_LINE_NUMBER)
            return
        # [2, 3] feed rate mode and feed rate
        if feed_mode == 93:
            if axis_command and "F" not in words:
                self._error(UNDEFINED_FEED_RATE)
                return
            feed = words.get("F", 0.0)
        elif self._feed_mode == 94:
            if "F" in words:
                feed = words["F"] * (_MM_PER_INCH if units == 20 else 1.0)
            else:
                feed = self._feed
        else:
            feed = words.get("F", 0.0)
        pump = words.get("S", self._pump_pwm)
        valve = words.get("E", self._valve_pwm)
        # [10] dwell
        if g.nonmodal == 4:
            if "P" not in words:
                self._error(VALUE_WORD_MISSING)
                return
            used.add("P")
        # [12] units; [19] target
        scale = _MM_PER_INCH if units == 20 else 1.0
        q0 = self._parser_q()
        if cart:
            base_pose = self._fk(q0) if (g.coord_mode == 20 or not self._cart_mode) else self._cart
            base = (*base_pose, q0[6])
            offset = (*self._base_offset(), 0.0, 0.0, 0.0, 0.0)
        else:
            base = q0
            offset = (0.0,) * 7
        target_list = list(base)
        for k, letter in enumerate(_AXIS_WORDS):
            if letter in words:
                value = words[letter] * scale
                if distance == 90:
                    target_list[k] = value + offset[k]
                else:
                    target_list[k] = value + base[k]
        target = _vec7(target_list)
        # [19] G53
        if g.nonmodal == 53 and motion_mode not in (0, 1):
            self._error(G53_INVALID_MOTION_MODE)
            return
        # [20] motion modes
        arc: _Arc | None = None
        if motion_mode == 80:
            if axis_letters:
                self._error(AXIS_WORDS_EXIST)
                return
        elif axis_command:
            if motion_mode in (2, 3, 5) and not cart:
                self._error(UNSUPPORTED_COMMAND)  # ASSUMED: no arcs / gates in joint mode
                return
            if motion_mode == 0:
                axis_command = bool(axis_letters)
            else:
                if feed == 0.0:
                    self._error(UNDEFINED_FEED_RATE)
                    return
                if motion_mode in (1, 5):
                    axis_command = bool(axis_letters)
                else:
                    result = self._arc_check(motion_mode, words, axis_letters, base, target, scale)
                    if isinstance(result, int):
                        self._error(result)
                        return
                    arc, arc_words = result
                    used |= arc_words
        if axis_command:
            used |= set(_AXIS_WORDS)
        if set(words) - used:
            self._error(UNUSED_WORDS)
            return

        # ---- STEP 4: execute -----------------------------------------------------------------
        out: list[str] = []
        self._feed_mode = feed_mode
        self._feed = feed
        self._pump_pwm = pump
        self._valve_pwm = valve
        if g.spindle is not None:
            self._spindle = g.spindle
        if g.coolant is not None:
            self._coolant = g.coolant
        if g.plane is not None:
            self._plane = g.plane
        self._units = units
        self._distance = distance
        if g.coord_select is not None:
            self._coord_select = g.coord_select
        self._motion = motion_mode
        if g.unlock:
            self._locked = False
            self._alarm = False
            out.append(self._info(TEXT_M50))
        if g.coord_mode == 20:
            self._cart_mode = True
            self._cart = _pose(base[:6])
            if self.profile == "2021":
                out.append(self._info(TEXT_M20))
        elif g.coord_mode == 21:
            self._cart_mode = False
            if self.profile == "2021":
                out.append(self._info(TEXT_M21))

        blocks: list[Block] = []
        hard_limit: Block | None = None
        wait_idle = False
        if g.nonmodal == 4 and not self._check:
            seconds = words["P"]
            wait_idle = True
            # The dwell starts where the queued motion ends; the motion of this line follows.
            blocks.append(motion.dwell_block(seconds, self._planner.planned_position))
        if axis_command and motion_mode != 80:
            start = blocks[-1].end if blocks else q0
            try:
                new_blocks, hard_limit, end_q = self._plan_motion(
                    motion_mode, cart, start, target, feed, feed_mode, arc
                )
            except _Refusal as refusal:
                out += self._refusal(refusal.text)
            else:
                if self._check:
                    self._check_q = end_q
                blocks += new_blocks
                if cart:
                    self._cart = _pose(target[:6])
        self._emit_lines(out)

        flow = g.flow
        if flow in (0, 2, 30) and not self._check:
            wait_idle = True
        if not blocks and not wait_idle:
            if flow in (2, 30):
                self._program_end()
                self._emit("[Pgm End]")
            self._emit("ok")
            return

        def finish() -> list[str]:
            if flow in (2, 30):
                self._program_end()
                return ["[Pgm End]", "ok"]
            if flow == 0:
                self._hold = True
                return []
            return ["ok"]

        then = _Pending([], "released", lambda: ["ok"]) if flow == 0 else None
        until = "idle" if wait_idle else "queued"
        self._wait(_Pending(blocks, until, finish, then=then, hard_limit=hard_limit))

    def _program_end(self) -> None:
        """M2 / M30: GRBL resets these modal groups (motion becomes G1)."""
        self._motion = 1
        self._plane = 17
        self._distance = 90
        self._feed_mode = 94
        self._coord_select = 54
        self._spindle = 5
        self._coolant = 9

    def _arc_check(
        self,
        motion_mode: int,
        words: dict[str, float],
        axis_letters: list[str],
        base: Sequence[float],
        target: Vec7,
        scale: float,
    ) -> tuple[_Arc, set[str]] | int:
        """GRBL's G2/G3 checks in the XY plane of the commanded pose; the arc or a status."""
        if not axis_letters:
            return NO_AXIS_WORDS
        if "X" not in words and "Y" not in words:
            return NO_AXIS_WORDS_IN_PLANE
        x0, y0 = base[0], base[1]
        x = target[0] - x0
        y = target[1] - y0
        if "R" in words:
            if x == 0.0 and y == 0.0:
                return INVALID_TARGET
            r = words["R"] * scale
            h2 = 4.0 * r * r - x * x - y * y
            if h2 < 0:
                return ARC_RADIUS_ERROR
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
                return NO_OFFSETS_IN_PLANE
            i_off = words.get("I", 0.0) * scale
            j_off = words.get("J", 0.0) * scale
            target_r = math.hypot(x - i_off, y - j_off)
            r = math.hypot(i_off, j_off)
            delta_r = abs(target_r - r)
            if delta_r > 0.005 and (delta_r > 0.5 or delta_r > 0.001 * r):
                return INVALID_TARGET
            if r == 0.0:
                return INVALID_TARGET
            used = {"I", "J", "K"} & set(words)
        rx0, ry0 = -i_off, -j_off  # centre -> start
        rtx, rty = x - i_off, y - j_off  # centre -> end
        travel = math.atan2(rx0 * rty - ry0 * rtx, rx0 * rtx + ry0 * rty)
        if motion_mode == 2:
            if travel >= -ARC_ANGULAR_TRAVEL_EPSILON:
                travel -= 2.0 * math.pi
        elif travel <= ARC_ANGULAR_TRAVEL_EPSILON:
            travel += 2.0 * math.pi
        arc = _Arc(x0 + i_off, y0 + j_off, r, math.atan2(ry0, rx0), travel)
        return arc, used

    # ------------------------------------------------------------------------------------------
    # motion planning

    def _plan_motion(
        self,
        motion_mode: int,
        cart: bool,
        start: Vec7,
        target: Vec7,
        feed: float,
        feed_mode: int,
        arc: _Arc | None,
    ) -> tuple[list[Block], Block | None, Vec7]:
        """The blocks of one accepted motion line, the block that ends on a limit switch (if
        any) and the joints where the line ends (raises :class:`_Refusal`)."""
        if not cart:
            if self._locked:
                raise _Refusal(TEXT_LOCKED)
            return self._joint_move(start, target, None if motion_mode == 0 else feed, feed_mode)
        if motion_mode == 0:
            q = self._ik(target[:6])
            end = _vec7((*q, target[6]))
            if self._locked:
                raise _Refusal(TEXT_LOCKED)
            return self._joint_move(start, end, None, feed_mode)
        p0 = self._cart
        rail0 = start[6]
        segments: list[tuple[Callable[[float], tuple[Pose, float]], float, int]] = []
        if motion_mode == 1:
            segments.append(self._line_segment(p0, _pose(target[:6]), rail0, target[6]))
        elif motion_mode == 5:
            lift = self.settings[49]
            z_top = max(p0[2], target[2]) + lift
            up = (p0[0], p0[1], z_top, p0[3], p0[4], p0[5])
            over = (target[0], target[1], z_top, target[3], target[4], target[5])
            segments.append(self._line_segment(p0, up, rail0, rail0))
            segments.append(self._line_segment(up, over, rail0, target[6]))
            segments.append(self._line_segment(over, _pose(target[:6]), target[6], target[6]))
        else:
            assert arc is not None
            segments.append(self._arc_segment(arc, p0, _pose(target[:6]), rail0, target[6]))
        return self._path_move(start, segments, feed, feed_mode)

    def _joint_move(
        self, start: Vec7, end: Vec7, feed: float | None, feed_mode: int
    ) -> tuple[list[Block], Block | None, Vec7]:
        letter = self._soft_violation(end)
        if letter is not None:
            raise _Refusal(TEXT_SOFT_LIMIT + letter)
        if self._check:
            return [], None, end
        cut = self._switch_crossing(start, end)
        if cut is not None:
            end = cut
        length = math.sqrt(math.fsum((b - a) ** 2 for a, b in zip(start, end, strict=True)))
        if length == 0.0 and cut is None:
            return [], None, end
        if feed is not None and feed_mode == 93:
            feed = feed * length
        if feed is not None and not math.isfinite(feed):
            feed = None  # the max rates limit the motion
        elif feed is not None and feed <= 0.0:
            feed = MIN_FEED
        try:
            block = motion.joint_block(start, end, feed, self._limits())
        except ValueError:
            raise _Refusal(TEXT_UNREACHABLE) from None
        return [block], (block if cut is not None else None), end

    def _switch_crossing(self, start: Sequence[float], end: Sequence[float]) -> Vec7 | None:
        """Where a joint move first carries J1..J3 out of their switches (``$21=1``), or None."""
        if not self.settings[21]:
            return None
        best: float | None = None
        for j, (lo, hi) in enumerate(HARD_LIMIT_SWITCHES):
            a, b = start[j], end[j]
            if not lo <= a <= hi or lo <= b <= hi:
                continue
            edge = hi if b > hi else lo
            f = (edge - a) / (b - a)
            if best is None or f < best:
                best = f
        if best is None:
            return None
        point = list(_lerp(start, end, best))
        for j, (lo, hi) in enumerate(HARD_LIMIT_SWITCHES):
            point[j] = min(max(point[j], lo), hi) if lo <= start[j] <= hi else point[j]
        return _vec7(point)

    def _line_segment(
        self, p0: Pose, p1: Pose, rail0: float, rail1: float
    ) -> tuple[Callable[[float], tuple[Pose, float]], float, int]:
        length = math.dist(p0[:3], p1[:3])
        turn = max(abs(b - a) for a, b in zip(p0[3:], p1[3:], strict=True))
        n = _sample_count(length, turn)

        def at(u: float) -> tuple[Pose, float]:
            if u >= 1.0:
                return p1, rail1
            return _pose(_lerp(p0, p1, u)), rail0 + (rail1 - rail0) * u

        return at, length, n

    def _arc_segment(
        self, arc: _Arc, p0: Pose, p1: Pose, rail0: float, rail1: float
    ) -> tuple[Callable[[float], tuple[Pose, float]], float, int]:
        dz = p1[2] - p0[2]
        length = math.hypot(abs(arc.travel) * arc.radius, dz)
        turn = max(abs(b - a) for a, b in zip(p0[3:], p1[3:], strict=True))
        n = _sample_count(length, turn)

        def at(u: float) -> tuple[Pose, float]:
            if u <= 0.0:
                return p0, rail0
            if u >= 1.0:
                return p1, rail1
            angle = arc.start_angle + arc.travel * u
            x = arc.cx + arc.radius * math.cos(angle)
            y = arc.cy + arc.radius * math.sin(angle)
            rest = _lerp(p0[2:], p1[2:], u)
            return (x, y, *rest), rail0 + (rail1 - rail0) * u  # type: ignore[return-value]

        return at, length, n

    @staticmethod
    def _unwrap(q: Sequence[float], ref: Sequence[float]) -> tuple[float, ...]:
        """Shift J4 and J6 by whole turns to lie nearest to ``ref`` (within their ranges)."""
        out = list(q[:6])
        for j in (3, 5):
            lo, hi = kin.JOINT_LIMITS[j]
            shifted = out[j] + 360.0 * round((ref[j] - out[j]) / 360.0)
            if lo <= shifted <= hi:
                out[j] = shifted
        return tuple(out)

    def _path_move(
        self,
        start: Vec7,
        segments: Sequence[tuple[Callable[[float], tuple[Pose, float]], float, int]],
        feed: float,
        feed_mode: int,
    ) -> tuple[list[Block], Block | None, Vec7]:
        """Check every sample of every segment, then build the blocks (raises _Refusal)."""
        checked: list[tuple[Callable[[float], tuple[Pose, float]], float, list[Vec7]]] = []
        prev: Sequence[float] = start
        for at, length, n in segments:
            refs: list[Vec7] = []
            for k in range(n + 1):
                pose, rail = at(k / n)
                q = self._unwrap(self._ik(pose), prev)
                refs.append(_vec7((*q, rail)))
                prev = refs[-1]
            checked.append((at, length, refs))
        # soft limits on every sample (the IK limits were checked above)
        for _at, _length, refs in checked:
            for q in refs:
                letter = self._soft_violation(q)
                if letter is not None:
                    raise _Refusal(TEXT_SOFT_LIMIT + letter)
        if self._locked:
            raise _Refusal(TEXT_LOCKED)
        if self._check:
            return [], None, checked[-1][2][-1]
        limits = self._limits()
        blocks: list[Block] = []
        current = start
        for at, length, refs in checked:
            gap = max(abs(a - b) for a, b in zip(refs[0], current, strict=True))
            if gap > SNAP_TOLERANCE:
                blocks.append(motion.joint_block(current, refs[0], None, limits))
                current = refs[0]
            poses = self._poses_function(at, refs, current)
            still = max(abs(a - b) for a, b in zip(refs[-1], current, strict=True)) == 0.0
            if length == 0.0 and still:
                continue
            rate = feed
            if feed_mode == 93:
                span = length if length > 0.0 else math.dist(refs[0], refs[-1])
                rate = feed * span
            if not math.isfinite(rate):
                rate = MAX_FEED  # an absurd G93 feed: the max rates limit the motion
            elif rate <= 0.0:
                rate = MIN_FEED
            try:
                block = motion.path_block(current, poses, length, rate, limits)
            except ValueError:
                raise _Refusal(TEXT_UNREACHABLE) from None
            blocks.append(block)
            current = block.end
        return blocks, None, current

    def _poses_function(
        self,
        at: Callable[[float], tuple[Pose, float]],
        refs: Sequence[Vec7],
        start: Vec7,
    ) -> Callable[[float], Vec7]:
        """``poses(u)`` for :func:`motion.path_block`: IK of the path, continuous in J4/J6."""
        ref_array = np.asarray(refs, dtype=np.float64)
        n = len(refs) - 1

        def poses(u: float) -> Vec7:
            if u <= 0.0:
                return start
            pose, rail = at(u)
            if u >= 1.0:
                return refs[-1]
            k = min(int(u * n), n - 1)
            f = u * n - k
            ref = ref_array[k] + (ref_array[k + 1] - ref_array[k]) * f
            q = self._unwrap(self._ik(pose, check_limits=False), ref.tolist())
            return _vec7((*q, rail))

        def safe(u: float) -> Vec7:
            try:
                return poses(u)
            except _Refusal as exc:
                raise ValueError(exc.text) from None

        return safe
