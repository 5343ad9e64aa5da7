"""The pure firmware model of the virtual Mirobot: bytes in, bytes out, an explicit clock.

:class:`Firmware` behaves like the arm's GRBL 0.9j based firmware (PROTOCOL.md is the reference
for every byte; where PROTOCOL.md is silent, the vendor's open firmware source and GRBL 0.9j
decide). No asyncio, no OS calls: the host feeds bytes with :meth:`Firmware.receive`, runs the
simulated clock with :meth:`Firmware.advance` and collects what the robot prints with
:meth:`Firmware.read_output`. Motion timing is :mod:`mirobot_emulator.motion`; kinematics are
:mod:`mirobot_async.kinematics` (the only module of the client it uses).

Layout
------
* :mod:`.linebuffer`: the receive ring and the line discipline.
* :mod:`.scanner`: GRBL's word scanner (STEP 2); :mod:`.validation`: its checks (STEP 3).
* :mod:`.modal`: the modal state; :mod:`.geometry`: FK, IK, soft limits, switches.
* :mod:`.moves`: motion lines into planner blocks; :mod:`.gcode`: executing a valid line.
* :mod:`.system`: the ``$`` commands and homing; :mod:`.reports`: status, banner, ``$#``.
* :mod:`.machine`: the shared state; :mod:`.facade`: :class:`Firmware`; :mod:`.codes`: texts.

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
GRBL's look-ahead (see :mod:`mirobot_emulator.motion`); work coordinate
systems, ``G10``/``G28``/``G30``/``G92``, tool length offsets (``G43.1``/``G49``) and probing
(``G38.x``): they answer ``Unsupported command`` (GRBL would accept them; no Mirobot client sends
them); ``G54..G59`` are accepted with all offsets zero; stored startup lines (``$N0=``) are kept
but never executed; the limit-switch physics of homing (homing cannot fail except by ``%``);
``$50`` tool presets; the ``$36`` point count (lines are exact); EEPROM persistence (settings
live as long as the object); the 500 ms stall GRBL adds after printing an alarm; the firmware
bugs visible in the open source (a stale modal-group bit for ``M3``/``M20``, parser positions
updated by refused moves, ``M20``/``M50`` executed by lines that then fail).

ASSUMED points implemented (each in one constant or function, named here)
-------------------------------------------------------------------------
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
* ``Machine.reset_condition``: only power-on locks the axes (oracle; PROTOCOL 6.1 said every
  ``%`` too); after a reset the 2021 profile is in ``Alarm`` (ASSUMED, its power-on state), the
  classic profile only when the reset interrupted motion.
* ``reports.step_position``: status angles are whole motor steps (``$100..$106`` per degree or
  mm, rounded half away from zero) and the pose is the FK of those angles (oracle).
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

from .codes import PROFILES, error_text
from .facade import DEFAULT_HOMING_SECONDS, Firmware
from .geometry import HARD_LIMIT_SWITCHES
from .linebuffer import LINE_BUFFER_SIZE, RX_BUFFER_SIZE, RX_CAPACITY

__all__ = [
    "DEFAULT_HOMING_SECONDS",
    "HARD_LIMIT_SWITCHES",
    "LINE_BUFFER_SIZE",
    "PROFILES",
    "RX_BUFFER_SIZE",
    "RX_CAPACITY",
    "Firmware",
    "error_text",
]
