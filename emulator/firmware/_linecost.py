"""How long the firmware takes to parse and plan one received line (simulated seconds).

Measured on the oracle (the classic firmware on a simulated 16 MHz ATmega2560, ``-s 0`` with
``-l`` logs): bursts of identical lines written at once after an empty line (whose ``ok`` times
the first byte), ``ok`` to ``ok`` once no more bytes arrive. Bytes arrive one every 100 us
(:mod:`._wire`), so short lines are paced by the wire and the parse of a line overlaps the
arrival of the next. Steady gaps, at the start pose (all joints 0) unless said, no block planned:

======================================  =====================  =====================
line                                    oracle gap ms          model gap ms
======================================  =====================  =====================
``M20``                                 7.092                  7.092
``M20 G91``                             7.169                  7.186
``M20 G91 G0 X1`` (``X0.1``, ``X10``)   12.672                 12.672
``M20 G91 G1 X1``                       12.705                 12.705
``M20 G91 G1 X1 F2000``                 12.826                 12.825
``M20 G91 G0 X1 Y0`` (a zero word)      12.765                 12.764
``M20 G91 G0 X1 Y10`` / ``Y0.01``       13.17 / 13.23          13.196
``M20 G91 G0 X1 B1`` / ``C1`` / ``A1``  12.90 / 13.04 / 13.46  12.91 / 13.04 / 13.38
``M20 G91 G0 X1 A1 B1 C1``              13.931                 13.946
``M20 G90 G0 X203 Y0 Z181 A0 B0 C0``    13.216                 13.140
``M20 G91 G0 X1``, J2 0.529 J3 -0.531   13.112                 13.142
``M20 G91 G0 X1``, every joint at 10    14.446                 14.632
``M20 G91 G1 X1 F2000``, same pose      14.600                 14.785
``M20`` at those two poses              7.41 / 8.05            7.41 / 8.05
``X0.1`` Cartesian G91 (a block each)   6.92-7.21              7.05
``X0`` joint mode (no block)            0.664                  1.458
======================================  =====================  =====================

The work is in the words: each word of a Cartesian line (:data:`WORD_SECONDS`), the ``M20``
word (the parser's pose from the machine's: forward kinematics, :func:`resync_seconds`), a
Cartesian target (inverse kinematics, :func:`cartesian_target_seconds`), a joint target, and a
planned block. A Cartesian line's block is charged after the line's effects, only when it did
plan one (:func:`block_seconds`; oracle: a repeated ``M20 G91 G0 X1`` whose target rounds to
the steps already planned makes none and is 0.40 ms faster than the first), its reply waits for
it (:class:`ParserWork`); a joint line's block is charged before its effects
(:data:`JOINT_BLOCK_SECONDS`). The float arithmetic of the AVR takes longer for non-zero
values: the forward kinematics 0.16 ms per non-zero joint, the inverse kinematics more for a
target off the arm's vertical plane (``Y``) or with a turned wrist (``A``/``B``/``C``). A line
already waiting in the receive ring costs :data:`PULL_SECONDS` a byte to take into the line
(five more spaces: +14 us); the bytes of a line that arrives while the parser is idle are taken
as they come. Bytes that arrive during the parse slow it down by their receive interrupt
(:data:`RX_INTERRUPT_SECONDS`, :data:`RX_LOST_INTERRUPT_SECONDS`): so a burst of ``M20 G91 G0
X1`` lines (14 bytes, 12.7 ms each) overflows the 127-byte ring, and which bytes are lost
follows from these instants to the 100 us byte (oracle, 20 such lines written at once: 10
``ok``, then ``error: Bad number format`` for an ``M`` whose line end was lost, and ``M20 G91
G0 X1`` left in the ring without its line end). The 2021 firmware is the same code base on the
same MCU (ASSUMED the same costs; its Cartesian ``G1`` cut into blocks is charged one block).
The line's effects, its ``ok`` and the next line wait for it; a ``?`` meanwhile is answered
right after the line's reply (GRBL reports between lines), or, when it came before the line's
wait for queued motion (:func:`wait_point_seconds`), at that wait, before the queued blocks
start (``Idle``: GRBL reports before it starts a cycle); the other realtime bytes act at once.

Not modelled: the exact float timing (the model sees zero or non-zero, e.g. ``B0.002`` is
measured 0.18 ms, ``B1`` 0.14 ms, ``B10`` 0.11 ms, all 0.15 here), a target equal to the
commanded pose (``M20 G91 G0 X0``: 0.16 ms faster), the re-planning growing with the blocks
queued (``X0.1`` Cartesian G91 lines: 6.92 ms with one block queued, 7.21 ms with eleven), the
stepper interrupt while the arm moves (joint ``X0`` lines 0.75-0.84 ms instead of 0.66) and
the preparation of a move's first segments when it starts (the line after the one that
starts a move takes up to 2.7 ms more), the time of a refused line (``M20 G91 M20 G91 G1 X1
F2000``: a modal group violation after 14.24 ms, here 13.01 ms; an ``M``: 0.47 ms, here 0.29)
and of an empty line (0.06 ms, here :data:`LINE_SECONDS`).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

from ._linebuffer import ReceivedLine

if TYPE_CHECKING:
    from ._machine import Machine
    from ._uart import Transmitter
    from ._wire import Wire

LINE_SECONDS: Final = 0.2e-3
"""Any line (``G90`` lines come one per 0.4 ms, as fast as their bytes)."""

PULL_SECONDS: Final = 2.8e-6
"""Taking one byte of a waiting line from the receive ring (oracle: five more spaces in a
waiting ``M20`` line, +14 us)."""

WAIT_WORD_SECONDS: Final = 0.1e-3
"""A line that waits for queued motion reaches its wait after reading its words: this long per
word after the first, from the start of its parse (:func:`wait_point_seconds`)."""

RX_INTERRUPT_SECONDS: Final = 6.6e-6
"""The receive interrupt of each byte that arrives during a parse delays it (oracle: 40, 80,
120 spaces behind ``M20 G91 G0 X0`` delay its ``ok`` by 0.266, 0.529, 0.792 ms)."""

RX_LOST_INTERRUPT_SECONDS: Final = 6.2e-6
"""The receive interrupt of a byte the full ring loses (it stores nothing; oracle: the second
of 20 ``M20 G91 G0 X1`` lines written at once, during which 14 bytes are stored and 114 lost,
takes 13.469 ms, 0.799 ms more than the next ones)."""

WORD_SECONDS: Final = 0.083e-3
"""A word of a Cartesian line (oracle: ``Y0`` added to ``M20 G91 G0 X1``, +0.091 ms with its
three bytes)."""

FEED_WORD_SECONDS: Final = 0.02e-3
"""An ``F`` word more than other words (oracle: ``F2000`` and ``F1000``, +0.12 ms with six
bytes)."""

FEED_MOTION_SECONDS: Final = 0.033e-3
"""``G1``/``G2``/``G3`` in a Cartesian line (oracle: ``G1`` instead of ``G0``, +0.033 ms)."""

RESYNC_SECONDS: Final = 6.798e-3
"""The ``M20`` word with every joint at zero: the parser's pose from the machine's."""

RESYNC_PER_JOINT_SECONDS: Final = 0.16e-3
"""The forward kinematics of ``M20``, per joint J1..J6 not at zero (oracle: ``M20`` lines
7.092 ms at the start pose, 7.41 ms with J2 and J3 off zero, 8.05 ms with all six at 10)."""

CARTESIAN_TARGET_SECONDS: Final = 5.303e-3
"""A Cartesian target in the arm's vertical plane with a level wrist (``Y``, ``A``, ``B``,
``C`` zero): its inverse kinematics."""

TARGET_COMPONENT_SECONDS: Final = (0.43e-3, 0.62e-3, 0.15e-3, 0.28e-3)
"""More inverse kinematics for a target with ``Y``, ``A``, ``B``, ``C`` not zero (oracle, one
at a time near the start pose: +0.40..0.46, +0.54..0.70, +0.11..0.18, +0.28 ms), together at
most :data:`TARGET_EXTRA_MAX_SECONDS`."""

TARGET_EXTRA_MAX_SECONDS: Final = 1.0e-3
"""Oracle: ``A1 B1 C1`` +0.99 ms, ``Y10 A1 B1 C1`` +0.99 ms, every joint at 10 +0.82 ms."""

JOINT_TARGET_SECONDS: Final = 0.45e-3
"""A joint-space target (axis words in joint mode)."""

JOINT_BLOCK_SECONDS: Final = 0.8e-3
"""Planning the block of a joint line with axis words, charged before its effects whether it
plans one or not (oracle: ``X0.1`` increments 1.26-1.43 ms in joint mode, ``X0`` 0.66 ms).
ASSUMED: a joint line's ``M21`` reads the position at the end of its parse; the oracle's own
instants vary more (the first segments of a move starting, the stepper interrupt: ``X0``
lines take 0.75-0.84 ms while the arm moves), and this is the calibration its bursts of
``M21 G91`` lines agree with (the firmware tape ``test_burst[m21-resync-25-two-axes]``)."""

BLOCK_SECONDS: Final = 0.40e-3
"""Planning the block of a Cartesian line into an empty planner (oracle: the first of a burst
of ``M20 G91 G0 X1`` lines is 0.40 ms slower than the next ones, which plan nothing; ``G1 X1
F2000`` the same)."""

QUEUED_BLOCK_SECONDS: Final = 1.05e-3
"""Planning the block of a Cartesian line behind queued blocks costs this much more (oracle:
``X0.1`` increments in Cartesian mode 6.92-7.21 ms, the more the more blocks are queued)."""

HELD_REPLY_LINE: Final = ReceivedLine("")
"""What ``Machine.parsing`` holds while the work before a held reply runs
(:meth:`ParserWork.hold`)."""

_M20: Final = re.compile(r"M0*20(?![0-9.])")
_M21: Final = re.compile(r"M0*21(?![0-9.])")
_AXIS: Final = re.compile(r"[XYZABC]")
_NON_MOTION: Final = re.compile(r"G0*(?:4|10|28|30|53|92)(?![0-9])")
_FEED_MOTION: Final = re.compile(r"G0*[123](?![0-9.])")
_DISTANCE: Final = re.compile(r"G0*(9[01])(?![0-9.])")
_WORD: Final = re.compile(r"([A-Z])([-+]?[0-9.]*)")
_TARGET_AXES: Final = "YABC"


@dataclass(frozen=True, slots=True)
class LineWork:
    """What a line asks of the parser, from its text alone (:func:`line_work`)."""

    seconds: float
    """The work that depends neither on the pose nor on how the bytes came."""
    resync: bool = False
    """``M20``: the forward kinematics of the machine's position."""
    cartesian: bool = False
    """A Cartesian line: its block is charged after its effects (:func:`block_seconds`)."""
    target: bool = False
    """A Cartesian target: inverse kinematics (:func:`cartesian_target_seconds`)."""
    distance: int | None = None
    """``G90``/``G91`` in the line (else the parser's mode)."""
    values: tuple[float | None, ...] = (None, None, None, None)
    """The ``Y``, ``A``, ``B``, ``C`` words' values (None: not in the line)."""


