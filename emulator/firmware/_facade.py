"""The :class:`Firmware` facade: bytes in, bytes out, an explicit clock; realtime bytes and the
loop that feeds received lines to the ``$`` commands and the G-code executor."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import Final

from .. import motion
from ..motion import Vec7
from . import _codes as c
from ._gcode import GcodeExecutor
from ._geometry import switch_pins
from ._linebuffer import RX_BUFFER_SIZE, RX_CAPACITY
from ._linecost import ParserWork, line_seconds, wait_point_seconds
from ._machine import Machine
from ._reports import banner, status_line
from ._scanner import read_float
from ._system import SystemCommands
from ._uart import Transmitter
from ._wire import BYTE_SECONDS, Wire

DEFAULT_HOMING_SECONDS: Final = 10.0
"""Switch search of ``$H`` on 2021 when the constructor is not told otherwise (PROTOCOL 9)."""

CLASSIC_HOMING_SECONDS: Final = 8.1534
"""Switch search of ``$H`` on classic, from the zero pose: the firmware tapes' search ends
8.1537 s after ``$H``'s line end was written (a ``Home`` status for a ``?`` meanwhile starts
2.2 ms later, the reply 5.6 ms later: :data:`._system.HOMED_PLANNING_SECONDS`; then the 2.3 s
return move), less this model's 0.3 ms from that byte to the search's start; with the
simulator's assumed switches (no device log gives a time)."""

ALARM_STALL_SECONDS: Final = 0.5003
"""After printing an alarm the firmware stalls before it goes on (tapes: the next line, ``ok``
of a line in progress or ``[Reset to continue]``, starts 500.6 ms after the alarm's first
byte, the reset's banner 500.9-501.0 ms: ``test_reset_during_homing``, ``test_hard_limit``,
``test_reset_during_motion``); realtime bytes meanwhile are lost (the restart clears GRBL's
flags; no tape sends any), other bytes enter the ring, which the reset empties."""

MOTION_END_HISTORY: Final = 64
"""How many ends of motion :attr:`Firmware.motion_end_times` keeps."""

STATUS_DURING_CRITICAL_ALARM: Final = False
"""Whether ``?`` is answered after a hard limit, before the reset. GRBL 0.9j's critical-event
loop does not answer it (its status report there is commented out as a TODO); PROTOCOL 6.1:
"nothing but ``%`` is processed until reset"."""

BOOT_SECONDS: Final = 0.030
"""After a soft reset the firmware prints its banner before it reads a line (oracle: ~29 ms
from the reset to ``Using reset pos!``, bound by the UART's transmit rate). Lines that arrive
meanwhile wait; a ``?`` that arrives meanwhile is answered first when the boot ends, before
those lines (oracle: ``%$I\nG4 P0\n?`` prints the banner, the status, then ``$I``'s reply)."""

RESET_DEAF_SECONDS: Final = 0.00035
"""A ``?`` that arrives this soon after the ``%`` is lost: the reset re-initialises the
firmware's realtime flags after the byte was flagged (oracle: lost 100-300 us after ``%``,
answered from 400 us; the bytes of lines are kept)."""


class _MachineViews:
    """The read-only views of the firmware's state that :class:`Firmware` offers."""

    _m: Machine

    def status_line(self) -> str:
        """The status report at this instant, without its ``\\r\\n`` (PROTOCOL 5)."""
        return status_line(self._m)

    @property
    def state(self) -> str:
        """The state word of the status report (``Idle``, ``Run``, ``Hold``, ``Home``, ...)."""
        return self._m.state

    @property
    def joints(self) -> Vec7:
        """Current joint position: J1..J6 (degrees) and the rail (mm)."""
        return self._m.planner.position

    @property
    def planner(self) -> motion.Planner:
        """The look-ahead planner (read-only use: its ``starvations``, ``run_outs`` and
        ``starved_seconds`` counters, ``state``, ``blocks``); the control channel reads it."""
        return self._m.planner

    @property
    def rx_free(self) -> int:
        """Free bytes in the receive ring (127 when empty)."""
        return self._m.rx.free

    @property
    def rx_lost(self) -> int:
        """Bytes lost so far because the receive ring was full."""
        return self._m.rx.lost

    @property
    def locked(self) -> bool:
        """True while the axes are locked (power-on / reset lock; ``M50`` or homing clears it)."""
        return self._m.locked

    @property
    def parser_blocked(self) -> bool:
        """True while received lines wait (planner full, homing search, dwell, hold, alarm)."""
        return self._m.blocked()


