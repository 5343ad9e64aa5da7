"""Pure motion model of the virtual Mirobot: GRBL-style look-ahead planning in joint space.

No asyncio, no OS calls, no clock of its own: time only moves when the caller runs
:meth:`Planner.advance`. Everything is in JOINT order (J1..J6 in degrees, then the rail D in
mm); the firmware's letter order (a..g = J4, J5, J6, D, J1, J2, J3) only appears in
:meth:`AxisLimits.from_settings`, :func:`letters_to_joints` and :func:`joints_to_letters`.

Modules: :mod:`._axes` (vectors, limits from the ``$`` settings, motor steps), :mod:`._profile`
(trapezoids), :mod:`._blocks` (what a block is), :mod:`._builders` (blocks from G-code
intentions), :mod:`._planner` (the 18-block look-ahead planner; its docstring has the rules).

The model, checked against the classic firmware (the oracle; its recorded firmware tapes)
-----------------------------------------------------------------------------------------
* Joint moves (``M21``, ``M20 G0``, classic ``M20 G1``): one block, a straight line in joint
  space. Its length is the Euclidean norm of the displacement **in whole motor steps** converted
  back to degrees (``$100..$106`` steps per degree; ``X90`` on J1 is 5106 steps = 90.005 deg);
  the feed is deg/min along that vector, reduced so that no axis exceeds its ``$11x`` max rate;
  the acceleration is ``min_i $12x_i / u_i`` deg/s^2 (``u``: the unit vector). From rest to
  rest this gives ``T = L / v + v / a`` (trapezoid) or ``2 sqrt(L / a)`` (triangle); the oracle
  agrees within 4 ms (``M21 G90 G1 X90 F2000`` 3.370 s, ``F1000`` 5.738 s; ``M20 G90 G1 X180
  Y20 Z120 A0 B0 C0 F2000`` from the start pose 1.655 s).
* Consecutive blocks blend at GRBL's junction speeds (``$11`` junction deviation, in degrees);
  see :mod:`._planner`. Programs measured in simulated time against the oracle (same bytes,
  character counting): 200 ``M20 G1`` chords of 3.1 mm at F2000 15.101 s there, 14.969 s here
  (15.091 s with the oracle's cycle start and line cost, see :meth:`Planner.cycle_start`);
  400 chords of 0.5 mm at F3000 13.232 / 13.106 s; joint polygons with 8 and 20 degree turns,
  right angles and zigzags within 0.4 %.
* The planner holds 17 blocks (GRBL's 18-slot ring keeps one free).
* Positions are whole motor steps during and after motion (GRBL's Bresenham line).
* :func:`path_blocks` cuts a Cartesian path into joint blocks that blend; :func:`path_block`
  keeps the one-block path (stops before and after it).
* :func:`dwell_block` (``G4 P``) and the homing search are *timed* blocks (``s`` is seconds);
  the planner stops before and after them.

**ASSUMED** points (each in one named constant or function)
-------------------------------------------------------------
* Cartesian acceleration of :func:`path_block` derived from the joint accelerations; a path
  with zero tool travel (pure re-orientation) is timed along the joint path, ``F`` in deg/min.
* ``G4`` dwell reports ``Run``, and a feed hold pauses the dwell timer.
* Homing: the reported joints stay where they were during the switch search; ``$HH`` searches
  J1..J5 one after another, each for ``SEQUENTIAL_SEARCH_FRACTION * search_seconds``; the
  pull-off moves the homed axes to 0 at G0 rates. Feed hold is ignored during homing.
* Feed hold shows ``Hold`` at once, while still decelerating; the braking starts at the first
  boundary of the stepper's 10 ms segments (``HOLD_SEGMENT_SECONDS``, counted from the start of
  the motion) at least ``HOLD_LATENCY`` (40.3 ms) after the ``!`` (oracle replay: the held
  position matches exactly); a ``~`` while still decelerating is dropped by the firmware
  (oracle: it stays in ``Hold``). A hold with an empty planner is ignored; a hold that
  decelerates onto the end of the last block ends in ``idle``. The first step comes
  ``CYCLE_START_LATENCY`` (1.75 ms, oracle replay) after a cycle start.
* Settings of 0 (or less) for a max rate or an acceleration are clamped to ``MIN_MAX_RATE`` /
  ``MIN_ACCEL``.

Not modelled
------------
GRBL's stepper segment buffer (except as the feed-hold latency) and AMASS: the oracle's
acceleration ramps run about 10 ms behind the ideal trapezoid and its decelerations about 6 ms
ahead, so mid-motion positions agree within about 0.35 degrees there (one step at cruise).
Nor jerk, the centripetal joint acceleration on curved joint paths, lost steps / stalls, motor
load, homing switch physics and feed overrides. Limits (soft/hard) and IK reachability are the
firmware's business, not this package's.
"""

from __future__ import annotations

from ._axes import (
    ARM_AXES,
    AXES,
    LETTER_TO_JOINT,
    MIN_ACCEL,
    MIN_MAX_RATE,
    RAIL,
    ZERO,
    AxisLimits,
    Steps7,
    Vec7,
    joints_to_letters,
    letters_to_joints,
)
from ._blocks import Block, DwellBlock, HomeSearchBlock, JointBlock, PathBlock
from ._builders import (
    DEFAULT_PATH_STEP_MM,
    MAX_PATH_SAMPLES,
    MIN_PATH_SAMPLES,
    PATH_START_TOLERANCE,
    SEQUENTIAL_ORDER,
    SEQUENTIAL_SEARCH_FRACTION,
    dwell_block,
    homing_blocks,
    joint_block,
    joint_block_in_steps,
    path_block,
    path_blocks,
)
from ._planner import (
    CYCLE_START_LATENCY,
    HOLDABLE_KINDS,
    SNAP_SECONDS,
    START_TOLERANCE,
    Planner,
    PlannerFull,
    junction_speed_sqr,
)
from ._profile import SNAP_FRACTION, Profile

__all__ = [
    "ARM_AXES",
    "AXES",
    "CYCLE_START_LATENCY",
    "DEFAULT_PATH_STEP_MM",
    "HOLDABLE_KINDS",
    "LETTER_TO_JOINT",
    "MAX_PATH_SAMPLES",
    "MIN_ACCEL",
    "MIN_MAX_RATE",
    "MIN_PATH_SAMPLES",
    "PATH_START_TOLERANCE",
    "RAIL",
    "SEQUENTIAL_ORDER",
    "SEQUENTIAL_SEARCH_FRACTION",
    "SNAP_FRACTION",
    "SNAP_SECONDS",
    "START_TOLERANCE",
    "ZERO",
    "AxisLimits",
    "Block",
    "DwellBlock",
    "HomeSearchBlock",
    "JointBlock",
    "PathBlock",
    "Planner",
    "PlannerFull",
    "Profile",
    "Steps7",
    "Vec7",
    "dwell_block",
    "homing_blocks",
    "joint_block",
    "joint_block_in_steps",
    "joints_to_letters",
    "junction_speed_sqr",
    "letters_to_joints",
    "path_block",
    "path_blocks",
]