def line_work(text: str, cartesian_mode: bool) -> LineWork:
    """The work of the filtered line ``text`` with the parser in Cartesian mode (``M20``) or
    not. A cheap textual estimate, not a second parser: a refused line costs what its words
    would."""
    if not text or text[0] == "$":
        return LineWork(LINE_SECONDS)
    resync = _M20.search(text) is not None
    if resync:
        cartesian_mode = True
    elif _M21.search(text) is not None:
        cartesian_mode = False
    moves = _AXIS.search(text) is not None and _NON_MOTION.search(text) is None
    if not cartesian_mode:
        joint_target = JOINT_TARGET_SECONDS + JOINT_BLOCK_SECONDS
        return LineWork(LINE_SECONDS + (joint_target if moves else 0.0))
    words = _WORD.findall(text)
    seconds = LINE_SECONDS + WORD_SECONDS * len(words)
    seconds += FEED_WORD_SECONDS * sum(1 for letter, _ in words if letter == "F")
    if _FEED_MOTION.search(text) is not None:
        seconds += FEED_MOTION_SECONDS
    values: list[float | None] = [None, None, None, None]
    for letter, number in words:
        if letter in _TARGET_AXES:
            try:
                values[_TARGET_AXES.index(letter)] = float(number)
            except ValueError:
                values[_TARGET_AXES.index(letter)] = 0.0
    distance = _DISTANCE.findall(text)
    return LineWork(
        seconds,
        resync=resync,
        cartesian=True,
        target=moves,
        distance=int(distance[-1]) if distance else None,
        values=tuple(values),
    )


