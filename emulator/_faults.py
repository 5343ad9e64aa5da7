"""Fault injection for the virtual Mirobot: pure, deterministic by seed.

Real arms misbehave in a few recurring ways (issue 7): an ``ok`` never arrives, a status line is
printed with a duplicated fragment, a ``?`` is ignored, the output stalls, a limit switch trips,
the controller resets on its own (banner in the middle of the stream), the USB cable is pulled.
This module describes those faults and applies the ones that act on data; the server
(:mod:`mirobot_emulator.server`) applies the ones that act on the link or on the firmware.

Nothing here does I/O or reads a clock: the server passes the time in.

Fault specifications (command line, ``--fault SPEC``, repeatable)::

    drop-ok:N                 drop the N-th "ok" line (1-based, counted from power-on)
    corrupt-status:N          corrupt the N-th status line (duplicate a fragment)
    corrupt-status-rate:P     corrupt each status line with probability P (seeded)
    ignore-status:N           ignore the N-th "?" byte received (no status line for it)
    stall:AFTER_S:DURATION_S  hold all output for DURATION_S seconds, AFTER_S after start
    hard-limit:AFTER_S[:AXIS] trip a hard limit switch (default axis 1)
    reset:AFTER_S             spontaneous reset: the banner appears mid-stream
    close:AFTER_S             close the port (unplugged cable); the emulator then exits
    split-bytes[:on|off]      write the output one byte at a time, each byte read by the client
                              before the next is written (the client sees single-byte reads)
    delay:MS                  hold every output line MS milliseconds before writing it (order
                              preserved)

Timed faults count wall-clock seconds since the server opened its port (not simulated seconds).
The link faults (``split-bytes``, ``delay``) act from the start, on every line after the power-on
banner; the control channel turns them on, off or changes them while running.

Control commands (the server's stdin, one per line; each answered ``ack <command>``)::

    drop-ok [N]          drop the next N "ok" lines (default 1)
    corrupt-status [N]   corrupt the next N status lines
    ignore-status [N]    ignore the next N "?" bytes
    stall SECONDS        hold all output for SECONDS from now
    hard-limit [AXIS]    trip a hard limit now (default axis 1)
    reset                spontaneous reset now
    close                close the port now, then exit
    split-bytes [on|off] write the output one byte per write from now on (default on) / stop
    delay MS             hold every output line MS milliseconds from now on (0 = off)
    time-scale X         change the simulation speed from now on (0 = instant motion)
    stats                no fault: answered ``ack stats NAME=N ...`` with the server's counters
                         (bytes and lines received from the client, bytes written, oks dropped,
                         statuses corrupted, ...), so that tests can see what really crossed
                         the wire

The server also answers queries of its own on the same channel (``motion-ends``,
``starvations``: see :mod:`mirobot_emulator.server._control`).

An "ok line" is a line that is exactly ``ok``; an ``ok`` glued to other text (``in homeing
moving...ok``) is not counted or dropped. A "status line" is a line starting with ``<``.
"""

from __future__ import annotations

import math
import random
import re
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass

__all__ = [
    "COUNTED_KINDS",
    "LINK_KINDS",
    "TIMED_KINDS",
    "Command",
    "Fault",
    "FaultFilter",
    "FaultSchedule",
    "FaultSpecError",
    "OutputDelay",
    "corrupt_status_line",
    "link_commands",
    "parse_command",
    "parse_fault",
]

COUNTED_KINDS = frozenset({"drop-ok", "corrupt-status", "ignore-status"})
TIMED_KINDS = frozenset({"stall", "hard-limit", "reset", "close"})
LINK_KINDS = frozenset({"split-bytes", "delay"})
COMMAND_KINDS = COUNTED_KINDS | TIMED_KINDS | LINK_KINDS | {"time-scale", "stats"}
MAX_DELAY_MS = 60_000.0


class FaultSpecError(ValueError):
    """A fault specification or control command that cannot be understood."""


@dataclass(frozen=True, slots=True)
class Command:
    """An action to perform now (from the control channel or from a timed fault).

    ``count`` is N for the counted kinds, the axis for ``hard-limit`` and 1 (on) or 0 (off) for
    ``split-bytes``; ``value`` is the duration in seconds for ``stall`` and ``delay`` and the
    factor for ``time-scale``. ``text`` is the normalised command line, echoed in the ``ack``.
    """

    kind: str
    count: int = 1
    value: float = 0.0
    text: str = ""


