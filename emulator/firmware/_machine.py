"""The controller's shared state: settings, planner, modal state, machine flags, the output
and the line that waits for the planner (:class:`Pending`). The ``$`` commands, the G-code
executor and the :class:`~mirobot_emulator.firmware.Firmware` facade all work on one
:class:`Machine`."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from .. import motion
from .. import settings as cfg
from ..motion import Block, Planner, Vec7
from . import _codes as c
from ._geometry import FW_LETTERS, Geometry
from ._linebuffer import LineBuffer, ReceivedLine
from ._modal import ModalState
from ._moves import MoveBuilder
from ._offsets import WorkOffsets

N_STARTUP_LINE = 2  # GRBL 0.9j config.h
HOLDABLE = motion.HOLDABLE_KINDS


@dataclass
class Pending:
    """A line whose final reply waits for the planner (the parser is blocked meanwhile).

    ``blocks`` are pushed as slots free up; then ``until`` must hold: ``"queued"`` (nothing
    more), ``"idle"`` (the planner is empty), ``"searched"`` (no homing search left) or
    ``"released"`` (the feed hold is released). ``finish`` then acts and returns the lines to
    print (the final reply last); ``then`` is the next stage, if any.
    """

    blocks: list[Block]
    until: str
    finish: Callable[[], list[str]]
    then: Pending | None = None
    hard_limit: Block | None = None
    planning: float = 0.0
    """Seconds of work after ``finish`` before its final reply is printed (planning the block
    ``finish`` queued): the reply, the next line and the queued blocks' start wait for it."""