def resync_seconds(joints: Sequence[float]) -> float:
    """The ``M20`` word with the machine at ``joints`` (degrees; J1..J6 count)."""
    return RESYNC_SECONDS + RESYNC_PER_JOINT_SECONDS * sum(1 for q in joints[:6] if q != 0.0)


def cartesian_target_seconds(target: Sequence[float | None]) -> float:
    """The inverse kinematics of a target whose ``Y``, ``A``, ``B``, ``C`` are ``target``."""
    extra = sum(
        cost
        for value, cost in zip(target, TARGET_COMPONENT_SECONDS, strict=True)
        if value is not None and abs(value) > 1e-9
    )
    return CARTESIAN_TARGET_SECONDS + min(extra, TARGET_EXTRA_MAX_SECONDS)


def target_components(
    work: LineWork, base: Sequence[float], distance: int
) -> tuple[float | None, ...]:
    """The ``Y``, ``A``, ``B``, ``C`` of the line's target from the pose it starts from
    (``base``: X, Y, Z, A, B, C) in distance mode ``distance`` (the line's own wins)."""
    relative = (work.distance or distance) == 91
    start = (base[1], base[3], base[4], base[5])
    return tuple(
        s if v is None else (s + v if relative else v)
        for s, v in zip(start, work.values, strict=True)
    )


