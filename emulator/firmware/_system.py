"""The ``$`` system commands: help, settings, ``$G``, ``$#``, ``$I``, ``$N``, ``$C``, ``$X``,
``$RST``, homing (``$H`` and variants) and the 2021 ``$M``."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Final

from .. import motion
from .. import settings as cfg
from ..motion import Vec7
from . import _codes as c
from ._geometry import vec7
from ._machine import N_STARTUP_LINE, Machine, Pending
from ._moves import MIN_FEED
from ._offsets import WorkOffsets
from ._scanner import read_float, uint8

HOMING_RAIL_FACTOR: Final = 1.5
"""ASSUMED: ``$H0`` (arm and rail) searches this many times ``homing_seconds``."""

HOMING_SINGLE_AXIS_FACTOR: Final = 0.4
"""ASSUMED: ``$H1..$H7`` (a single axis) search this fraction of ``homing_seconds``."""

CLASSIC_SEQUENTIAL_HOMING_FACTOR: Final = 29.0691 / 8.1534
"""Classic ``$HH`` (one axis after another) searches this many times ``homing_seconds``: the
firmware tapes' ``$HH`` search ends 29.0694 s after its line end, ``$H``'s 8.1537 s (its
harness's switches; both are followed by the same ~2.3 s return move)."""

HOMED_PLANNING_SECONDS: Final = 5.6e-3
"""After the switch search the firmware plans the return move, then prints its reply (tapes,
``$H`` from the zero pose: the reply comes 5.6 ms after the search's end, a ``Home`` status
for a ``?`` during the search 2.2 ms after it; with that status the reply waits until the
report is produced, then 5.6 ms: ``tests/oracle/test_diff_homing.py::test_homing_phases``,
``tests/integration/test_client.py::test_home_then_moves[classic]``)."""

FREE_MEMORY: Final = 2036
"""The number of the classic ``Free memory:`` line (any number, PROTOCOL 4.3)."""


class SystemCommands:
    """Executes a line starting with ``$``; ``reset`` is the soft reset (``$C`` off, ``$RST``),
    ``run_gcode`` runs a G-code line and returns its status (``$N0=``)."""

    def __init__(
        self, machine: Machine, reset: Callable[[], None], run_gcode: Callable[[str], int]
    ) -> None:
        self.m = machine
        self.reset = reset
        self.run_gcode = run_gcode

    def run_startup_lines(self) -> None:
        """After a reset out of Alarm, the stored ``$N0``/``$N1`` lines run, each printed with
        its reply glued on (oracle: ``G91ok``)."""
        m = self.m
        if m.alarm:
            return
        for text in m.startup_lines:
            if text:
                data = text.encode("latin-1", "replace")
                m.out += data
                m.printed += len(data)
                self.run_gcode(text)

    def _idle_or_alarm(self) -> bool:
        return self.m.state in ("Idle", "Alarm")

    def execute(self, line: str) -> None:
        m = self.m
        if len(line) == 1:
            m.emit_lines(c.HELP)
            m.emit("ok")
            return
        kind = line[1]
        if kind in "$GCX":
            self._simple(line, kind)
            return
        if not self._idle_or_alarm():
            m.error(c.IDLE_ERROR)
            return
        if kind == "#":
            if len(line) != 2:
                m.error(c.INVALID_STATEMENT)
                return
            m.emit_lines(m.work.report(m.modal.g92))
            m.emit("ok")
        elif kind == "H":
            self._home(line)
        elif kind == "I":
            self._build_info(line)
        elif kind == "R":
            self._restore(line)
        elif kind == "N" and len(line) == 2:
            for n, text in enumerate(m.startup_lines):
                m.emit(f"$N{n}={text}")
            m.emit("ok")
        elif kind == "N":
            self._store_startup_line(line)
        elif kind == "M" and m.profile == "2021":
            self._zero_move(line)
        else:
            self._store_setting(line)

    def _simple(self, line: str, kind: str) -> None:
        """``$$``, ``$G``, ``$C``, ``$X`` (allowed in any state but a few)."""
        m = self.m
        if len(line) > 2 and line[2] != "H":
            m.error(c.INVALID_STATEMENT)
            return
        if kind == "$":
            if m.state in ("Run", "Hold"):
                m.error(c.IDLE_ERROR)
                return
            m.emit_lines(cfg.format_dump(m.settings, m.family))
        elif kind == "G":
            m.emit(m.modal.report())
        elif kind == "C":
            if m.check:
                m.emit("[Disabled]")
                m.emit("ok")
                self.reset()
                return
            if m.state != "Idle":
                m.error(c.IDLE_ERROR)
                return
            m.check = True
            m.emit("[Enabled]")
        elif m.alarm:  # $X
            m.emit(c.FEEDBACK_UNLOCKED)
            m.alarm = False
        m.emit("ok")

    def _build_info(self, line: str) -> None:
        m = self.m
        if len(line) == 2:
            suffix = c.BUILD_INFO_SUFFIX[m.family]
            m.emit(f"[{c.GRBL_VERSION}.{c.GRBL_BUILD}:{m.build_info}{suffix}]")
        elif line[2] != "=":
            m.error(c.INVALID_STATEMENT)
            return
        else:
            m.build_info = line[3:]
        m.emit("ok")

    def _restore(self, line: str) -> None:
        m = self.m
        if len(line) != 6 or line[2:5] != "ST=" or line[5] not in "$#*":
            m.error(c.INVALID_STATEMENT)
            return
        if line[5] in "$*":
            before = m.geometry.limits()
            m.settings.clear()  # in place: holders of ``settings`` see the change
            m.settings.update(cfg.default_settings(m.family))
            m.regrid(before)
        if line[5] in "#*":  # GRBL: the coordinate data G54..G59, G28, G30 (tape
            m.work = WorkOffsets()  # scenarios-s4/restore_variants: $# after $RST=# reads 0)
        if line[5] == "*":
            m.startup_lines = [""] * N_STARTUP_LINE
            m.build_info = ""
        m.emit("[Restoring defaults]")
        m.emit("ok")
        self.reset()

    def _store_startup_line(self, line: str) -> None:
        m = self.m
        parsed = read_float(line, 2)
        if parsed is None:
            m.error(c.BAD_NUMBER_FORMAT)
            return
        number, i = parsed
        if i >= len(line) or line[i] != "=":
            m.error(c.INVALID_STATEMENT)
            return
        if m.state != "Idle":
            m.error(c.IDLE_ERROR)
            return
        n = math.trunc(number)
        if not 0 <= n < N_STARTUP_LINE:
            m.error(c.INVALID_STATEMENT)
            return
        text = line[i + 1 :]
        # oracle: the line is executed (and replies) to prove it valid; stored only then
        if not text:
            m.emit("ok")
        elif self.run_gcode(text):
            return
        m.startup_lines[n] = text

    def _store_setting(self, line: str) -> None:
        m = self.m
        parsed = read_float(line, 1)
        if parsed is None:
            m.error(c.BAD_NUMBER_FORMAT)
            return
        parameter, i = parsed
        if i >= len(line) or line[i] != "=":
            m.error(c.INVALID_STATEMENT)
            return
        parsed = read_float(line, i + 1)
        if parsed is None:
            m.error(c.BAD_NUMBER_FORMAT)
            return
        value, i = parsed
        if i != len(line) or parameter > 255:
            m.error(c.INVALID_STATEMENT)
            return
        before = m.geometry.limits()
        m.reply(self._set_setting(uint8(parameter), value))
        m.regrid(before)

    def _set_setting(self, number: int, value: float) -> int:
        """Store setting ``number``; the GRBL status (0 = ok)."""
        m = self.m
        if value < 0 and not (m.profile == "2021" and number in cfg.SIGNED_2021):
            return c.NEGATIVE_VALUE
        spec = cfg.spec(m.family, number)
        if spec is None:
            return c.INVALID_STATEMENT
        if spec.kind != "float":
            ivalue = math.trunc(value)
            if number == 0 and ivalue % 256 < 3:
                return c.SETTING_STEP_PULSE_MIN
            if number in (20, 21, 22):
                ivalue = 1 if ivalue % 256 else 0
            value = float(ivalue % 65536 if number == 26 else ivalue % 256)
        if number == 20 and value and not m.settings[22]:
            return c.SOFT_LIMIT_ERROR
        m.settings[number] = value
        if number == 22 and not value:
            m.settings[20] = 0.0  # GRBL: disabling homing disables soft limits
        return 0

    # homing and $M -------------------------------------------------------------------------

    def _home(self, line: str) -> None:
        m = self.m
        if not m.settings[22]:
            m.error(c.SETTING_DISABLED)
            return
        suffix = line[2:]
        seconds = m.homing_seconds
        sequential = suffix[:1] == "H"
        order: tuple[tuple[int, ...], ...] | None = None
        axes: tuple[int, ...] = motion.ARM_AXES
        home_rail = False
        if m.profile == "classic" and sequential:
            groups = len(motion.SEQUENTIAL_ORDER) * motion.SEQUENTIAL_SEARCH_FRACTION
            seconds *= CLASSIC_SEQUENTIAL_HOMING_FACTOR / groups  # the total, split evenly
        if m.profile == "2021" and not sequential:
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
        start = m.planner.planned_position
        blocks = motion.homing_blocks(
            start,
            seconds,
            m.geometry.limits(),
            sequential,
            order=order,
            axes=axes,
            home_rail=home_rail,
        )
        searches = [b for b in blocks if b.kind == "home_search"]
        homed = {*axes, *((motion.RAIL,) if home_rail else ())}
        m.alarm = False
        m.locked = False  # oracle: even a homing cut short by % leaves the axes unlocked
        if m.profile == "classic":
            m.emit_lines(["", f"Free memory: {FREE_MEMORY}"])

        def finish() -> list[str]:
            zero = vec7([0.0 if j in homed else start[j] for j in range(motion.AXES)])
            m.planner.set_position(zero)
            m.parser_init(feed=0.0)
            self._return_to_zero(zero, homed)
            return list(c.HOMED_LINES[m.family])

        # a ? during the search is answered when it ends (the facade, ``status_deferred``),
        # before the return move is planned and the reply printed
        m.wait(Pending(searches, "searched", finish, planning=HOMED_PLANNING_SECONDS))

    def _return_to_zero(self, zero: Vec7, homed: set[int]) -> None:
        """After the switch search (oracle): each homed axis moves its reset distance
        (``$150..$156``, away from its switch: negative where ``$28`` has its bit) at the homing
        feed ``$24``, state ``Run``; the position reads 0 again when the planner is next idle.
        The parser is free meanwhile."""
        m = self.m
        target = list(zero)
        for k, joint in enumerate(motion.LETTER_TO_JOINT):
            if joint in homed:
                sign = -1.0 if uint8(m.settings[28]) >> k & 1 else 1.0
                target[joint] += sign * m.settings[150 + k]
        delta = [b - a for a, b in zip(zero, target, strict=True)]
        longest = max(abs(d) for d in delta)
        if longest == 0.0:
            return
        feed = m.settings[24] * math.sqrt(math.fsum(d * d for d in delta)) / longest
        if not feed > 0.0:  # ASSUMED: a homing feed $24=0 crawls, as a G1 feed of 0 does
            feed = MIN_FEED
        limits = m.geometry.limits()
        m.planner.push(motion.joint_block(zero, vec7(target), feed, limits))
        m.rezero = zero

    def _zero_move(self, line: str) -> None:
        """2021 ``$M``: rapid move of J1..J6 to zero (ASSUMED details in the package doc)."""
        m = self.m
        if line != "$M":
            m.error(c.INVALID_STATEMENT)
            return
        if m.alarm:
            m.error(c.ALARM_LOCK)
            return
        if m.locked:
            m.emit_lines([*c.refusal_lines(c.TEXT_LOCKED, m.family), "ok"])
            return
        start = m.planner.planned_position
        target = vec7((0.0, 0.0, 0.0, 0.0, 0.0, 0.0, start[6]))
        block = motion.joint_block(start, target, None, m.geometry.limits())
        m.modal.cart = m.geometry.fk(target)
        m.modal.joints = target
        if block.length == 0.0:
            m.emit("ok")
            return
        m.wait(Pending([block], "queued", lambda: ["ok"]))