@dataclass(frozen=True, slots=True)
class Fault:
    """One ``--fault`` specification.

    Counted kinds use ``n`` (1-based index); ``corrupt-status-rate`` uses ``rate``; timed kinds
    use ``at`` (seconds after start) and ``command`` (what to do then); link kinds use
    ``command`` (applied when the server starts).
    """

    kind: str
    n: int = 0
    rate: float = 0.0
    at: float = 0.0
    command: Command | None = None


def _positive_int(text: str, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise FaultSpecError(f"{what}: expected a positive integer, got {text!r}") from None
    if value < 1:
        raise FaultSpecError(f"{what}: expected a positive integer, got {text!r}")
    return value


def _seconds(text: str, what: str, *, allow_zero: bool = True) -> float:
    try:
        value = float(text)
    except ValueError:
        raise FaultSpecError(f"{what}: expected a number of seconds, got {text!r}") from None
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise FaultSpecError(f"{what}: expected a non-negative number of seconds, got {text!r}")
    return value


def _milliseconds(text: str, what: str) -> float:
    """A ``delay`` argument in milliseconds -> seconds."""
    try:
        value = float(text)
    except ValueError:
        raise FaultSpecError(f"{what}: expected a number of milliseconds, got {text!r}") from None
    if not math.isfinite(value) or not 0 <= value <= MAX_DELAY_MS:
        raise FaultSpecError(
            f"{what}: expected a number of milliseconds in 0..{MAX_DELAY_MS:g}, got {text!r}"
        )
    return value / 1000.0


def _on_off(text: str, what: str) -> int:
    word = text.lower()
    if word in ("on", "1", "yes", "true"):
        return 1
    if word in ("off", "0", "no", "false"):
        return 0
    raise FaultSpecError(f"{what}: expected on or off, got {text!r}")


def parse_fault(spec: str) -> Fault:
    """Parse one ``--fault`` argument (see the module docstring); raises :class:`FaultSpecError`."""
    parts = spec.strip().split(":")
    kind, args = parts[0].strip().lower(), [p.strip() for p in parts[1:]]

    def need(lo: int, hi: int) -> None:
        if not lo <= len(args) <= hi:
            raise FaultSpecError(f"bad fault {spec!r}: {kind} takes {lo}..{hi} ':'-arguments")

    if kind in COUNTED_KINDS:
        need(1, 1)
        return Fault(kind, n=_positive_int(args[0], spec))
    if kind == "corrupt-status-rate":
        need(1, 1)
        try:
            rate = float(args[0])
        except ValueError:
            raise FaultSpecError(f"bad fault {spec!r}: expected a probability") from None
        if not 0.0 <= rate <= 1.0:
            raise FaultSpecError(f"bad fault {spec!r}: probability must be in [0, 1]")
        return Fault(kind, rate=rate)
    if kind == "stall":
        need(2, 2)
        at = _seconds(args[0], spec)
        duration = _seconds(args[1], spec)
        return Fault(kind, at=at, command=Command("stall", value=duration, text=f"stall {args[1]}"))
    if kind == "hard-limit":
        need(1, 2)
        at = _seconds(args[0], spec)
        axis = _positive_int(args[1], spec) if len(args) > 1 else 1
        command = Command("hard-limit", count=axis, text=f"hard-limit {axis}")
        return Fault(kind, at=at, command=command)
    if kind in ("reset", "close"):
        need(1, 1)
        return Fault(kind, at=_seconds(args[0], spec), command=Command(kind, text=kind))
    if kind == "split-bytes":
        need(0, 1)
        on = _on_off(args[0], spec) if args else 1
        text = "split-bytes " + ("on" if on else "off")
        return Fault(kind, command=Command(kind, count=on, text=text))
    if kind == "delay":
        need(1, 1)
        seconds = _milliseconds(args[0], spec)
        return Fault(kind, command=Command(kind, value=seconds, text=f"delay {args[0]}"))
    known = sorted(COUNTED_KINDS | TIMED_KINDS | LINK_KINDS | {"corrupt-status-rate"})
    raise FaultSpecError(f"unknown fault {spec!r} (known: {', '.join(known)})")


def parse_command(line: str) -> Command:
    """Parse one control-channel line (see the module docstring); raises :class:`FaultSpecError`."""
    words = line.split()
    if not words:
        raise FaultSpecError("empty command")
    kind, args = words[0].lower(), words[1:]
    text = " ".join([kind, *args])
    if kind not in COMMAND_KINDS:
        known = ", ".join(sorted(COMMAND_KINDS))
        raise FaultSpecError(f"unknown command {kind!r} (known: {known})")
    if kind in COUNTED_KINDS or kind == "hard-limit":
        if len(args) > 1:
            raise FaultSpecError(f"{kind} takes at most one argument")
        count = _positive_int(args[0], kind) if args else 1
        return Command(kind, count=count, text=text)
    if kind == "stall":
        if len(args) != 1:
            raise FaultSpecError("stall takes one argument: SECONDS")
        return Command(kind, value=_seconds(args[0], kind), text=text)
    if kind == "time-scale":
        if len(args) != 1:
            raise FaultSpecError("time-scale takes one argument: X")
        return Command(kind, value=_seconds(args[0], kind), text=text)
    if kind == "split-bytes":
        if len(args) > 1:
            raise FaultSpecError("split-bytes takes at most one argument: on or off")
        on = _on_off(args[0], kind) if args else 1
        return Command(kind, count=on, text="split-bytes " + ("on" if on else "off"))
    if kind == "delay":
        if len(args) != 1:
            raise FaultSpecError("delay takes one argument: MS (milliseconds)")
        return Command(kind, value=_milliseconds(args[0], kind), text=text)
    if args:
        raise FaultSpecError(f"{kind} takes no argument")
    return Command(kind, text=text)


# A status line: numbers, and header words (Angle, Cartesian, coordinate, Pump, PWM, ...).
_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?")
_WORD = re.compile(rb"[A-Za-z_]{2,}")


def corrupt_status_line(line: bytes, rng: random.Random) -> bytes:
    """Corrupt a status line the way real arms do: a fragment of it is printed twice.

    The result is ``body[:k] + body[m:]`` with ``m < k``: the line is printed up to the middle of
    a number (``k``), then again from the middle of an earlier header word (``m``), e.g.
    ``...,28.916,13.226esian coordinate(XYZ RxRyRz):-3.985,...`` (compare the real line in
    ``vectors.json``). A digit glued to letters makes the line unparsable by construction. The
    line ending, if any, is kept. Lines without a header word before a number are returned
    unchanged.
    """
    body = line.rstrip(b"\r\n")
    ending = line[len(body) :]
    words = [w for w in _WORD.finditer(body) if w.start() > 0]
    if not words:
        return line
    first_word_end = words[0].end()
    # k: a position just after a digit of a number that comes after some header word.
    ks = [
        k
        for num in _NUMBER.finditer(body)
        for k in range(num.start() + 1, num.end() + 1)
        if k > first_word_end and body[k - 1 : k].isdigit()
    ]
    if not ks:
        return line
    # Pick the number position first, then a position strictly inside an earlier word.
    k = ks[rng.randrange(len(ks))]
    ms = [m for w in words if w.end() <= k for m in range(w.start() + 1, w.end())]
    m = ms[rng.randrange(len(ms))]
    return body[:k] + body[m:] + ending


class FaultFilter:
    """The data faults: drops ``ok`` lines, corrupts status lines, removes ``?`` bytes.

    Feed it every complete output line (with its ending) and every chunk of input in order; it
    counts them itself. ``seed`` makes corruption positions and ``corrupt-status-rate`` draws
    reproducible.
    """

    def __init__(self, faults: Iterable[Fault] = (), *, seed: int = 0) -> None:
        self._rng = random.Random(seed)
        self._drop_ok_at: set[int] = set()
        self._corrupt_at: set[int] = set()
        self._ignore_at: set[int] = set()
        self._rate = 0.0
        for fault in faults:
            if fault.kind == "drop-ok":
                self._drop_ok_at.add(fault.n)
            elif fault.kind == "corrupt-status":
                self._corrupt_at.add(fault.n)
            elif fault.kind == "ignore-status":
                self._ignore_at.add(fault.n)
            elif fault.kind == "corrupt-status-rate":
                self._rate = max(self._rate, fault.rate)
        self._drop_next = 0
        self._corrupt_next = 0
        self._ignore_next = 0
        self.oks_seen = 0
        self.status_lines_seen = 0
        self.status_requests_seen = 0
        self.dropped_oks = 0
        self.corrupted_status_lines = 0
        self.ignored_status_requests = 0

    def apply(self, command: Command) -> bool:
        """Arm a counted fault from the control channel; False if ``command`` is not one."""
        if command.kind == "drop-ok":
            self._drop_next += command.count
        elif command.kind == "corrupt-status":
            self._corrupt_next += command.count
        elif command.kind == "ignore-status":
            self._ignore_next += command.count
        else:
            return False
        return True

    def output_line(self, line: bytes) -> bytes | None:
        """One complete output line (ending included) -> the line to send, or None to drop it."""
        body = line.rstrip(b"\r\n")
        if body == b"ok":
            self.oks_seen += 1
            if self.oks_seen in self._drop_ok_at:
                self._drop_ok_at.discard(self.oks_seen)
                self.dropped_oks += 1
                return None
            if self._drop_next > 0:
                self._drop_next -= 1
                self.dropped_oks += 1
                return None
            return line
        if body.startswith(b"<"):
            self.status_lines_seen += 1
            corrupt = False
            if self.status_lines_seen in self._corrupt_at:
                self._corrupt_at.discard(self.status_lines_seen)
                corrupt = True
            elif self._corrupt_next > 0:
                self._corrupt_next -= 1
                corrupt = True
            elif self._rate > 0.0 and self._rng.random() < self._rate:
                corrupt = True
            if corrupt:
                corrupted = corrupt_status_line(line, self._rng)
                if corrupted != line:
                    self.corrupted_status_lines += 1
                return corrupted
        return line

    def input_bytes(self, data: bytes) -> bytes:
        """Input on its way to the firmware -> the same minus the ``?`` bytes to ignore."""
        if b"?" not in data or not (self._ignore_at or self._ignore_next):
            self.status_requests_seen += data.count(b"?")
            return data
        out = bytearray()
        for byte in data:
            if byte == 0x3F:  # "?"
                self.status_requests_seen += 1
                if self.status_requests_seen in self._ignore_at:
                    self._ignore_at.discard(self.status_requests_seen)
                    self.ignored_status_requests += 1
                    continue
                if self._ignore_next > 0:
                    self._ignore_next -= 1
                    self.ignored_status_requests += 1
                    continue
            out.append(byte)
        return bytes(out)


def link_commands(faults: Iterable[Fault]) -> list[Command]:
    """The commands of the link faults (``split-bytes``, ``delay``), to apply at start, in order."""
    return [f.command for f in faults if f.kind in LINK_KINDS and f.command is not None]


class OutputDelay:
    """The ``delay`` fault: every output chunk is held ``delay`` seconds, order preserved.

    :meth:`push` a chunk (whole lines) at time ``now``; :meth:`pop` returns, concatenated, the
    chunks whose time has come, oldest first. A chunk is never released before one pushed earlier
    (lowering the delay while chunks wait does not reorder them). With a zero delay and nothing
    waiting, a chunk pushed at ``now`` is released by ``pop(now)``.
    """

    def __init__(self, delay: float = 0.0) -> None:
        self._queue: deque[tuple[float, bytes]] = deque()
        self._last_release = -math.inf
        self._held = 0
        self.delay = delay

    @property
    def delay(self) -> float:
        """Seconds each chunk pushed from now on is held."""
        return self._delay

    @delay.setter
    def delay(self, seconds: float) -> None:
        if not math.isfinite(seconds) or seconds < 0:
            raise ValueError(f"delay must be a finite number of seconds >= 0, got {seconds!r}")
        self._delay = seconds

    def __len__(self) -> int:
        """Bytes waiting."""
        return self._held

    def push(self, data: bytes, now: float) -> None:
        """A chunk produced at ``now``."""
        if not data:
            return
        release = max(now + self._delay, self._last_release)
        self._last_release = release
        self._queue.append((release, bytes(data)))
        self._held += len(data)

    def pop(self, now: float) -> bytes:
        """The chunks due at ``now``, oldest first, concatenated."""
        out = bytearray()
        while self._queue and self._queue[0][0] <= now:
            out += self._queue.popleft()[1]
        self._held -= len(out)
        return bytes(out)

    def next_time(self) -> float | None:
        """When the oldest waiting chunk is due, or None."""
        return self._queue[0][0] if self._queue else None

    def clear(self) -> None:
        """Forget every chunk waiting."""
        self._queue.clear()
        self._last_release = -math.inf
        self._held = 0


class FaultSchedule:
    """The timed faults, in order: ask :meth:`due` with the seconds elapsed since start."""

    def __init__(self, faults: Iterable[Fault] = ()) -> None:
        timed = [f for f in faults if f.kind in TIMED_KINDS and f.command is not None]
        # Stable sort: faults at the same time keep their command-line order.
        self._pending: list[tuple[float, Command]] = sorted(
            ((f.at, f.command) for f in timed if f.command is not None), key=lambda p: p[0]
        )

    def next_time(self) -> float | None:
        """Elapsed seconds at which the next fault is due, or None."""
        return self._pending[0][0] if self._pending else None

    def due(self, elapsed: float) -> list[Command]:
        """Remove and return the commands due at ``elapsed`` seconds, in order."""
        count = 0
        while count < len(self._pending) and self._pending[count][0] <= elapsed:
            count += 1
        commands = [command for _, command in self._pending[:count]]
        del self._pending[:count]
        return commands