def block_seconds(queued: int) -> float:
    """Planning the block of a Cartesian line with ``queued`` blocks already in the planner."""
    return BLOCK_SECONDS + (QUEUED_BLOCK_SECONDS if queued else 0.0)


def line_seconds(m: Machine, line: ReceivedLine, *, waited: bool) -> tuple[float, LineWork | None]:
    """Parse seconds of ``line`` on ``m`` now, and its work (None: an overflowed line).
    ``waited``: the line was complete in the ring before the parser was free (else its last
    byte came just now, the earlier ones were taken as they came)."""
    if line.overflow:
        return 0.0, None
    work = line_work(line.text, m.modal.cart_mode)
    seconds = work.seconds + PULL_SECONDS * (line.raw if waited else 1)
    base: Sequence[float] = m.modal.cart
    if work.resync:
        joints = m.machine_position()
        seconds += resync_seconds(joints)
        if work.target:
            base = m.geometry.fk(joints)
    if work.target:
        seconds += cartesian_target_seconds(target_components(work, base, m.modal.distance))
    return seconds, work


def wait_point_seconds(text: str) -> float:
    """How long after its parse began a line that waits for queued motion (``M3``/``M4``/``M5``
    behind a move) reaches its wait, before which a ``?`` finds the move not started. Oracle,
    the last ``?`` answered ``Idle`` behind ``M21 G90 X30 F300`` in 0.1 ms steps: ``M5`` 11
    bytes after its line, ``M4 E65`` 8, ``M3 S500`` 7, ``M4 E40 S500`` 4: the wait comes 0.1 ms
    later per word (with this model's parse start, the first word's time is in the line before;
    ``M21 G90 X5 M3 S1000``: moving 1.3 ms after, here 0.4 ms)."""
    words = sum(char.isalpha() for char in text)
    return WAIT_WORD_SECONDS * max(words - 1, 0)