class Machine:
    """Everything the firmware knows between two bytes, and how it prints."""

    def __init__(self, profile: str, homing_seconds: float) -> None:
        self.family = profile
        """The firmware family: its texts, banner, settings list (``codes.PROFILES``)."""
        self.profile = c.BEHAVES_AS[profile]
        """The profile whose behaviour the family has (2024 behaves as 2021)."""
        self.homing_seconds = homing_seconds
        self.silent_homing = not c.ANSWERS_STATUS_WHILE_HOMING[profile]
        """No ``?`` is answered during the homing search (oracle; not on 2024)."""
        self.settings: dict[int, float] = cfg.default_settings(profile)
        self.geometry = Geometry(profile, self.settings)
        self.moves = MoveBuilder(self.geometry, self.settings)
        self.planner = Planner(
            motion.ZERO, deferred_start=True, start_latency=motion.CYCLE_START_LATENCY
        )
        self.modal = ModalState()
        self.work = WorkOffsets()
        self.rx = LineBuffer()
        self.out = bytearray()
        self.printed = 0
        """Bytes printed since power-on (the transmitter's clock counts them, :mod:`._uart`)."""
        self.pending: Pending | None = None
        self.parsing: ReceivedLine | None = None
        """The line the parser is working on (see :mod:`._linecost`); its effects and reply
        come when the work is done."""
        self.limit_blocks: list[Block] = []
        """Blocks that end on a limit switch: the alarm fires when one of them is done."""
        self.startup_lines = [""] * N_STARTUP_LINE
        self.build_info = ""
        self.alarm = False
        self.critical = False
        """A hard-limit alarm: nothing but ``%`` is processed until reset."""
        self.locked = True
        self.hold = False
        self.suspended = False
        self.status_deferred = False
        self.held_reply: tuple[bytes, float] | None = None
        """A finished :class:`Pending`'s reply and its ``planning`` seconds: the facade prints
        it when that work is done (:meth:`progress_pending`)."""
        self.line_cut_short = False
        """A hard limit stopped a line in progress: the reset prints its ``ok``."""
        """``?`` arrived during a homing search: answered once when the search ends."""
        self.rezero: Vec7 | None = None
        """After homing's return move: the position to read when the planner is next idle."""
        """``@`` received: lines wait until ``~`` (the state word does not change)."""
        self.check = False
        self.booting = False
        """The banner after a soft reset is being printed: received lines wait."""
        self.report_before_start: Callable[[], float] | None = None
        """A ``?`` arrived while the current line was parsed: :meth:`start_cycle` prints its
        report (returning the seconds until it is produced) before queued blocks start."""

    # output ---------------------------------------------------------------------------------

    def emit(self, line: str) -> None:
        data = line.encode("latin-1", "replace") + b"\r\n"
        self.out += data
        self.printed += len(data)

    def withdraw(self, mark: int) -> bytes:
        """Take back what was printed since the output held ``mark`` bytes (it is printed
        later with :meth:`emit_bytes`: a reply that waits for the planning of its block)."""
        data = bytes(self.out[mark:])
        del self.out[mark:]
        self.printed -= len(data)
        return data

    def emit_bytes(self, data: bytes) -> None:
        self.out += data
        self.printed += len(data)

    def emit_lines(self, lines: Sequence[str]) -> None:
        for line in lines:
            self.emit(line)

    def error(self, status: int) -> None:
        self.emit(c.error_line(self.family, status))

    def reply(self, status: int) -> None:
        """``ok`` for status 0, else the error line."""
        if status:
            self.error(status)
        else:
            self.emit("ok")

    def info(self, text: str) -> str:
        """``text`` as the profile prints an information line."""
        if self.family == "2024":
            return f"Info,{text}"  # EVIDENCE-NEWER.md 2: no space
        return text if self.profile == "classic" else f"Info, {text}"

    # state ----------------------------------------------------------------------------------

    @property
    def state(self) -> str:
        """The state word of the status report (``Idle``, ``Run``, ``Hold``, ``Home``, ...)."""
        if self.alarm or self.critical:
            return "Alarm"
        if self.hold:
            return "Hold"
        planner_state = self.planner.state
        if planner_state == "home":
            return "Home"
        if planner_state == "hold":
            return "Hold"
        if self.check:
            return "Check"
        running = self.planner.running
        if planner_state == "run" and not (running is not None and running.kind == "dwell"):
            return "Run"
        return "Idle"  # oracle: a G4 dwell reports Idle

    def reset_condition(self, *, interrupted: bool, power_on: bool = False) -> None:
        """Alarm after a reset that interrupted motion (oracle; PROTOCOL 3, both profiles) and
        at the 2021 profile's power-on (PROTOCOL 1); an Alarm survives a reset (oracle: a second
        ``%`` after ``ALARM: Abort during cycle`` still reports ``Alarm``; GRBL keeps its state),
        so only ``$X``, ``M50`` or homing clear it. The axis lock is not touched: only power-on
        sets it (oracle)."""
        self.alarm = interrupted or (power_on and self.profile == "2021") or self.alarm

    def regrid(self, before: motion.AxisLimits) -> None:
        """The steps per degree changed (a ``$`` setting, ``$RST``): GRBL keeps the machine
        position in motor steps, so the idle arm's angles are its steps on the new grid (a
        block from an angle off the grid would not start where the planner ends)."""
        after = self.geometry.limits()
        if after.steps is None or before.steps == after.steps:
            return
        if self.planner.blocks:  # (never: settings are refused while motion is queued)
            return
        # (from no steps at all, a ``$10x=0`` ideal machine: the nearest whole steps)
        grid = after if before.steps is None else before
        self.planner.set_position(after.from_steps(grid.to_steps(self.planner.position)))

    def parser_init(self, *, feed: float) -> None:
        """GRBL ``gc_init`` with ``feed``; the pose is the FK of the planned joints."""
        q = self.planner.planned_position
        self.modal.init(feed=feed, joints=q, pose=self.geometry.fk(q))

    def moving(self) -> bool:
        """True when the arm is physically in motion (a reset then loses position)."""
        running = self.planner.running
        if running is None or running.kind == "dwell":
            return False
        if self.planner.held:
            return self.planner.time_to_next_change() is not None
        return True

    def blocked(self) -> bool:
        """True while received lines wait (planner full, homing, dwell, hold, alarm)."""
        return (
            self.pending is not None
            or self.parsing is not None
            or self.hold
            or self.suspended
            or self.critical
            or self.booting
        )

    def feed_hold(self) -> None:
        """``!``: decelerate to a hold; lines wait until ``~`` (GRBL ignores it in Alarm, check
        mode and homing)."""
        running = self.planner.running
        if self.alarm or self.check or (running is not None and running.kind not in HOLDABLE):
            return
        self.hold = True
        self.planner.hold()

    def machine_position(self) -> Vec7:
        """Where the arm is now, in whole steps: what ``M20``/``M21`` resynchronise to."""
        return self.geometry.limits().quantise(self.planner.position)

    def hard_limit_alarm(self, pins: int = 0) -> None:
        """A limit switch closed: stop, print the alarm, refuse everything but ``%``.

        ``pins``: the closed switches by firmware axis bit (a..g = bits 0..6); the oracle prints
        them as 8 binary digits right before the text (``00010000ALARM: Hard limit``: J1)."""
        if self.family == "2024":  # ASSUMED: the axis letter of the lowest closed switch
            letters = [FW_LETTERS[k] for k in range(7) if pins >> k & 1]
            self.emit(c.alarm_line(self.family, "Hard limit", (letters or [""])[0]))
        else:
            self.emit(f"{pins:08b}ALARM: Hard limit")  # [Reset to continue] after the stall
        self.planner.abort()
        self.limit_blocks.clear()
        self.line_cut_short = self.line_cut_short or self.pending is not None
        self.pending = None
        self.hold = False
        self.alarm = True
        self.critical = True

    def reset_to_continue(self) -> None:
        """The hard-limit alarm's second line (after the firmware's stall)."""
        self.emit(c.FEEDBACK_RESET_TO_CONTINUE)

    def reset_alarm(self) -> tuple[bool, bool]:
        """A soft reset arrived: the alarm it prints if it interrupts homing or motion, then
        (printed, interrupted); a hard-limit alarm is interrupted, and survives the reset."""
        if self.critical:
            return False, True
        running = self.planner.running
        if running is not None and running.kind == "home_search":
            self.emit(c.alarm_line(self.family, "Homing fail"))
        elif self.moving():
            self.emit(c.alarm_line(self.family, "Abort during cycle"))
        else:
            return False, False
        return True, True

    def switch_reached(self) -> bool:
        """After blocks finished: if one that ran into a limit switch (``limit_blocks``) is done,
        the hard-limit alarm (True)."""
        queued = self.planner.blocks
        for block in self.limit_blocks:
            if not any(b is block for b in queued):
                self.hard_limit_alarm(self.geometry.limit_pins(self.planner.position))
                return True
        return False

    def clear_on_reset(self) -> None:
        """What a soft reset clears: motion, received bytes, the waiting and parsed line, the
        hold, the check mode and a hard-limit lock."""
        self.line_cut_short = False
        self.planner.abort()
        self.rx.clear()
        self.pending = None
        self.parsing = None
        self.limit_blocks.clear()
        self.hold = False
        self.suspended = False
        self.status_deferred = False
        self.held_reply = None
        self.rezero = None
        self.check = False
        self.critical = False
        self.report_before_start = None

    def start_cycle(self) -> None:
        """GRBL's auto cycle start. Its realtime step prints a requested status report before
        it starts the cycle, so a ``?`` that arrived during the parse of a line that then waits
        finds queued blocks not yet started (``Idle`` at the old pose), and they start only
        once the report is produced (oracle: ``M21 G90 X30 F300`` and ``M4 E40 S500`` written
        at once, ``?`` 0.3 ms after the move's ``ok``: ``Idle``, motion ends 12.5 ms later than
        with the ``?`` 0.1 ms later, ``Run``; the report's 175 bytes through the transmit
        ring)."""
        if self.planner.started:
            return  # nothing waits for a cycle start
        report = self.report_before_start
        if report is not None and self.planner.blocks:
            self.report_before_start = None
            self.planner.cycle_start(delay=report())
        else:
            self.planner.cycle_start()

    # the waiting line -----------------------------------------------------------------------

    def wait(self, pending: Pending) -> None:
        """Make ``pending`` the waiting line and progress it as far as possible now."""
        self.pending = pending
        self.progress_pending()

    def progress_pending(self) -> bool:
        """Advance the waiting line; True when it is finished (the parser is free again)."""
        while self.pending is not None:
            p = self.pending
            while p.blocks and self.planner.free > 0:
                self.planner.push(p.blocks.pop(0))
            if p.blocks or p.until != "queued":
                self.start_cycle()  # GRBL's auto cycle start: planner full, or a wait
            if p.blocks:
                return False
            if p.hard_limit is not None:
                self.limit_blocks.append(p.hard_limit)
                p.hard_limit = None
            if p.until != "queued" and not self._pending_done(p.until):
                return False
            self.pending = p.then
            lines = p.finish()
            if p.planning and lines:
                self.emit_lines(lines[:-1])
                reply = lines[-1].encode("latin-1", "replace") + b"\r\n"
                self.held_reply = (reply, p.planning)
                return True
            self.emit_lines(lines)
        return True

    def _pending_done(self, until: str) -> bool:
        if until == "queued":
            return True
        if until == "idle":
            return not self.planner.busy
        if until == "searched":
            return not any(b.kind == "home_search" for b in self.planner.blocks)
        if until == "released":
            return not self.hold
        raise AssertionError(until)  # pragma: no cover
