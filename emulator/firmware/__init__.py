"""The pure firmware model of the virtual Mirobot: bytes in, bytes out, an explicit clock.

:class:`Firmware` behaves like the arm's GRBL 0.9j based firmware. Evidence, strongest first
(classic profile): the device logs in ``vectors.json`` (banner and homing texts), the oracle (the
vendor's open firmware 20191228_2 as it ran unmodified in an AVR simulator, a black box; what it
did is kept as the firmware tapes, ``../shared/firmware-tapes``, replayed by ``tests/tapes``),
PROTOCOL.md, the manuals. The 2021 profile keeps the 2021 manual's texts and otherwise behaves
as the classic oracle does. No asyncio, no OS calls: the host feeds bytes with
:meth:`Firmware.receive`, runs the simulated clock with :meth:`Firmware.advance` and collects
what the robot prints with :meth:`Firmware.read_output`. Motion timing is
:mod:`mirobot_emulator.motion`; kinematics are :mod:`mirobot_async.kinematics` (the only module
of the client it uses; its typed ``Unreachable``/``OutOfLimits`` become the firmware's texts in
:func:`._geometry.kinematics_refusal`).

Layout
------
* :mod:`._linebuffer`: the receive ring and the line discipline.
* :mod:`._scanner`: GRBL's word scanner (STEP 2); :mod:`._validation`: its checks (STEP 3).
* :mod:`._modal`: the modal state; :mod:`._offsets`: work coordinates; :mod:`._geometry`: FK, IK,
  soft limits, switches.
* :mod:`._moves`: motion lines into planner blocks; :mod:`._gcode`: executing a valid line.
* :mod:`._system`: the ``$`` commands and homing; :mod:`._reports`: status and banner.
* :mod:`._machine`: the shared state; :mod:`._facade`: :class:`Firmware`; :mod:`._codes`: texts.

Every 2021 behaviour that no 2021 manual or 2021 device log shows (the ASSUMED ones), and why
each is not simply classic's: ``docs/2021-profile.md``.

What is modelled (checked against the oracle where it says so)
----------------------------------------------------------------
* Line discipline: ``\\r`` or ``\\n`` end a line, every empty line gets ``ok``, bytes
  ``<= 0x20`` and ``/`` are dropped, letters upper-cased, ``(...)`` and ``;`` comments removed.
  A line holds 79 bytes after filtering; the 80th byte is dropped, ``Line overflow`` is printed
  at once and the bytes after it start a new line (oracle: ``LINE_BUFFER_SIZE``). The receive
  ring holds 127 bytes, the rest is lost (oracle: ``RX_CAPACITY``; :attr:`Firmware.rx_lost`).
* After a soft reset the banner takes ``BOOT_SECONDS`` (30 ms, oracle): lines received meanwhile
  wait, a ``?`` received meanwhile is answered first when it ends (before those lines), one
  within ``RESET_DEAF_SECONDS`` of the ``%`` is lost (oracle: the reset clears its flags).
* After printing an alarm (``Abort during cycle``, ``Homing fail``, ``Hard limit``) the firmware
  stalls ``ALARM_STALL_SECONDS`` (500 ms, tapes) with the motion stopped: then the ``ok`` of a
  line in progress and the reset's banner, or ``[Reset to continue]``. Realtime bytes meanwhile
  (``%`` too) are lost; other bytes enter the receive ring, which the reset empties.
* A ``?`` that arrives while the previous report is still being printed gets none of its own
  (oracle: 12.5 ms after a 175-byte report's ``?``, 15.1 ms for 193 bytes, ~45 ms after a
  ``%`` whose banner goes first); modelled by :mod:`._uart` when the server paces the link at
  the arm's baud rate at real time or faster (``Firmware.uart.byte_seconds``), else every ``?``
  is answered. ASSUMED: the window does not grow while the arm moves (the oracle's does: 14-16
  ms for a 175-byte report at 30 deg/s, whose first byte comes 2-12 ms after the ``?`` as the
  stepper interrupt takes the processor).
* Realtime bytes ``?`` ``!`` ``~`` ``%`` and ``@`` anywhere in the stream; ``@`` holds the
  parser (lines wait, motion and the state word go on) until ``~`` (oracle). ``0x18`` is an
  ordinary (dropped) byte.
* The G-code grammar with GRBL 0.9j's modal groups and checks, the error texts of both profiles,
  the Mirobot texts, settings and ``$$`` (classic: with ``$28`` and ``$150..$156``, oracle),
  ``$G``, ``$#``, ``$I`` (oracle line), ``$N``, ``$C``, ``$X``, ``$RST``, homing, the status
  report, the power-on lock, Alarm, soft and hard limits, feed hold, soft reset.
* Work coordinates (oracle): ``G10 L2``/``L20`` set ``G54..G59``, ``G92``/``G92.1``,
  ``G28``/``G30`` (rapid joint moves, through the axis words' point in ``M21``) and
  ``G28.1``/``G30.1``; the offsets add to absolute targets (ASSUMED in ``M20`` too), ``$#``
  prints them; ``G49`` is accepted, ``G43.1`` answers ``Invalid gcode ID:37``.
* The parser's own position (``ModalState.joints``): targets are measured from it, the planner
  moves from where queued motion ends; a line with ``M20`` or ``M21`` first sets it to the
  machine position, where the arm is now (oracle: eight queued ``M21 G91 X1`` end at 1.005).
* Startup lines (oracle): ``$N0=``/``$N1=`` execute the line to check it (stored only when it
  is accepted); after a reset out of Alarm each stored line runs, printed with its reply glued
  on (``G91ok``).
* Status angles are whole motor steps, the pose is the FK of those angles (oracle:
  ``reports.step_position``); during a ``G4`` dwell the state is ``Idle`` (oracle).
* Parse time (oracle, :mod:`._linecost`): bytes arrive one per 100 us (:mod:`._wire`); each line
  occupies the parser with its words' work (``M20`` 6.8 ms + 0.16 ms per joint off zero, a
  Cartesian target 5.3-6.3 ms by its ``Y``/``A``/``B``/``C``, a Cartesian block 0.40 ms, 1.45 ms
  behind others, charged only when planned; a joint line 1.45 ms), plus 6.6 us per byte that
  arrives meanwhile (its receive interrupt; 6.2 us if the full ring loses it); its effects, its
  ``ok`` and the next line come after it; a ``?`` meanwhile is answered right after the line's
  reply. A full ring loses the bytes that arrive (oracle: bursts of ``M20 G91`` lines lose the
  same bytes). GRBL's auto cycle start: queued blocks wait until the planner is full, a line
  waits for it (``G4``, homing, ``$``), or the receive ring has no complete line.
* Cartesian lines (2021 ``$35=1``), gate moves and arcs are cut into blending joint-space
  blocks, one every 2 mm (ASSUMED; the 2021 ``$36`` point count is not used).

Not modelled
------------
GRBL's look-ahead details (see :mod:`mirobot_emulator.motion`); probing (``G38.x``: the oracle
prints ``ALARM: Probe fail``; here ``Unsupported command``) and ``G43`` without ``.1``; arcs in
the classic firmware's real arc plane (its axes 0..2 are J4..J6); the limit-switch physics of
homing (homing cannot fail except by ``%``); ``$50`` tool presets; the ``$36`` point count;
EEPROM persistence (settings live as long as the object); the 500 ms stall GRBL adds after
printing an alarm; the firmware's float32 FK (status numbers are float32, ``.float32``, but the
pose is double FK of the float32 angles: the last digit differs in about 7.6 % of lines).

ASSUMED points implemented (each in one constant or function, named here)
-------------------------------------------------------------------------
* ``codes.error_line``: 2021 errors are ``Error, E1nn,<text>`` with ``nn`` the GRBL 0.9 status
  number, except the manual's ``E113 Undefined feed rate`` (GRBL 22) and ``E116 Arc radius
  error`` (GRBL 34); every other text is the classic one.
* ``codes.refusal_lines``: the "ok but dropped" texts are an empty line then the text, then
  ``ok`` (oracle); ``GOAL OUT OF WORKSPACE... THETA3!`` has ``ok`` glued to it on the same line
  (oracle: ``codes.TEXTS_WITHOUT_LINE_END``).
* ``Machine.reset_condition``: only power-on locks the axes (oracle; PROTOCOL 6.1 said every
  ``%`` too); the 2021 profile powers on in ``Alarm`` (PROTOCOL 1); a reset makes an ``Alarm``
  only when it interrupts motion and keeps one (oracle, PROTOCOL 3; both profiles).
* ``facade.m50_allowed_in_alarm``: on 2021 a bare ``M50`` line is accepted in ``Alarm`` and
  clears it (the 2021 manual unlocks with ``M50`` right after power-on, when the arm is in
  ``Alarm``); on classic ``M50`` in ``Alarm`` gets ``error: Alarm lock`` like any G-code.
* Only a valid line has effects: ``M20``/``M21``/``M50`` act and print only when the whole line
  is accepted (so ``M20 G1 X200`` with feed 0 prints just the error, as in the vectors).
* ``M20`` ``G91`` increments add to the last *commanded* pose; a line with ``M20`` first sets it
  to the FK of the machine position. ``GcodeExecutor._refused_target``: a locked refusal still
  moves the parser's position to the target, an unreachable Cartesian target still becomes the
  commanded pose (oracle); a soft-limit refusal moves neither (ASSUMED in ``M20``).
* The 2021 base offset ``$41..$43`` is added to absolute ``M20`` X/Y/Z targets (open firmware);
  the status report prints the pose in the robot frame (FK with the ``$46..$48`` tool offset).
* ``geometry.IK_CHECKS_JOINT_RANGES``: the IK is the firmware branch with no joint range check
  (oracle): a wrist out of range gets ``Soft limit triggered:B`` with ``$20=1`` and moves with
  ``$20=0``; ``There is one angle out of limit!!!`` is never printed.
* ``geometry.shoulder_mirrored_pose`` (oracle): the firmware's IK takes the wrist centre's
  horizontal distance from the shoulder without its sign, so a wrist centre behind the shoulder
  (within ``A1`` = 32 mm of the base axis) is solved as if mirrored in front of it: J2 and the
  wrist differ from the textbook branch and the arm goes elsewhere (``X1 Y5 Z182 A0 B0 C0``:
  J2 -78.77, pose X 11.55 Y 57.75; ``$20=1`` names ``Y``). The client's own reading,
  ``kinematics.firmware_pose``, makes ``inverse(branch="firmware")`` refuse such poses
  (``BehindShoulder``), so its envelope never lets one through.
* ``MoveBuilder.linear_lines``: classic ``M20 G1`` is one joint-space block, F in deg/min along
  the joint vector (oracle); on 2021 with ``$35=1`` it is a straight line. Straight lines,
  ``G2``/``G3`` arcs and ``G05`` are checked sample by sample (every 2 mm / 2 degrees) before
  any motion; J4 and J6 are kept continuous along a path; if the current joints are not the IK
  of the commanded pose (to a motor step), a rapid joint move to it comes first.
* ``HARD_LIMIT_SWITCHES`` and ``SWITCH_OVERTRAVEL`` (ASSUMED for a real arm: the oracle
  harness's switch model): the J1..J3 switches close 0.5 degrees beyond the factory range ends;
  a move that would carry J1..J3 past one (``$21=1``; possible with ``$20=0`` or widened
  ``$13x``/``$14x``) stops on the first whole motor step past it, at the speed it had there
  (GRBL kills the step pulses at once; the other axes where GRBL's line has them at that step
  event), e.g. J1 at 160.515 (oracle, any feed); joint moves are exact, Cartesian paths (2021)
  stop within a step or two. A switch that is already closed when a move starts is passed
  (no edge). Then ``<8 binary digits>ALARM: Hard limit`` (the closed switches, bit 4 = J1:
  oracle ``00010000ALARM: Hard limit``) and, after the stall, ``[Reset to continue]`` are
  printed; nothing but
  ``%`` is processed until reset, not even ``?`` (``STATUS_DURING_CRITICAL_ALARM``); after the
  reset the arm is in Alarm where it stopped. The oracle's harness turns its range switches off
  once homing has completed; ours stay (a real arm's switches do not go away).
  :meth:`Firmware.trigger_hard_limit` raises the same alarm at once (fault injection).
* 2021 ``G2``/``G3`` arcs are always in the XY plane (2021 manual), Z and orientation move
  linearly (helix); ``G2``/``G3``/``G05`` in ``M21`` (joint) mode answer ``Unsupported command``.
  An arc whose end has the start's X and Y answers ``Invalid gcode ID:33``. Classic parses
  ``G2``/``G3`` but X/Y are not in its arc plane: ``Invalid gcode ID:32`` (oracle).
* ``G05`` (2021 gate move): straight up to ``max(z_start, z_end) + $49``, across, straight down,
  all at the feed rate F (so F is required, E113 otherwise); orientation and rail change on the
  way across.
* ``$M`` (2021): rapid joint move of J1..J6 to 0 (rail unchanged), needs Idle (``Not idle``),
  refuses in ``Alarm`` (``Alarm lock``) and prints ``Locked status`` while locked.
* Homing: ``homing_seconds`` (default ``CLASSIC_HOMING_SECONDS`` = 8.1534 s on classic, tapes;
  ``DEFAULT_HOMING_SECONDS`` = 10 s on 2021, PROTOCOL) is the switch search of ``$H``;
  ``$HH`` and ``$HE`` are sequential (:mod:`mirobot_emulator.motion`; classic ``$HH``
  searches ``CLASSIC_SEQUENTIAL_HOMING_FACTOR`` times as long, tapes 29.07 s); ``$H0`` (arm + rail)
  searches ``HOMING_RAIL_FACTOR`` times as long, ``$H1..$H7`` (one axis; 7 = rail) for
  ``HOMING_SINGLE_AXIS_FACTOR`` of it. During the search ``?`` is not answered; one deferred
  ``?`` is answered (state ``Home``) when it ends (oracle). Then the homed axes read zero, the
  lock is cleared and the parser re-initialised (feed 0, ``M21``, PWM 0), the return move is
  planned (``HOMED_PLANNING_SECONDS``, after that status is produced), the homed text is
  printed (device logs: classic ``""``, ``Free memory: 2036`` before and ``in homeing
  moving...ok`` after, where the oracle prints ``ok``), and ``SystemCommands._return_to_zero``
  moves each homed axis its reset distance ``$150..$156`` (away from its switch: negative where
  ``$28`` has its bit) at the homing feed ``$24`` in ``Run`` while the parser is free; the
  position reads zero again when the planner is next idle (oracle: ~2.3 s on classic).
  The classic profile accepts any ``$H...`` as ``$H`` except ``$HH`` (open firmware).
  ``M95`` homes as ``$H`` does, with its replies (tapes: classic, a bare ``M95``; ASSUMED: the
  rest of its line acts first, and 2021 does the same, its manual being silent).
* ``G4`` waits for the planner to empty, then dwells (state ``Idle``, oracle); its ``ok`` comes
  after the dwell, and after the motion of its line is queued, not run (oracle: ``M21 G91 G0
  X30 G4 P0.2``); it lasts :func:`._gcode.dwell_seconds` (GRBL's 50 ms steps counted in 16 bits:
  ``G4 P3277`` waits 0.2 s, tapes). ``M2``/``M30`` wait for the planner, reset the modal state
  as GRBL does and print ``[Pgm End]``; ``M0`` waits, then holds; its ``ok`` follows the ``~``.
* A soft reset during a dwell or a completed feed hold is not "during motion" (no alarm), as in
  GRBL; during homing it is ``ALARM: Homing fail``.
* The banner's last line is followed by ``['$H'|'$X' to unlock]`` whenever the state is Alarm,
  so always on 2021; the banner's numbers are the integer parts of the DH settings, the base
  offsets and the FK at zero joints. The second banner line is the device logs' ``Qinnew Robot
  ...`` (the oracle prints ``Wlkata Robot ...--Modified by Thor Zhou``).
* ``scanner.STALE_GROUP_WORDS``: ``M3``/``M4``/``M5``/``M20``/``M21``/``M50`` take the modal
  group of the G or M word before them in the line, so any modal word before them is a
  ``Modal group violation`` (oracle: ``G91 M3``, ``M8 M5``, ``G90 M21``, ``G4 M5``; a value
  word in between leaves another group; first in a line they take the feed-mode group:
  ``M21 G93`` is a violation);
  ASSUMED the same on 2021. ``M40``/``M41`` (calibration) are not modelled.
* ``$I``: ``[0.9j.20160303:<stored info>--ZDX&LEAH(201306)]`` (oracle; the same on 2021, where
  no evidence shows it).
* ``reports.fmt``: status reports follow the ``$10`` mask like the open firmware (bit 0 angles
  and pose, bit 5 the PWMs, bit 6 ``Motion_MODE``, bits 2/3/4 ``Buf``/``RX``/``Lim``); a number
  that would print as ``-0.000`` prints ``0.000`` (the vectors never show ``-0.000``).
* A line with both a refusal (IK) and a lock prints only the first refusal (IK first, as the
  firmware computes IK before its lock check).

Taken from GRBL 0.9j / the open firmware where PROTOCOL.md is silent
--------------------------------------------------------------------
* ``$X`` prints ``[Caution: Unlocked]`` only in Alarm (otherwise just ``ok``).
* ``$`` commands other than ``$$``, ``$G``, ``$C``, ``$X`` need Idle or Alarm: ``$H`` or a
  setting sent while the arm moves answers ``Not idle``; ``$$`` too while moving or held.
* ``!`` while idle enters ``Hold`` as well (oracle); while held, received lines wait until ``~``.
* ``Pump PWM`` / ``Valve PWM`` are the last ``S`` / ``E`` words (with or without ``M3``/``M4``;
  ``M5`` does not clear them); a reset and a homing set both to 0 (GRBL's ``gc_init``).
* Lines that wait for queued motion to end (oracle, ``gcode.waits_for_motion``): an ``M3``/
  ``M4``/``M5`` that changes the output mode, a new ``S``/``E`` while ``M3`` or ``M4`` is on (the
  status keeps the old PWM until the wait ends), an ``M8``/``M9`` that changes the coolant
  state; the rest of the line (its motion too) runs after the wait.
* A joint line whose target rounds to the steps already planned makes no block (GRBL drops
  it): a burst of resynchronising ``M21 G91`` lines never waits for a planner slot (oracle).
* ``Soft limit triggered:<axis>`` names the first offending axis in the firmware's order
  a..g = J4, J5, J6, D, J1, J2, J3 (letters A B C D X Y Z).
* On 2021 every line with an ``M20``/``M21`` word prints its ``Info`` line (the firmware runs
  ``M20``/``M21`` each time); classic prints nothing for them.
* ``$20=1`` needs ``$22=1`` (``Homing not enabled``); ``$22=0`` turns soft limits off.
* Error texts of GRBL 0.9j beyond PROTOCOL 4.1: ``Value < 3 usec`` (``$0``), ``Homing not
  enabled``, ``EEPROM read fail. Using defaults``.
"""

from __future__ import annotations

from ._codes import PROFILES, error_text
from ._facade import CLASSIC_HOMING_SECONDS, DEFAULT_HOMING_SECONDS, Firmware
from ._geometry import HARD_LIMIT_SWITCHES
from ._linebuffer import LINE_BUFFER_SIZE, RX_BUFFER_SIZE, RX_CAPACITY
from ._uart import report_compute_seconds

__all__ = [
    "CLASSIC_HOMING_SECONDS",
    "DEFAULT_HOMING_SECONDS",
    "HARD_LIMIT_SWITCHES",
    "LINE_BUFFER_SIZE",
    "PROFILES",
    "RX_BUFFER_SIZE",
    "RX_CAPACITY",
    "Firmware",
    "error_text",
    "report_compute_seconds",
]
