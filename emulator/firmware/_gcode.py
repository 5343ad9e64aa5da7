"""STEP 4 of GRBL 0.9j's parser: a valid G-code line executed on the :class:`Machine`."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Final

from .. import motion
from ..motion import Block, Vec7
from . import _codes as c
from ._float32 import single
from ._geometry import Pose, Refusal, pose6
from ._machine import Machine, Pending
from ._modal import ModalState
from ._offsets import ZERO7, with_values
from ._scanner import AXIS_WORDS, GBlock, scan
from ._validation import MM_PER_INCH, CheckedLine, check_block


def waits_for_motion(line: CheckedLine, modal: ModalState) -> bool:
    """Whether ``line`` waits until queued motion has ended before it acts (GRBL 0.9j's
    synchronised spindle and coolant changes; oracle, a line sent behind a 1.6 s move):

    - ``M3``/``M4``/``M5`` that change the output mode (``M3 S0`` and ``M4`` from ``M5``,
      ``M4 E65`` after ``M3``, ``M5`` after either); not ``M3`` after ``M3``, ``M5`` after
      ``M5``;
    - a new ``S`` or ``E`` value while ``M3`` or ``M4`` is on (``S0`` or ``M3 S500`` after
      ``M3 S1000``, ``E40`` after ``M3 S1000``, ``S500`` after ``M4 E65``); the status shows the
      old PWM until the wait ends. With ``M5`` a new ``S``/``E`` is set at once, no wait;
    - ``M8``/``M9`` that change the coolant state (``M8`` from ``M9``, ``M9`` after ``M8``).

    Nothing else waits: ``$`` commands, ``G10``, ``G28``, ``G28.1``, ``G53``, ``G92``, ``M1``,
    ``M20``, ``M50``, ``T``, ``F`` answer at once (``G4``, ``M0``, ``M2`` and ``M30`` wait by
    their own rules). The rest of the line, its motion included, runs after the wait; the
    ``M20``/``M21`` resynchronisation was read before it. Check mode (``$C``) never waits.
    """
    g = line.block
    if g.spindle is not None and g.spindle != modal.spindle:
        return True
    if g.coolant is not None and g.coolant != modal.coolant:
        return True
    return modal.spindle != 5 and (line.pump != modal.pump_pwm or line.valve != modal.valve_pwm)


DWELL_STEP_MS: Final = 50
"""GRBL 0.9j's ``DWELL_TIME_STEP``: a dwell is counted in steps of this many milliseconds."""