class ParserWork:
    """The parser's work on one line: when it ends (with the receive interrupts of the bytes
    that arrive meanwhile, :data:`RX_INTERRUPT_SECONDS`), and the reply of an executed line
    held while its block is planned (:func:`block_seconds`)."""

    def __init__(self, wire: Wire) -> None:
        self._wire = wire
        self.until: float | None = None
        """When the work ends (None: the parser is idle)."""
        self.work: LineWork | None = None
        """The work of the line being parsed (None: an overflowed line)."""
        self.reply: bytes | None = None
        """The executed line's reply, printed when its block is planned."""
        self._begun = (0.0, 0.0, 0)  # start, own seconds, bytes arrived by the start
        self._room = 0  # free bytes in the receive ring at the start

    def begin(self, m: Machine, now: float, seconds: float) -> None:
        """``seconds`` of work from ``now`` (``m``'s receive ring as it is now)."""
        wire = self._wire
        if not wire.in_transit:  # no byte arrives meanwhile: no receive interrupt
            self._room = m.rx.free
            self._begun = (now, seconds, wire.delivered)
            self.until = now + seconds + 0.0  # (what busy_until adds for no byte)
            return
        arrived = wire.arrived_by(now)
        self._room = m.rx.free - (arrived - wire.delivered)  # bytes due are not put yet
        self._begun = (now, seconds, arrived)
        self.until = wire.busy_until(*self._begun, self._interrupts)

    def more_bytes(self) -> None:
        """The host wrote more bytes: those that arrive before the end delay it."""
        if self.until is not None:
            self.until = self._wire.busy_until(*self._begun, self._interrupts)

    def _interrupts(self, count: int) -> float:
        """The receive interrupts of ``count`` bytes arriving during the work: the ring takes
        what it has room for (nothing leaves it meanwhile), the rest is lost."""
        stored = min(count, max(self._room, 0))
        return stored * RX_INTERRUPT_SECONDS + (count - stored) * RX_LOST_INTERRUPT_SECONDS

    def execute(
        self, m: Machine, line: ReceivedLine, run: Callable[[str], None], now: float
    ) -> bool:
        """Execute ``line`` with ``run``; if it queued a block (not waiting for a slot), hold
        its reply and keep ``line`` in ``m.parsing`` while the block is planned. True if so."""
        planner = m.planner
        free, mark = planner.free, len(m.out)
        run(line.text)
        work = self.work
        if work is None or not work.cartesian or planner.free >= free or m.pending:
            return False
        self.reply = m.withdraw(mark)
        self.begin(m, now, block_seconds(planner.CAPACITY - free))
        m.parsing = line
        return True

    def hold(self, m: Machine, now: float, uart: Transmitter) -> None:
        """``m.held_reply`` (a finished :class:`~._machine.Pending`'s reply and its planning
        seconds) becomes the reply of a line whose block is planned: printed when the work is
        done; the next line and the queued blocks' start wait, a ``?`` meanwhile is answered
        after the reply. A ``?`` deferred by a homing search is answered first (``Home``), and
        the work starts once that report is produced (tapes: the report, then the return
        move's planning, then ``ok``)."""
        if m.held_reply is None:  # pragma: no cover - only called with a held reply
            return
        reply, seconds = m.held_reply
        m.held_reply = None
        if m.status_deferred:
            m.status_deferred = False
            uart.print_report(m, now, state="Home")
            seconds += uart.production_left(now)
        m.parsing = HELD_REPLY_LINE
        self.work = None
        self.reply = reply
        self.begin(m, now, seconds)

    def done(self) -> bytes | None:
        """The work has ended; the reply held for the planned block, if any."""
        self.until = None
        reply, self.reply = self.reply, None
        return reply

    def clear(self) -> None:
        """No work (a soft reset drops the line and its reply)."""
        self.until = None
        self.reply = None
