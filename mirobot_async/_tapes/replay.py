"""Replay a tape into the emulator's firmware model and say where the two differ.

The model (:class:`mirobot_emulator.firmware.Firmware`) powers on with its banner printed; its
clock starts at the tape's first ``Using reset pos!`` line. Each written byte is fed at its own
instant, the clock run event by event in between, and every line the model prints is compared
with the tape's, in order: non-status lines byte for byte (after the field texts of
:mod:`.fieldtexts`), status lines byte for byte at rest and within :data:`STATUS_STEP_TOLERANCE`
motor steps per axis while the arm moves, every line's first byte within
:data:`INSTANT_TOLERANCE` (firmware tapes) of the tape's. The comparison stops at the first
difference: a tape is open-loop (the host chose when to write by reading the firmware's
replies), so after one difference what follows no longer means anything.

A recorded tape (``source`` ``device`` or ``virtual``) holds the field texts as printed (they are
not mapped to the source revision's), and a ``virtual`` one is replayed as the in-process arm
runs: the model's own wire and an unpaced transmitter (that arm does not pace its output).
"""

from __future__ import annotations

import importlib
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from mirobot_async._tapes.fieldtexts import normalise_emulator
from mirobot_async._tapes.format import Printed, Tape, Written

BANNER_END = b"Using reset pos!\r\n"
UART_BYTE_SECONDS = 93.5e-6
"""The firmware's UART at 115200 baud: 10.77 bit times a byte (the firmware tapes' clock)."""

STATUS_STEP_TOLERANCE = 60
"""Motor steps per axis by which a status taken while the arm moves may differ.

A status samples the position at an instant. The firmware takes 2-12 ms to compute a report
while its stepper interrupt runs (measured on its tapes; the model assumes the time at rest),
and at the fastest joint rate (J2 at $112 = 3000 deg/min with 113.33 steps/deg: 5667 steps/s)
60 steps are 10.6 ms."""

STAMP_SECONDS = 0.0002
"""A run of the model this short is one call, its output stamped at the run's end (a written
byte comes every 100 us on the firmware's tapes): 1 % of :data:`INSTANT_TOLERANCE`."""

INSTANT_TOLERANCE = 0.02
"""Seconds by which a line's first byte may differ from the firmware tape's (replies to lines
queued behind motion inherit the motion's timing; see :data:`STATUS_STEP_TOLERANCE`)."""

DEVICE_INSTANT_TOLERANCE = 1.0
"""For recorded tapes (a device's or a virtual arm's): their instants carry the USB latency or
the virtual arm's clock steps, so they are compared only loosely (the bytes and order exactly)."""

_STATUS = re.compile(rb"^<([A-Za-z]+)[,|]")
_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?")


@dataclass(frozen=True)
class Difference:
    """The first place the emulator printed otherwise (None: that side printed nothing)."""

    tape: str
    event: int
    firmware: bytes | None
    firmware_t: float | None
    emulator: bytes | None
    emulator_t: float | None
    why: str = ""

    def __str__(self) -> str:
        def side(data: bytes | None, t: float | None) -> str:
            if data is None:
                return "nothing"
            return f"{data!r}" + ("" if t is None else f" at {t:.4f}")

        text = (
            f"{self.tape} event {self.event}: firmware {side(self.firmware, self.firmware_t)}; "
            f"emulator {side(self.emulator, self.emulator_t)}"
        )
        return f"{text} ({self.why})" if self.why else text


@dataclass
class ReplayReport:
    """What one replay found: equal, or the first :class:`Difference`, with its measures."""

    tape: str
    firmware: str
    equal: bool = True
    difference: Difference | None = None
    lines: int = 0
    statuses: int = 0
    moving_statuses: int = 0
    exact_statuses: int = 0
    largest_steps: int = 0
    largest_shift: float = 0.0
    """Seconds: the largest difference of a compared line's first byte."""
    instants: str = "exact"
    """``exact`` (simulated instants), ``loose`` (wall-clock instants: within
    :data:`DEVICE_INSTANT_TOLERANCE`) or ``none`` (a virtual arm not at time scale 1)."""
    shifts: list[float] = field(default_factory=list)
    transcript: tuple[list[tuple[int, bytes]], list[bytes]] = field(
        default_factory=lambda: ([], [])
    )
    """The tape's lines (with their events) and the emulator's, normalised, as compared."""
    pairs: list[tuple[int, float, float | None]] = field(default_factory=list)
    """Per line compared equal in bytes: its event, the firmware's and the emulator's first-byte
    instants (the comparison goes on past a difference of instants alone, to the first of bytes)."""


def is_status(line: bytes) -> bool:
    return _STATUS.match(line) is not None


def _moving(line: bytes) -> bool:
    match = _STATUS.match(line)
    return match is not None and match.group(1) not in (b"Idle", b"Alarm")