class Firmware(_MachineViews):
    """A virtual Mirobot controller: call :meth:`receive`, :meth:`advance`, :meth:`read_output`.

    ``profile`` is ``"classic"`` (20191228_2) or ``"2021"`` (20210516); ``homing_seconds`` the
    switch search of ``$H`` (default :data:`CLASSIC_HOMING_SECONDS` on classic,
    :data:`DEFAULT_HOMING_SECONDS` on 2021). The arm is powered on at
    construction: the banner is already in the output.
    """

    def __init__(
        self,
        profile: str = "2021",
        *,
        homing_seconds: float | None = None,
        byte_seconds: float = BYTE_SECONDS,
    ) -> None:
        if profile not in c.PROFILES:
            raise ValueError(f"unknown firmware profile {profile!r}: not one of {c.PROFILES}")
        if homing_seconds is None:
            homing_seconds = (
                CLASSIC_HOMING_SECONDS if profile == "classic" else DEFAULT_HOMING_SECONDS
            )
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
        self._m = Machine(profile, self.homing_seconds)
        self._wire = Wire(byte_seconds)
        self._parser = ParserWork(self._wire)  # the work on the line ``Machine.parsing``
        self._parse_started = 0.0
        self._status_after_parse: float | None = None  # when a ``?`` came during the parse
        self._boot_until: float | None = None
        """When the banner after a soft reset is printed (``BOOT_SECONDS``): lines wait."""
        self._reset_at = -math.inf
        self._status_after_boot = False
        """``?`` arrived during the boot: answered when it ends, before any line."""
        self._after_stall: Callable[[], None] | None = None
        """What follows the stall after an alarm (:meth:`_stall`; None: no stall)."""
        self.uart = Transmitter()
        """The firmware's transmitter; the server sets its ``byte_seconds`` (:mod:`._uart`)."""
        self.settings: dict[int, float] = self._m.settings
        self._gcode = GcodeExecutor(self._m)
        self._system = SystemCommands(self._m, self.reset, self._gcode.execute)
        self._gcode.home = lambda: self._system.execute("$H")  # M95
        self._m.reset_condition(interrupted=False, power_on=True)
        self._m.parser_init(feed=200.0)
        self._m.emit_lines(banner(self._m))
        self.uart.sync(self._m.printed, self.now)  # the power-on banner is out before any host

    # ------------------------------------------------------------------------------------------
    # public API

    def receive(self, data: bytes) -> None:
        """Bytes from the host, written now: they arrive one byte time apart (:mod:`._wire`;
        run the clock to see their effect). On arrival realtime bytes act at once wherever
        they are; the others enter the 128-byte receive ring (lost when it is full) and
        complete lines are parsed (:mod:`._linecost`) and executed as soon as the parser is free
        (not waiting for the planner, a homing search, a dwell or a hold).
        """
        self._wire.send(bytes(data), self.now)
        due = self._wire.take_due(self.now)
        if due:
            self._deliver(due)
        if self._parser.until is not None:
            self._parser.more_bytes()  # bytes that arrive during a parse delay it
        if self._m.printed != self.uart.seen:
            self.uart.sync(self._m.printed, self.now)

    def _deliver(self, data: bytes) -> None:
        """Bytes that have arrived at the UART (:meth:`.LineBuffer.arrive`)."""
        self._m.rx.arrive(data, self._pump_if_free, self._realtime)

    def _pump_if_free(self) -> None:
        m = self._m  # (not m.blocked(), without the call)
        if (
            m.pending is None
            and m.parsing is None
            and not (m.hold or m.suspended or m.critical or m.booting)
        ):
            self._pump(waited=False)

    def advance(self, dt: float) -> None:
        """Run the simulated clock ``dt`` seconds (``math.inf``: until nothing changes by itself).

        Lines waiting for the planner are executed as blocks finish, their replies printed.
        """
        if not dt >= 0.0:
            raise ValueError(f"dt must be >= 0, got {dt}")
        m, uart, wire, parser = self._m, self.uart, self._wire, self._parser
        planner = m.planner
        end = self.now + dt
        self._service()
        zero_steps = 0
        next_change, next_arrival = planner.time_to_next_change, wire.next_event
        while True:
            now = self.now
            uart.sync(m.printed, now)  # what the last events printed, printed then
            step = next_change()
            # the earliest of the planner's change, the parse's end, the next arrival, the boot
            if (at := parser.until) is not None:
                wait = at - now if at > now else 0.0  # max(at - now, 0.0)
                if step is None or wait < step:  # min(step, wait)
                    step = wait
            if (arrival := next_arrival()) is not None:
                wait = arrival - now if arrival > now else 0.0
                if step is None or wait < step:
                    step = wait
            if (at := self._boot_until) is not None:
                wait = at - now if at > now else 0.0
                if step is None or wait < step:
                    step = wait
            if step is None:
                if not math.isinf(end):
                    planner.advance(end - now)  # its clock times the starvations
                    self.now = end
                break
            left = end - now
            finished = planner.finished
            if step > left:
                # within SNAP_SECONDS of a block end the planner finishes the block here
                planner.advance(left)
                self.now = end
                if planner.finished != finished:
                    self._block_done()
                if arrival is not None and (due := wire.take_due(self.now)):  # (None: no bytes)
                    self._deliver(due)  # the bytes arrived by ``end``
                break
            planner.advance(step)
            self.now = now = now + step
            zero_steps = zero_steps + 1 if step == 0.0 else 0
            if planner.finished != finished:
                self._block_done()
            if arrival is not None and (due := wire.take_due(self.now)):
                self._deliver(due)  # before the parse ends: a full ring lost what came meanwhile
            if self._boot_until is not None and self._boot_until <= self.now:
                self._finish_boot()
            if parser.until is not None and parser.until <= self.now:
                self._finish_parse()
            if zero_steps > 100_000:  # pragma: no cover - a planner bug, never loop forever
                break
        self._service()

    def _block_done(self) -> None:
        """After blocks finished: an end of motion if the planner ran empty (before the waiting
        lines can refill it: ``G4 P0`` between moves), then carry on."""
        m = self._m
        if not m.planner.busy:
            self.motion_end_times.append(self.now)
            self.motion_ends += 1
            if m.rezero is not None:
                m.planner.set_position(m.rezero)
                m.rezero = None
        if m.limit_blocks and m.switch_reached():
            self._stall(m.reset_to_continue)
            return
        self._service()

    def read_output(self) -> bytes:
        """Everything printed since the last call (each line ends ``\\r\\n``)."""
        out = bytes(self._m.out)
        self._m.out.clear()
        return out

    def next_deadline(self) -> float | None:
        """Simulated time of the next internal change (a block ends, a line is parsed), None
        when nothing changes by itself."""
        deadline = self._m.planner.time_to_next_change()
        if deadline is not None:
            deadline += self.now
        arrival = self._wire.next_event()
        for at in (self._parser.until, arrival, self._boot_until):
            if at is not None and (deadline is None or at < deadline):
                deadline = at
        return deadline

    def reset(self) -> None:
        """Soft reset, exactly as if ``%`` had arrived (ignored while the firmware stalls after
        an alarm, :data:`ALARM_STALL_SECONDS`)."""
        m = self._m
        if self._after_stall is not None:
            return
        alarm, interrupted = m.reset_alarm()
        owed_ok = m.pending is not None or m.line_cut_short  # printed with the banner
        m.clear_on_reset()
        self._parser.clear()  # the line being parsed is dropped
        self._status_after_parse = None
        m.reset_condition(interrupted=interrupted)
        if alarm:  # motion stopped at once; the firmware restarts after its stall
            self._stall(lambda: self._restart(owed_ok))
        else:
            self._restart(owed_ok)

    def _restart(self, owed_ok: bool) -> None:
        """The reset's restart: the line in progress (homing, a dwell, a wait) ends with ``ok``
        (oracle), the receive ring is emptied, the banner printed; lines wait for the boot."""
        m = self._m
        if owed_ok:
            m.emit("ok")
        m.rx.clear()
        m.parser_init(feed=200.0)
        m.emit_lines(banner(m))
        self._system.run_startup_lines()
        self._reset_at = self.now
        self.uart.reset()
        self._status_after_boot = False
        self._boot_until = self.now + BOOT_SECONDS
        m.booting = True

    def _stall(self, after: Callable[[], None]) -> None:
        """The firmware stalls :data:`ALARM_STALL_SECONDS` after printing an alarm (no line is
        read, realtime bytes are lost, bytes still enter the ring); then ``after``."""
        self._after_stall = after
        self._boot_until = self.now + ALARM_STALL_SECONDS
        self._m.booting = True

    def _finish_boot(self) -> None:
        """The banner is out: a ``?`` received meanwhile is answered, then lines are read (or
        the stall after an alarm ended: what follows it)."""
        m = self._m
        self._boot_until = None
        m.booting = False
        after, self._after_stall = self._after_stall, None
        if after is not None:
            after()
        elif self._status_after_boot:
            self._status_after_boot = False
            if not m.critical:
                self.uart.print_report(m, self.now)
        self._service()

    def trigger_hard_limit(self, axis: int = 1) -> None:
        """Fault injection: a limit switch (``axis``, informative) closes now.

        ``axis`` is the joint number (1..6, 7 = the rail) whose switch closes. Motion stops at
        once, ``<pins>ALARM: Hard limit`` and ``[Reset to continue]`` are printed and nothing but
        ``%`` is processed until a reset. Ignored while already in that state.
        """
        if not self._m.critical:
            self._m.hard_limit_alarm(switch_pins(axis))
            self._stall(self._m.reset_to_continue)

    @property
    def input_deadline(self) -> float | None:
        """When received bytes next arrive (a line end or realtime byte, :mod:`._wire`), the
        line being parsed is done (:mod:`._linecost`) or the boot after a reset ends
        (``BOOT_SECONDS``); None when nothing is in transit, being parsed or booting."""
        times = [self._wire.next_event(), self._parser.until, self._boot_until]
        return min((t for t in times if t is not None), default=None)

    # ------------------------------------------------------------------------------------------
    # realtime bytes

    def _realtime(self, byte: int) -> None:
        m = self._m
        if self._after_stall is not None:
            return  # the stall after an alarm: the restart clears the realtime flags
        if byte == 0x25:  # %
            self.reset()
            self._service()
            return
        if m.critical and not (byte == 0x3F and STATUS_DURING_CRITICAL_ALARM):
            return  # nothing but % until reset (GRBL's critical-event loop)
        if byte == 0x3F:  # ?
            running = m.planner.running
            if m.booting:
                if self.now - self._reset_at >= RESET_DEAF_SECONDS:
                    self._status_after_boot = True  # answered when the banner is out
            elif running is not None and running.kind == "home_search" and m.silent_homing:
                m.status_deferred = True  # oracle: the homing search answers no ``?``
            elif m.parsing is not None:
                if self._status_after_parse is None:  # later ones are merged into its report
                    self._status_after_parse = self.now
            elif not self.uart.merges(self.now):  # else merged into the report being printed
                self.uart.print_report(m, self.now)
        elif byte == 0x21:  # !
            m.feed_hold()
        elif byte == 0x40:  # @ (oracle: lines wait until ~; motion and the state go on)
            m.suspended = True
        elif byte == 0x7E and (m.hold or m.suspended):  # ~
            if m.hold and m.planner.speed > 0.0:
                return  # oracle: a ~ while the hold still decelerates is dropped (stays Hold)
            m.suspended = False
            if m.hold:
                m.hold = False
                m.planner.resume()
            self._service()

    # ------------------------------------------------------------------------------------------
    # the main loop: pending lines, received bytes

    def _service(self) -> None:
        """Push waiting blocks, finish waiting lines, then start parsing a received line."""
        m = self._m
        if m.pending is not None and not m.progress_pending():
            return
        if m.held_reply is not None:  # its work runs as a parse (a deferred ? answered first)
            self._parse_started = self.now
            self._parser.hold(m, self.now, self.uart)
            return
        if m.parsing is not None or m.hold or m.suspended or m.critical or m.booting:
            return  # (m.blocked(): the waiting line is done)
        if m.rx.ring:
            self._pump()
        elif not m.planner.started:
            m.start_cycle()  # what _pump does without a line

    def _pump(self, *, waited: bool = True) -> None:
        """Start parsing the next complete line of the receive ring (the parser is free; it
        ``waited`` there, or came just now); without one, GRBL's auto cycle start."""
        m = self._m
        line = m.rx.take_line()
        if line is None:
            m.start_cycle()
            return
        m.parsing = line
        seconds, self._parser.work = line_seconds(m, line, waited=waited)
        self._parse_started = self.now
        self._parser.begin(m, self.now, seconds)

    def _finish_parse(self) -> None:
        """The parser is done with its line: execute it (:class:`~._linecost.ParserWork`)."""
        m, parser = self._m, self._parser
        line = m.parsing
        m.parsing = None
        reply = parser.done()
        if line is None:  # pragma: no cover - only called with a line in progress
            return
        requested, self._status_after_parse = self._status_after_parse, None
        early = (  # a ? came before the held line's wait
            requested is not None
            and requested <= self._parse_started + wait_point_seconds(line.text)
        )
        m.report_before_start = self._report_now if early else None  # at the line's own wait
        if m.critical:
            m.line_cut_short = True  # a hard limit meanwhile: the reset prints its ok
        elif reply is not None:  # the block is planned: the line's reply, then the next line
            m.emit_bytes(reply)
        elif line.overflow:
            m.error(c.OVERFLOW)
        elif parser.execute(m, line, self._execute_line, self.now):
            # the reply waits while the block is planned; a ? meanwhile is answered after it
            self._status_after_parse, m.report_before_start = requested, None
            return
        if requested is not None and not (early and m.report_before_start is None):
            m.report_before_start = self._report_now  # before the main loop's cycle start
        self._service()
        if m.report_before_start is not None:  # a further line: after this line's reply
            self._report_now()

    def _report_now(self) -> float:
        return self.uart.report_before_start(self._m, self.now)

    def _execute_line(self, line: str) -> None:
        m = self._m
        if not line:
            m.emit("ok")
        elif line[0] == "$":
            self._system.execute(line)
        elif m.alarm and not m50_allowed_in_alarm(m.profile, line):
            m.error(c.ALARM_LOCK)
        else:
            self._gcode.execute(line)


def m50_allowed_in_alarm(profile: str, line: str) -> bool:
    """ASSUMED: on 2021 a bare ``M50`` unlocks even in Alarm (the manual's power-on use)."""
    if profile != "2021" or line[:1] != "M":
        return False
    parsed = read_float(line, 1)
    return parsed is not None and parsed == (50.0, len(line))


__all__ = ["RX_BUFFER_SIZE", "RX_CAPACITY", "Firmware"]