def dwell_seconds(p: float) -> float:
    """How long GRBL 0.9j's ``mc_dwell`` waits for ``G4 P<p>`` (seconds): ``floor(20 p)``
    steps of 50 ms, the count stored in a ``uint16_t``, after ``delay_ms`` of the remaining
    whole milliseconds (a ``uint16_t`` too). So the count wraps (tape
    ``scenarios-s4/dwell_overflow_edge``: ``G4 P3277`` is 65540 steps, waits 4 of them: ``ok``
    after 0.201 s) and a fraction of a millisecond is dropped."""
    count = math.floor(single(1000 // DWELL_STEP_MS * single(p)))
    steps = count % 65536
    remainder = math.floor(single(single(1000.0 * single(p)) - steps * DWELL_STEP_MS)) % 65536
    return (remainder + steps * DWELL_STEP_MS) / 1000.0


class GcodeExecutor:
    """Scans, checks and executes one G-code line (prints its replies)."""

    def __init__(self, machine: Machine) -> None:
        self.m = machine
        self.home: Callable[[], None] = lambda: None
        """``M95``: the homing cycle of ``$H`` (the facade sets it; it prints the reply)."""

    def execute(self, line: str) -> int:
        """Run ``line`` and print its replies; its GRBL status (0 when accepted)."""
        m = self.m
        scanned, status = scan(line, m.profile)
        if status:
            self._early_effects(scanned)
            m.error(status)
            return status
        # oracle: a line with M20 or M21 first sets the parser's position to the machine's
        # (where the arm is now, not where queued motion ends)
        origin = m.machine_position() if scanned.coord_mode is not None else m.modal.joints
        checked = check_block(scanned, m.modal, origin, m.geometry, m.work)
        if isinstance(checked, int):
            self._early_effects(scanned)
            m.error(checked)
            return checked
        if not m.check and waits_for_motion(checked, m.modal):
            if m.modal.spindle == 5:  # outputs off: the new PWMs are set without waiting
                m.modal.pump_pwm, m.modal.valve_pwm = checked.pump, checked.valve
            m.wait(Pending([], "idle", lambda: self._run_after_wait(checked)))
            return 0
        self._run(checked)
        return 0

    def _run_after_wait(self, line: CheckedLine) -> list[str]:
        """The rest of a line that waited for the planner to empty (its replies printed)."""
        self._run(line)
        return []

    def _early_effects(self, g: GBlock) -> None:
        """A failing line's ``M50``/``M20``/``M21`` words still act on classic (oracle:
        ``M20 Q1`` -> ``Unsupported command`` and then ``Motion_MODE:1``; ``M50 Q1`` prints
        ``M50: Unlock each axis.`` before its error and unlocks). ASSUMED not on 2021 (its
        vectors show a failing ``M20`` line printing no ``Info`` line)."""
        m = self.m
        if m.profile != "classic":
            return
        if g.unlock:
            m.locked = False
            m.emit(m.info(c.TEXT_M50))
        if g.coord_mode is not None:
            q = m.machine_position()
            m.modal.cart_mode = g.coord_mode == 20
            m.modal.joints = q
            m.modal.cart = m.geometry.fk(q)

    def _set_modal(self, line: CheckedLine) -> list[str]:
        """The modal effects of a valid line; the information lines it prints."""
        m = self.m
        g = line.block
        modal = m.modal
        out: list[str] = []
        modal.feed_mode = line.feed_mode
        modal.feed = line.feed
        modal.pump_pwm = line.pump
        modal.valve_pwm = line.valve
        if g.spindle is not None:
            modal.spindle = g.spindle
        if g.coolant is not None:
            modal.coolant = g.coolant
        if g.plane is not None:
            modal.plane = g.plane
        modal.units = line.units
        modal.distance = line.distance
        if g.coord_select is not None:
            modal.coord_select = g.coord_select
        modal.motion = line.motion_mode
        if g.unlock:
            m.locked = False
            m.alarm = False
            out.append(m.info(c.TEXT_M50))
        if g.coord_mode is not None:
            modal.joints = line.origin
        if g.coord_mode == 20:
            modal.cart_mode = True
            modal.cart = pose6(line.base[:6])
            if m.profile == "2021":
                out.append(m.info(c.TEXT_M20))
        elif g.coord_mode == 21:
            modal.cart_mode = False
            if m.profile == "2021":
                out.append(m.info(c.TEXT_M21))
        return out

    def _refused_target(self, line: CheckedLine, text: str) -> None:
        """Oracle: a move refused because the axes are locked still moves the parser's
        position to its target (``G91 X10`` locked, ``M50``, ``G91 X1`` -> 10.999), and so does
        an unreachable Cartesian target for the commanded pose (``M20 G91 G0 X500`` then
        ``G91 G0 X-300`` is unreachable too); a soft-limit refusal leaves both."""
        m = self.m
        if text == c.TEXT_LOCKED and not line.cart:
            m.modal.joints = line.target
        elif line.cart and text in (c.TEXT_LOCKED, c.TEXT_UNREACHABLE):
            m.modal.cart = pose6(line.target[:6])

    def _store_offsets(self, line: CheckedLine) -> None:
        """``G10 L2``/``L20``, ``G92``, ``G92.1``, ``G28.1``, ``G30.1`` (oracle: as GRBL 0.9j)."""
        m = self.m
        g = line.block
        modal = m.modal
        scale = MM_PER_INCH if line.units == 20 else 1.0
        values = {k: g.words[a] * scale for k, a in enumerate(AXIS_WORDS) if a in g.words}
        selected = modal.coord_select
        if g.nonmodal == 10:
            p = int(g.words["P"])
            system = selected if p == 0 else 53 + p
            if g.words["L"] == 20.0:  # the current position becomes the given value
                values = {k: line.base[k] - v for k, v in values.items()}
            m.work.systems[system] = with_values(m.work.systems[system], values)
        elif g.nonmodal == 92:
            offsets = m.work.systems[selected]
            values = {k: line.base[k] - offsets[k] - v for k, v in values.items()}
            modal.g92 = with_values(modal.g92, values)
        elif g.nonmodal == 921:
            modal.g92 = ZERO7
        elif g.nonmodal == 281:
            m.work.g28 = modal.joints
        else:
            m.work.g30 = modal.joints

    def _go_to_stored(self, line: CheckedLine, start: Vec7) -> list[Block]:
        """``G28``/``G30``: rapid joint moves, through the axis words' point if any (joint
        mode only, ASSUMED), to the stored joints (raises :class:`Refusal`)."""
        m = self.m
        stored = m.work.g28 if line.block.nonmodal == 28 else m.work.g30
        if m.locked:
            raise Refusal(c.TEXT_LOCKED)
        points = (
            [line.target]
            if not line.cart and any(a in line.block.words for a in AXIS_WORDS)
            else []
        )
        blocks: list[Block] = []
        for point in [*points, stored]:
            new, _, _ = m.moves.joint_move(start, point, None, line.feed_mode, check=m.check)
            blocks += new
            start = new[-1].end if new else start
        m.modal.joints = stored
        m.modal.cart = m.geometry.fk(stored)
        return blocks

    def _path_start(self, line: CheckedLine, start: Vec7) -> Pose:
        """The pose a Cartesian path (2021 straight line, arc, ``G05``) starts from: the
        commanded pose, except on a line with ``M20``, which resynchronised the commanded pose
        to where the arm is *now*: its path starts where the queued motion ends (``start``),
        as classic's joint move does. ASSUMED (docs/2021-profile.md): from the resynchronised
        pose, 30 streamed ``M20 G90 G1`` chords of a 20 mm circle took 43 s (a snap back to
        where the arm was at each parse) and left the circle by 6.9 mm; now 5 s, within 0.2."""
        if line.block.coord_mode == 20:
            return self.m.geometry.fk(start)
        return self.m.modal.cart

    def _run(self, line: CheckedLine) -> None:
        m = self.m
        g = line.block
        out = self._set_modal(line)
        ok = "ok"  # the final reply (a refusal text may come first on the same line)
        blocks: list[Block] = []
        hard_limit: Block | None = None
        wait_idle = False
        dwell: list[Block] = []
        if g.nonmodal == 4 and not m.check:
            # The dwell starts where the queued motion ends; the motion of this line is queued
            # after it, and the reply does not wait for that motion (oracle: ``M21 G91 G0 X30
            # G4 P0.2`` answers as its motion starts, like GRBL's dwell before step 19).
            seconds = dwell_seconds(g.words["P"])
            dwell.append(motion.dwell_block(seconds, m.planner.planned_position))
            blocks = list(dwell)
        if g.nonmodal in (10, 92, 281, 301, 921):
            self._store_offsets(line)
        elif g.nonmodal in (28, 30):
            start = blocks[-1].end if blocks else m.planner.planned_position
            try:
                blocks += self._go_to_stored(line, start)
            except Refusal as refusal:
                out += c.refusal_lines(refusal.text, m.family)
        elif line.axis_command and line.motion_mode != 80:
            start = blocks[-1].end if blocks else m.planner.planned_position
            try:
                new_blocks, hard_limit, end_q = m.moves.plan(
                    line.motion_mode,
                    line.cart,
                    start,
                    line.target,
                    line.feed,
                    line.feed_mode,
                    line.arc,
                    cart_start=self._path_start(line, start) if line.cart else m.modal.cart,
                    locked=m.locked,
                    check=m.check,
                )
            except Refusal as refusal:
                out += c.refusal_lines(refusal.text, m.family)
                if refusal.then is not None:  # the first text's line ends before the second
                    out += c.refusal_lines(refusal.then, m.family)[1:]
                elif refusal.text in c.TEXTS_WITHOUT_LINE_END and m.family != "2024":
                    ok = out.pop() + ok
                self._refused_target(line, refusal.text)
            else:
                m.modal.joints = line.target if not line.cart else end_q
                blocks += new_blocks
                if line.cart:
                    m.modal.cart = pose6(line.target[:6])
        if out:
            m.emit_lines(out)
        if g.home and not m.check:
            self.home()  # tapes: a bare M95 homes as $H does (the rest of the line ASSUMED first)
            return

        flow = g.flow
        if flow in (0, 2, 30) and not m.check:
            wait_idle = True
        if dwell:
            blocks = blocks[len(dwell) :]
        if not blocks and not wait_idle and not dwell:
            if flow in (2, 30):
                m.modal.program_end()
                m.emit("[Pgm End]")
            m.emit(ok)
            return
        # what m.wait(Pending(blocks, "queued", ...)) does when every block has a free slot
        if (
            not wait_idle
            and not dwell
            and flow not in (0, 2, 30)
            and m.pending is None
            and len(blocks) <= m.planner.free
        ):
            for block in blocks:
                m.planner.push(block)
            if hard_limit is not None:
                m.limit_blocks.append(hard_limit)
            m.emit(ok)
            return

        def finish() -> list[str]:
            if flow in (2, 30):
                m.modal.program_end()
                return ["[Pgm End]", ok]
            if flow == 0:
                m.hold = True
                return []
            return [ok]

        then = Pending([], "released", lambda: ["ok"]) if flow == 0 else None
        until = "idle" if wait_idle else "queued"
        pending = Pending(blocks, until, finish, then=then, hard_limit=hard_limit)
        if dwell:
            pending = Pending(dwell, "idle", list, then=pending)
        m.wait(pending)
