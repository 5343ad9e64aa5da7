"""The 18-block look-ahead planner of the virtual Mirobot, with an explicit clock.

Our own implementation of the planning GRBL publishes (Sonny Jeon's look-ahead notes and
GRBL's wiki), in JOINT space:

* **Junction speed.** When a block that can blend (a :class:`JointBlock` with motion) follows
  another, the largest speed through the corner is GRBL's junction deviation rule: with
  ``cos_theta = -(u_prev . u_next)`` (``u``: joint-space unit vectors, ``theta`` the angle
  between the two directions seen from the corner) and ``sin_half = sqrt((1 - cos_theta) / 2)``::

      v_junction^2 = accel_next * $11 * sin_half / (1 - sin_half)

  0 for a reversal (``cos_theta > 0.999999``), and never above either block's nominal speed.
  A block pushed onto an empty planner, and every block next to a timed block (dwell, homing)
  or a one-block Cartesian :class:`PathBlock`, starts or ends at rest.
* **Look-ahead.** On every push, and whenever a block starts, the entry speeds are re-planned:
  a reverse pass from the last block (which ends at rest) lowers each entry speed to what its
  block can brake from (``v_in^2 <= v_out^2 + 2 a L``), then a forward pass from the running
  block's *current* position and speed lowers each to what can be reached
  (``v_out^2 <= v_in^2 + 2 a L``). The running block gets a fresh trapezoid from where it is to
  its new exit speed; each later block gets its trapezoid when it starts.
* **Feed hold** decelerates along the planned path at each block's acceleration, across block
  ends if needed; resume re-plans from the current speed.

Not modelled: GRBL's stepper segment buffer (the few milliseconds of motion already prepared
when a block arrives; only a feed hold waits for it, ``HOLD_LATENCY``), AMASS, and the minimum
planner speed. GRBL starts a cycle only when the planner is full or its input has run dry;
with ``deferred_start`` the firmware reproduces that through :meth:`Planner.cycle_start`.
"""

from __future__ import annotations

import math
from collections import deque
from typing import ClassVar, Final

from ._axes import AxisLimits, Steps7, Vec7, finite_vec7
from ._blocks import Block, JointBlock
from ._profile import STOPPED, Profile, constant_rate

SNAP_SECONDS: Final = 1e-9
"""A block whose remaining time is below this is finished (float error never runs forever)."""

START_TOLERANCE: Final = 1e-6
"""Largest per-axis gap allowed between a pushed block's start and the planner's planned end."""

HOLDABLE_KINDS: Final = frozenset({"move", "line", "arc", "dwell"})
"""Blocks a feed hold acts on (homing ignores it)."""

HOLD_LATENCY: Final = 0.0403
"""Seconds a feed hold keeps the planned motion at least before it decelerates: GRBL's stepper
has already prepared that much (its segment buffer); the braking then starts at the next
boundary of its ``HOLD_SEGMENT_SECONDS`` segments, counted from the start of the motion.
Oracle, replayed at its own simulated instants (the firmware tapes of ``test_replay_motion``): in
four recordings the held position is matched exactly by braking 40.9-49.8 ms after the ``!``, and
each time at a multiple of 10 ms since the motion started (the fits allow 39.8-40.9 ms here)."""

HOLD_SEGMENT_SECONDS: Final = 0.010
"""GRBL's stepper segments (``ACCELERATION_TICKS_PER_SECOND`` = 100): a hold acts at their
boundaries (0: at once after ``HOLD_LATENCY``)."""

CYCLE_START_LATENCY: Final = 0.00175
"""Seconds from GRBL's auto cycle start to the first step: its stepper prepares the first
segments and wakes up (oracle, replayed at its own simulated instants: single moves agree
within one motor step with 1.5-2 ms, against 4 steps ahead without)."""

REVERSAL_COS: Final = 0.999999
"""GRBL's cut-offs: a junction this close to a reversal stops; this close to straight is
treated as straight (no division by zero)."""


class PlannerFull(RuntimeError):
    """push() on a planner with no free slot."""