STEPS_PER_DEGREE = (16.0, 22.22, 11.11, 200.0, 56.73, 113.33, 64.0)
"""``$100..$106`` at power-on in the status's ``Angle(ABCDXYZ)`` order (J4, J5, J6, rail, J1,
J2, J3): a status prints whole motor steps, so an angle times this is a step count."""


def status_distance(a: bytes, b: bytes) -> int | None:
    """Largest difference, in motor steps of an axis, between two status lines of the same shape
    (None: their texts differ other than in numbers). The Cartesian numbers follow the angles
    and are compared by shape only."""
    if _NUMBER.sub(b"#", a) != _NUMBER.sub(b"#", b):
        return None
    angles_a = _angles(a)
    angles_b = _angles(b)
    if angles_a is None or angles_b is None or len(angles_a) != len(angles_b):
        return 0
    return max(
        round(abs(x - y) * s) for x, y, s in zip(angles_a, angles_b, STEPS_PER_DEGREE, strict=False)
    )


def _angles(line: bytes) -> list[float] | None:
    start = line.find(b"Angle(")
    if start < 0:
        return None
    head = line.find(b":", start)
    end = line.find(b",Cartesian", head)
    if head < 0 or end < 0:
        return None
    return [float(x) for x in _NUMBER.findall(line[head + 1 : end])]


class _Transmitter(Protocol):
    byte_seconds: float


class _Firmware(Protocol):
    """What the replay uses of :class:`mirobot_emulator.firmware.Firmware`."""

    now: float
    uart: _Transmitter

    def receive(self, data: bytes) -> None: ...
    def advance(self, dt: float) -> None: ...
    def read_output(self) -> bytes: ...
    def next_deadline(self) -> float | None: ...


class _Model:
    """The firmware model with the tape's clock and a paced transmitter."""

    def __init__(self, firmware: str, offset: float, paced: bool = True) -> None:
        # imported when a tape is replayed: the CLI that offers replay stays cheap to import
        model = importlib.import_module("mirobot_emulator.firmware")
        self.compute: Callable[[int], float] = model.report_compute_seconds
        self.byte_seconds = UART_BYTE_SECONDS if paced else 0.0
        if paced:
            self.fw: _Firmware = model.Firmware(firmware, byte_seconds=UART_BYTE_SECONDS)
        else:  # the in-process virtual arm: the model's own wire, an unpaced transmitter
            self.fw = model.Firmware(firmware)
            self.compute = lambda length: 0.0
        self.fw.uart.byte_seconds = self.byte_seconds
        self.offset = offset
        self.banner = _lines(self.fw.read_output())
        self.printed: list[tuple[float, bytes]] = []  # (first byte, tape clock), line
        self._free = 0.0

    def run_to(self, t: float) -> None:
        fw = self.fw
        target = t - self.offset
        if 0.0 < target - fw.now <= STAMP_SECONDS:
            # the next byte is due within a byte time or two: the model runs its own events on
            # the way (the same run as step by step); what it printed is stamped at the end
            fw.advance(target - fw.now)
            self._collect()
            return
        while fw.now < target:
            deadline = fw.next_deadline()
            if deadline is None or deadline >= target:
                step = target - fw.now
            else:
                step = max(deadline - fw.now, 0.0)
            fw.advance(step)
            self._collect()
            if step == 0.0 and fw.next_deadline() == deadline:
                fw.advance(min(1e-7, target - fw.now))  # an event that does not move on
                self._collect()

    def write(self, data: bytes) -> None:
        self.fw.receive(data)
        self._collect()

    def _collect(self) -> None:
        out = self.fw.read_output()
        if not out:
            return
        now = self.fw.now
        for line in _lines(out):
            at = now + self.compute(len(line)) if is_status(line) else now
            start = max(at, self._free)
            self._free = start + len(line) * self.byte_seconds
            self.printed.append((start + self.offset, line))


def _lines(data: bytes) -> list[bytes]:
    parts = data.split(b"\r\n")
    lines = [p + b"\r\n" for p in parts[:-1]]
    if parts[-1]:
        lines.append(parts[-1])
    return lines


def _banner_offset(tape: Tape) -> tuple[float, int] | None:
    """The tape-clock instant of the first ``Using reset pos!`` line and its event index."""
    for k, event in enumerate(tape.events):
        if isinstance(event, Printed) and event.data == BANNER_END:
            return event.start, k
    return None


def replay(tape: Tape, firmware: str = "classic", *, stop_at: float | None = None) -> ReplayReport:
    """Replay ``tape`` into a fresh ``firmware`` model; compare up to ``stop_at`` (tape clock)."""
    report = ReplayReport(tape.id, firmware)
    found = _banner_offset(tape)
    # a recorded tape's instants are loose: a device's carry the USB latency, a virtual arm's
    # the steps of its clock loop (at time scale 10 a 2 ms tick is 20 ms of the arm's time)
    exact = tape.source == "firmware"
    report.instants = "exact" if exact else "loose"
    tolerance = INSTANT_TOLERANCE if exact else DEVICE_INSTANT_TOLERANCE
    scale = tape.header.get("time_scale")
    if tape.source == "virtual" and scale is not None and scale != 1:
        # a virtual arm faster than real time stamps what it prints when its clock loop wakes:
        # a host that stalls 0.1 s moves its clock 1 s at time scale 10 (and at 0 each line's
        # motion ends at once), so only the bytes and their order are compared
        report.instants = "none"
        tolerance = math.inf
    offset, banner_at = found if found is not None else (0.0, -1)
    model = _Model(firmware, offset, paced=tape.source != "virtual")
    expected: list[tuple[int, Printed]] = []
    end = tape.end_t if stop_at is None else min(stop_at, tape.end_t)
    for k, event in enumerate(tape.events):
        if event.t > end:
            break
        if isinstance(event, Printed):
            expected.append((k, event))
        elif isinstance(event, Written) and not event.dropped:
            if event.t - offset >= 0.0:
                model.run_to(event.t)
            model.write(event.data)
    model.run_to(end)
    ours: list[tuple[float | None, bytes]] = []
    if found is not None:
        ours += [(None, line) for line in model.banner]
        expected_banner = [e for k, e in expected if k <= banner_at]
        if len(model.banner) != len(expected_banner):
            ours = [(None, line) for line in model.banner]
    ours += [(at, line) for at, line in model.printed if at <= end + 1e-9]
    if tape.source == "firmware":  # recorded tapes hold field texts as the emulator prints them
        ours = normalise_emulator(ours)
    report.transcript = ([(k, e.data) for k, e in expected], [line for _at, line in ours])
    # without a power-on on the tape the model cannot know where the arm stood: shapes only
    _compare(report, expected, ours, tolerance, by_shape=found is None)
    return report


def _compare(
    report: ReplayReport,
    expected: Sequence[tuple[int, Printed]],
    ours: Sequence[tuple[float | None, bytes]],
    tolerance: float,
    *,
    by_shape: bool,
) -> None:
    for n, (k, line) in enumerate(expected):
        theirs = line.data
        if n >= len(ours):
            report.equal = False
            if report.difference is None:
                report.difference = Difference(report.tape, k, theirs, line.start, None, None)
            return
        at, mine = ours[n]
        if line.partial:
            mine = mine[: len(theirs)]
        report.lines += 1
        why = ""
        if is_status(theirs):
            report.statuses += 1
            if theirs == mine:
                report.exact_statuses += 1
            elif by_shape and _NUMBER.sub(b"#", theirs) == _NUMBER.sub(b"#", mine):
                pass  # a recording that began after power-on: where the arm stood is unknown
            elif _moving(theirs) and (steps := status_distance(theirs, mine)) is not None:
                report.moving_statuses += 1
                report.largest_steps = max(report.largest_steps, steps)
                if steps > STATUS_STEP_TOLERANCE:
                    why = f"{steps} motor steps apart"
            else:
                why = "bytes"
        elif theirs != mine:
            why = "bytes"
        if why:
            report.equal = False
            if report.difference is None:
                report.difference = Difference(report.tape, k, theirs, line.start, mine, at, why)
            return
        report.pairs.append((k, line.start, at))
        if at is not None:
            shift = at - line.start
            report.shifts.append(shift)
            if abs(shift) > abs(report.largest_shift):
                report.largest_shift = shift
            if abs(shift) > tolerance and report.difference is None:
                report.equal = False
                why = f"{shift * 1000:+.1f} ms"
                report.difference = Difference(report.tape, k, theirs, line.start, mine, at, why)
    if len(ours) > len(expected) and report.difference is None:
        at, mine = ours[len(expected)]
        report.equal = False
        report.difference = Difference(
            report.tape, len(expected), None, None, mine, at, "extra line"
        )


def transcript_differences(report: ReplayReport) -> list[str]:
    """Every place the emulator's lines differ from the tape's, not only the first: the two
    transcripts aligned line by line (status reports by their shape), each differing run said
    once. For a probe that waits for each reply (``mirobot doctor``), where a reply that differs
    does not change what follows."""
    import difflib

    theirs, ours = report.transcript

    def key(line: bytes) -> bytes:
        return _NUMBER.sub(b"#", line) if is_status(line) else line

    matcher = difflib.SequenceMatcher(
        None, [key(line) for _k, line in theirs], [key(line) for line in ours], autojunk=False
    )
    found = []
    for tag, i1, i2, j1, j2 in matcher.get_opcodes():
        if tag == "equal":
            continue
        where = f"event {theirs[i1][0]}" if i1 < len(theirs) else "at the end"
        firmware = b"".join(line for _k, line in theirs[i1:i2]) or None
        emulator = b"".join(ours[j1:j2]) or None
        found.append(
            f"{report.tape} {where}: arm {firmware!r}; emulator {emulator!r}"
            if firmware is not None or emulator is not None
            else f"{report.tape} {where}: {tag}"
        )
    return found