def junction_speed_sqr(previous: Vec7, following: Vec7, accel: float, deviation: float) -> float:
    """GRBL's junction deviation rule (module docstring): the largest squared speed through the
    corner between unit directions ``previous`` and ``following``; ``inf`` when straight and
    ``deviation > 0`` is not limiting (callers cap it by the nominal speeds)."""
    cos_theta = -math.fsum(a * b for a, b in zip(previous, following, strict=True))
    if cos_theta > REVERSAL_COS or deviation <= 0.0:
        return 0.0
    cos_theta = max(cos_theta, -REVERSAL_COS)
    sin_half = math.sqrt(0.5 * (1.0 - cos_theta))
    return accel * deviation * sin_half / (1.0 - sin_half)


class Planner:
    """The 18-block look-ahead planner with an explicit clock.

    ``state`` is ``"idle"`` (nothing queued), ``"home"`` (a ``home_search`` block runs),
    ``"hold"`` (a feed hold is in effect, from the moment it is requested) or ``"run"``.
    ``starvations`` counts the times a block arrived after the planner had run empty by
    finishing its motion (the machine stopped for want of blocks, then more came), and
    ``starved_seconds`` the simulated time it stood still each time; ``run_outs`` counts the
    times it ran empty at all.
    """

    CAPACITY: ClassVar[int] = 17
    """Blocks the planner holds: GRBL's ring of ``BLOCK_BUFFER_SIZE`` = 18 keeps one slot empty
    (the oracle acknowledges 17 motion lines, the 18th waits for the first block to finish)."""

    def __init__(
        self,
        position: Vec7,
        *,
        deferred_start: bool = False,
        hold_latency: float = HOLD_LATENCY,
        start_latency: float = 0.0,
        hold_segment: float = HOLD_SEGMENT_SECONDS,
    ) -> None:
        """``deferred_start``: blocks pushed onto an empty planner wait (state ``idle``) until
        :meth:`cycle_start`, as GRBL's auto cycle start does (see :meth:`cycle_start`); without
        it they start at once. ``hold_latency``, ``hold_segment``: see ``HOLD_LATENCY`` and
        ``HOLD_SEGMENT_SECONDS`` (both 0: brake at once)."""
        if not (math.isfinite(hold_latency) and hold_latency >= 0.0):
            raise ValueError(f"hold_latency must be finite and >= 0: {hold_latency}")
        self._position = finite_vec7(position, "position")
        if not (math.isfinite(hold_segment) and hold_segment >= 0.0):
            raise ValueError(f"hold_segment must be finite and >= 0: {hold_segment}")
        self._hold_latency = hold_latency
        self._hold_segment = hold_segment
        self._motion_since = 0.0  # planner clock when the running motion began (its segments)
        self._start_latency = start_latency
        self._delay = 0.0  # left of the start latency: the running block waits that long
        self._deferred = deferred_start
        self.started = True
        """False while queued blocks wait for :meth:`cycle_start` (deferred start); read-only."""
        self._queue: deque[Block] = deque()
        self._junction: deque[float] = deque()  # max squared entry speed of each queued block
        self._entry: list[float] = []  # planned squared entry speeds (index 0: the head)
        self._profile: Profile = STOPPED  # profile of the running block (queue head)
        self._t = 0.0  # time since _profile started
        self._held = False
        self._tail_direction: Vec7 | None = None  # direction_out of the last blending block
        self._tail_speed = 0.0
        self.clock = 0.0
        """Simulated seconds this planner has been advanced."""
        self.starvations = 0
        self.starved_seconds = 0.0
        self.run_outs = 0
        self._ran_out_at: float | None = None
        self.finished = 0
        """Blocks finished so far (read-only: a caller sees whether :meth:`advance` ended some)."""

    # ---- queries ---------------------------------------------------------------------------

    @property
    def running(self) -> Block | None:
        """The block at the head of the queue (running, or stopped by a hold); None when idle
        or while the queued blocks wait for :meth:`cycle_start`."""
        return self._queue[0] if self._queue and self.started else None

    @property
    def blocks(self) -> tuple[Block, ...]:
        """Every queued block, the running one first."""
        return tuple(self._queue)

    @property
    def busy(self) -> bool:
        return bool(self._queue)

    @property
    def free(self) -> int:
        return self.CAPACITY - len(self._queue)

    @property
    def held(self) -> bool:
        return self._held

    @property
    def state(self) -> str:
        if not self._queue or not self.started:
            return "idle"
        if self._held:
            return "hold"
        if self._queue[0].kind == "home_search":
            return "home"
        return "run"

    @property
    def progress(self) -> float:
        """Path coordinate ``s`` of the running block (0 when idle)."""
        return self._profile.s_at(self._t) if self._queue else 0.0

    @property
    def speed(self) -> float:
        """Current speed along the running block's ``s`` (0 when idle or stopped)."""
        if not self._queue or self._queue[0].timed:
            return 0.0
        return self._profile.v_at(self._t)

    @property
    def position(self) -> Vec7:
        """Current joint position (J1..J6, rail): whole steps for blocks planned with steps."""
        if not self._queue:
            return self._position
        return self._queue[0].position_at(self._profile.s_at(self._t))

    def position_steps(self, limits: AxisLimits) -> Steps7:
        """Current position in whole motor steps of ``limits`` (``ValueError`` without steps)."""
        return limits.to_steps(self.position)

    @property
    def planned_position(self) -> Vec7:
        """End of the last queued block: where the next pushed block must start."""
        return self._queue[-1].end if self._queue else self._position

    def estimated_duration(self, block: Block) -> float:
        """Total time of ``block``'s from-rest profile (same as ``block.duration``)."""
        return block.duration

    def time_to_next_change(self) -> float | None:
        """Seconds until the running block ends or a hold finishes decelerating.

        None when idle, and when stopped by a hold (nothing changes until :meth:`resume`).
        """
        if not self._queue or not self.started:
            return None
        left = max(self._profile.duration - self._t, 0.0) + self._delay
        if self._held and left <= SNAP_SECONDS:
            return 0.0 if self._profile.s_end >= self._queue[0].length else None
        return left

    def remaining_time(self) -> float:
        """Seconds until the planner is empty as planned now (``inf`` while held)."""
        if not self._queue:
            return 0.0
        if self._held:
            return math.inf
        if not self.started:
            self._replan(0.0, 0.0)  # as cycle_start() will
        total = [max(self._profile.duration - self._t, 0.0) + self._delay]
        entry = self._entry
        for i in range(1, len(self._queue)):
            block = self._queue[i]
            if block.timed:
                total.append(block.length)
                continue
            v_in = math.sqrt(entry[i])
            v_out = math.sqrt(entry[i + 1]) if i + 1 < len(entry) else 0.0
            total.append(block.profile_from(0.0, v_in, v_out).duration)
        return math.fsum(total)

    # ---- commands --------------------------------------------------------------------------

    def push(self, block: Block) -> None:
        """Queue ``block`` and re-plan (it starts at once if the planner is idle).

        Raises :class:`PlannerFull` without a free slot, ``ValueError`` if the block does not
        start at :attr:`planned_position` (within ``START_TOLERANCE`` per axis).
        """
        if len(self._queue) >= self.CAPACITY:
            raise PlannerFull(f"planner full ({self.CAPACITY} blocks)")
        queue = self._queue
        planned = queue[-1].end if queue else self._position  # self.planned_position
        a, b = block.start, planned
        if a == b:  # (the usual case: no gap)
            gap = 0.0
        elif len(a) == len(b) == 7:  # without a generator (the same maximum)
            gap = max(abs(a[0] - b[0]), abs(a[1] - b[1]), abs(a[2] - b[2]), abs(a[3] - b[3]),
                      abs(a[4] - b[4]), abs(a[5] - b[5]), abs(a[6] - b[6]))  # fmt: skip
        else:
            gap = max(abs(x - y) for x, y in zip(a, b, strict=True))
        if not gap <= START_TOLERANCE:
            raise ValueError(f"block starts at {block.start}, planner ends at {planned}")
        was_empty = not self._queue
        if was_empty:
            self.started = not self._deferred
            self._motion_since = self.clock
            self._tail_direction = None
            if self._ran_out_at is not None:
                self.starvations += 1
                self.starved_seconds += self.clock - self._ran_out_at
                self._ran_out_at = None
        self._queue.append(block)
        self._junction.append(self._junction_limit(block))
        if was_empty:
            self._profile = block.profile_from(0.0)
            self._t = 0.0
            self._entry = [0.0, 0.0]  # (what the re-plan of one block from rest gives)
        if self.started:  # else cycle_start() plans the blocks from rest when they start
            self._replan()

    def advance(self, dt: float) -> None:
        """Move time forward by ``dt`` seconds (``math.inf``: run everything that can run)."""
        if not dt >= 0.0:
            raise ValueError(f"dt must be >= 0, got {dt}")
        if not self._queue or not self.started:  # nothing runs: only the clock goes on
            if dt != math.inf:
                self.clock += dt
            return
        remaining = dt
        if self._delay > 0.0 and self._queue and self.started:
            wait = min(self._delay, remaining)
            self._delay -= wait
            self.clock += wait
            remaining -= wait
            if self._delay > 0.0:
                return
        while self._queue and self.started:
            profile = self._profile
            left = profile.duration - self._t
            if remaining < left - SNAP_SECONDS:
                self._t += remaining
                self.clock += remaining
                return
            left = max(left, 0.0)
            remaining = max(remaining - left, 0.0)
            self.clock += left
            self._t = profile.duration
            if self._held and profile.s_end < self._queue[0].length:
                break  # stopped mid-block, waiting for resume()
            self._finish_head(0.0 if self._queue[0].timed else profile.v_end)
        if math.isfinite(remaining):
            self.clock += remaining

    def hold(self) -> None:
        """Feed hold ``!``: decelerate along the planned path to a stop (state ``hold`` at once).

        Ignored when idle, already held, or homing.
        """
        if self.running is None or self._held or self._queue[0].kind not in HOLDABLE_KINDS:
            return
        self._delay = 0.0
        block = self._queue[0]
        profile, t = self._profile, self._t
        s = profile.s_at(t)
        if block.timed:
            self._profile = block.stop_profile(s, 0.0)
        else:
            # the prepared motion runs on for the latency (within this block), then brakes
            t_brake = min(t + self._hold_delay(), profile.duration)
            brake = block.stop_profile(profile.s_at(t_brake), profile.v_at(t_brake))
            phases = profile.window(t, t_brake) + brake.phases()
            self._profile = Profile(s, profile.v_at(t), phases, brake.s_end, brake.v_end)
        self._t = 0.0
        self._held = True

    def _hold_delay(self) -> float:
        """Seconds from now until a hold brakes: ``HOLD_LATENCY``, then on to the next segment
        boundary of the running motion."""
        ready = self.clock + self._hold_latency
        segment = self._hold_segment
        if segment <= 0.0:
            return self._hold_latency
        segments = math.ceil((ready - self._motion_since) / segment - 1e-9)
        return max(self._motion_since + segments * segment - self.clock, self._hold_latency)

    def resume(self) -> None:
        """Cycle start ``~``: re-plan from the current position and speed (from rest once
        stopped). Ignored when not held."""
        if not self._held:
            return
        self._held = False
        self._motion_since = self.clock  # GRBL prepares its segments anew
        if not self._queue:
            return
        block = self._queue[0]
        s = self._profile.s_at(self._t)
        if block.timed:
            self._profile = constant_rate(s, block.length)
            self._t = 0.0
            return
        self._replan(s, self._profile.v_at(self._t))

    def cycle_start(self, delay: float = 0.0) -> None:
        """Start the queued blocks (GRBL's auto cycle start), the first one ``delay`` seconds
        later than usual (the firmware was busy). A firmware with
        ``deferred_start`` calls this when a block does not fit (the planner is full), when
        its receive buffer has run dry, and before it waits for the planner to empty (``G4``,
        ``M2``, ``$`` commands); no effect when already started or empty."""
        if self.started or not self._queue:
            return
        self.started = True
        self._delay = (0.0 if self._queue[0].timed else self._start_latency) + max(delay, 0.0)
        self._motion_since = self.clock + self._delay
        self._replan(0.0, 0.0)

    def abort(self) -> None:
        """Soft reset: stop at once where the arm is, clear every block and the hold."""
        self._position = self.position
        self._queue.clear()
        self._junction.clear()
        self._entry = []
        self._profile = STOPPED
        self._t = 0.0
        self._held = False
        self._tail_direction = None
        self._ran_out_at = None
        self._delay = 0.0

    def set_position(self, p: Vec7) -> None:
        """Redefine the current position (only while idle; ``RuntimeError`` otherwise)."""
        if self._queue:
            raise RuntimeError("set_position() while blocks are queued")
        self._position = finite_vec7(p, "position")

    # ---- internals -------------------------------------------------------------------------

    def _junction_limit(self, block: Block) -> float:
        """Largest squared entry speed of ``block`` after the current tail; updates the tail."""
        if isinstance(block, JointBlock) and block.length == 0.0:
            return math.inf  # a joint block without motion: the speed passes through it
        if block.timed or block.direction_in is None:  # a block that does not blend
            self._tail_direction = None
            return 0.0
        assert block.direction_in is not None
        previous, previous_speed = self._tail_direction, self._tail_speed
        self._tail_direction = block.direction_out
        self._tail_speed = block.speed
        if previous is None:
            return 0.0
        limit = junction_speed_sqr(
            previous, block.direction_in, block.accel, block.junction_deviation
        )
        return min(limit, block.speed * block.speed, previous_speed * previous_speed)

    def _replan(self, s0: float | None = None, v0: float | None = None) -> None:
        """Reverse and forward passes; a fresh profile for the running block from ``s0`` at
        ``v0`` (default: where and how fast it is now). Nothing changes while held."""
        queue = self._queue
        if not queue or self._held:
            return
        head = queue[0]
        if s0 is None or v0 is None:
            s0 = self._profile.s_at(self._t)
            v0 = self._profile.v_at(self._t)
        n = len(queue)
        if n == 1:  # the passes below over one block: its exit is at rest
            self._entry = [v0 * v0, 0.0]
            if not head.timed:
                self._profile = head.profile_from(s0, v0, 0.0)  # (math.sqrt(0.0))
                self._t = 0.0
            return
        entry = [0.0] * (n + 1)
        following = 0.0  # squared exit speed of block i (entry of i + 1)
        for i in range(n - 1, 0, -1):
            block = queue[i]
            if block.timed:
                entry[i] = following = 0.0
                continue
            entry[i] = following = min(
                self._junction[i], following + 2.0 * block.accel * block.length
            )
        reach = 0.0 if head.timed else v0 * v0 + 2.0 * head.accel * max(head.length - s0, 0.0)
        for i in range(1, n):
            block = queue[i]
            entry[i] = min(entry[i], reach)
            reach = 0.0 if block.timed else entry[i] + 2.0 * block.accel * block.length
        entry[0] = v0 * v0
        self._entry = entry
        if head.timed:
            return
        self._profile = head.profile_from(s0, v0, math.sqrt(entry[1]))
        self._t = 0.0

    def _finish_head(self, v_exit: float) -> None:
        block = self._queue.popleft()
        self._junction.popleft()
        self.finished += 1
        self._position = block.end
        self._t = 0.0
        if not self._queue:
            self._profile = STOPPED
            self._entry = []
            self._held = False  # nothing left to hold
            self._tail_direction = None
            self.run_outs += 1
            self._ran_out_at = self.clock
            return
        head = self._queue[0]
        if self._held:
            self._profile = head.stop_profile(0.0, v_exit) if v_exit > 0.0 else STOPPED
            return
        if head.timed:
            self._profile = head.profile_from(0.0)
            self._entry = [0.0, *self._entry[2:]]
            return
        self._replan(0.0, v_exit)
