"""Differential harness: the vendor's firmware (the oracle, in an AVR simulator) and our emulator's
``--firmware classic`` profile, both driven as processes over their ptys, exactly as users do.

A :class:`Pair` starts both on a fresh power-on, sends the same bytes to both and records what
each answers (:class:`Exchange`). :meth:`Pair.check` compares the two transcripts byte for byte
after one normalisation only: :mod:`tests.oracle.allowlist` (texts of the field binaries that
differ from the source revision, each cited). Status lines taken while the arm moves are the one
other exception, because two processes cannot be sampled at the same simulated instant: in
exchanges marked ``moving=True`` the numbers inside status lines are compared by format, not by
value (state word, field names and digit counts stay exact). For byte-exact statuses during
motion, :func:`replay` feeds the writes of an :class:`OracleRecording` into our pure firmware
model at the oracle's own simulated instants (tests/oracle/test_replay_motion.py).

The oracle is located by ``MIROBOT_ORACLE_SOURCE`` (default ``../shared/firmware-oracle`` next to
the repository) and its build by ``MIROBOT_ORACLE_DIR`` (default
``~/.cache/mirobot-firmware-oracle``), as ``run.sh`` does.
"""

from __future__ import annotations

import os
import re
import selectors
import signal
import subprocess
import sys
import termios
import time
import tty
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .allowlist import normalise_ours

REPO = Path(__file__).resolve().parents[2]
ORACLE_SOURCE = Path(
    os.environ.get("MIROBOT_ORACLE_SOURCE", str(REPO.parent / "shared" / "firmware-oracle"))
)
_CACHE = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
ORACLE_BUILD = Path(os.environ.get("MIROBOT_ORACLE_DIR", str(_CACHE / "mirobot-firmware-oracle")))
BUILD_FILES = ("fwsim", "grbl.elf", "eeprom.bin", "sys_addr")
ENABLE_HINT = (
    "firmware oracle not built: run ../shared/firmware-oracle/build.sh "
    "(or set MIROBOT_ORACLE_DIR / MIROBOT_ORACLE_SOURCE) to enable tests/oracle"
)

EMULATOR_TIME_SCALE = 5.0  # close to the oracle's free-running speed (about 5-7x real time)
BANNER_END = b"Using reset pos!\r\n"
START_TIMEOUT = 20.0
STOP_TIMEOUT = 5.0


class HarnessError(RuntimeError):
    """The oracle itself did not answer as a scenario expects: a scenario or host problem, never
    a difference (so it is an error even in a test that is expected to fail)."""


def oracle_missing() -> str | None:
    """Why the oracle cannot run here (``None`` when it can)."""
    if not (ORACLE_SOURCE / "run.sh").is_file():
        return f"{ENABLE_HINT} [no {ORACLE_SOURCE}/run.sh]"
    missing = [f for f in BUILD_FILES if not (ORACLE_BUILD / f).is_file()]
    if missing:
        return f"{ENABLE_HINT} [{ORACLE_BUILD} lacks {', '.join(missing)}]"
    return None


# --------------------------------------------------------------------------------------------
# Reply structure


def lines_of(data: bytes) -> list[bytes]:
    """Complete lines of ``data`` (without their ``\\r\\n``)."""
    return [line.rstrip(b"\r") for line in data.split(b"\n")[:-1]]


def is_terminal(line: bytes) -> bool:
    """A line that ends the reply to one input line: ``ok`` (also glued to a message, as in
    ``in homeing moving...ok``) or ``error...``."""
    return line.endswith(b"ok") or line.startswith(b"error")


def is_status(line: bytes) -> bool:
    return line.startswith(b"<") and line.endswith(b">")


@dataclass(frozen=True)
class Until:
    """When the reply to one exchange is complete: at least ``terminals`` ok/error lines,
    ``statuses`` status lines and the text ``text``; then ``quiet`` more wall seconds are read."""

    terminals: int = 0
    statuses: int = 0
    text: bytes | None = None
    quiet: float = 0.0

    def met(self, data: bytes) -> bool:
        lines = lines_of(data)
        return (
            sum(map(is_terminal, lines)) >= self.terminals
            and sum(map(is_status, lines)) >= self.statuses
            and (self.text is None or self.text in data)
        )


def line_ends(data: bytes) -> int:
    """How many lines the firmware sees in ``data``: GRBL ends a line at ``\\r`` and ``\\n``."""
    return data.count(b"\n") + data.count(b"\r")


# --------------------------------------------------------------------------------------------
# One device


class Device:
    """A firmware process serving a pty: the oracle (``run.sh``) or our emulator."""

    def __init__(self, name: str, argv: Sequence[str], workdir: Path) -> None:
        self.name = name
        self.argv = list(argv)
        self.stderr_path = workdir / f"{name}.stderr"
        with open(self.stderr_path, "wb") as err:
            self.proc = subprocess.Popen(
                self.argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=err
            )
        self.fd = -1
        self.received = bytearray()
        self.mark = 0
        self.arrivals: list[tuple[float, int]] = []  # (wall time, len(received) after the read)

    def connect(self) -> None:
        """Open the pty (the oracle's MCU powers on now) and wait for the power-on banner."""
        assert self.proc.stdout is not None
        path = self._stdout_line(START_TIMEOUT)
        if not path.startswith("/"):
            raise RuntimeError(
                f"{self.name}: no pty path on stdout ({path!r}); see {self.stderr_path}"
            )
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        tty.setraw(self.fd, termios.TCSANOW)  # TCSANOW: no flush, the banner stays readable
        if not self.read_until(lambda d: BANNER_END in d, START_TIMEOUT):
            raise RuntimeError(f"{self.name}: no power-on banner: {bytes(self.received)!r}")

    def _stdout_line(self, timeout: float) -> str:
        assert self.proc.stdout is not None
        sel = selectors.DefaultSelector()
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        try:
            if not sel.select(timeout):
                raise RuntimeError(f"{self.name}: silent for {timeout} s; see {self.stderr_path}")
        finally:
            sel.close()
        return self.proc.stdout.readline().decode("utf-8", "replace").strip()

    def control(self, command: str, timeout: float = 5.0) -> str:
        """A control-channel command of our emulator; returns its ``ack`` line."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(command.encode() + b"\n")
        self.proc.stdin.flush()
        deadline = time.monotonic() + timeout
        while True:
            line = self._stdout_line(max(0.0, deadline - time.monotonic()))
            if line.startswith(("ack", "error")):
                if not line.startswith("ack"):
                    raise RuntimeError(f"{self.name} refused {command!r}: {line}")
                return line

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                n = os.write(self.fd, view)
            except BlockingIOError:
                self.pump(0.01)
                continue
            view = view[n:]

    def pump(self, timeout: float) -> bool:
        """Read what is available within ``timeout`` seconds; True if anything came."""
        sel = selectors.DefaultSelector()
        sel.register(self.fd, selectors.EVENT_READ)
        try:
            if not sel.select(timeout):
                return False
        finally:
            sel.close()
        try:
            chunk = os.read(self.fd, 65536)
        except (BlockingIOError, OSError):
            return False
        self.received += chunk
        self.arrivals.append((time.monotonic(), len(self.received)))
        return bool(chunk)

    def pending(self) -> bytes:
        return bytes(self.received[self.mark :])

    def take(self) -> bytes:
        data = self.pending()
        self.mark = len(self.received)
        return data

    def read_until(self, done: Callable[[bytes], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not done(self.pending()):
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            self.pump(min(left, 0.05))
        return True

    def read_quiet(self, seconds: float) -> None:
        while self.pump(seconds):
            pass

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        for stream in (self.proc.stdin, self.proc.stdout):
            if stream is not None:
                stream.close()


def pump_both(first: Device, second: Device, timeout: float) -> None:
    """Wait up to ``timeout`` seconds for either device, then read whatever each has (one
    select over both, so neither waits behind the other: arrival times stay sharp)."""
    sel = selectors.DefaultSelector()
    try:
        for device in (first, second):
            sel.register(device.fd, selectors.EVENT_READ, device)
        for key, _ in sel.select(timeout):
            key.data.pump(0)
    finally:
        sel.close()


def spawn_oracle(workdir: Path, *flags: str) -> Device:
    env_dir = str(ORACLE_BUILD)
    argv = ["env", f"MIROBOT_ORACLE_DIR={env_dir}", str(ORACLE_SOURCE / "run.sh"), "-s", "0"]
    argv += ["-l", str(workdir / "oracle.log"), *flags]
    return Device("oracle", argv, workdir)


def spawn_emulator(workdir: Path, *flags: str, time_scale: float = EMULATOR_TIME_SCALE) -> Device:
    argv = [sys.executable, "-m", "mirobot_emulator", "--firmware", "classic"]
    argv += ["--time-scale", repr(time_scale), *flags]
    return Device("ours", argv, workdir)


# --------------------------------------------------------------------------------------------
# The pair


@dataclass
class Exchange:
    """What was sent in one step and what each side answered to it."""

    sent: bytes
    oracle: bytes
    ours: bytes
    moving: bool = False
    note: str = ""


_NUMBER = re.compile(rb"-?\d+(\.\d+)?")


def mask_status_numbers(data: bytes) -> bytes:
    """Status lines with every number replaced by its format (``-12.345`` -> ``#.###``): sign
    and value depend on the sampled instant, the number of decimals does not."""

    def mask_line(line: bytes) -> bytes:
        if not is_status(line.rstrip(b"\r")):
            return line
        return _NUMBER.sub(
            lambda m: b"#" + (b"." + b"#" * (len(m.group(1)) - 1) if m.group(1) else b""), line
        )

    return b"\n".join(mask_line(line) for line in data.split(b"\n"))


@dataclass
class Pair:
    """The oracle and our emulator, powered on together and fed the same bytes."""

    oracle: Device
    ours: Device
    exchanges: list[Exchange] = field(default_factory=list)
    banner: Exchange | None = None
    first_write: float = 0.0
    """Wall time just before the last :meth:`stream` wrote its first byte to our emulator."""

    @classmethod
    def spawn(
        cls,
        workdir: Path,
        oracle_flags: Sequence[str] = (),
        our_flags: Sequence[str] = (),
        time_scale: float = EMULATOR_TIME_SCALE,
    ) -> Pair:
        """Start both processes (without waiting); :meth:`connect` powers them on."""
        workdir.mkdir(parents=True, exist_ok=True)
        oracle = spawn_oracle(workdir, *oracle_flags)
        try:
            ours = spawn_emulator(workdir, *our_flags, time_scale=time_scale)
        except BaseException:
            oracle.close()
            raise
        return cls(oracle, ours)

    def connect(self) -> Pair:
        try:
            self.oracle.connect()
            self.ours.connect()
        except BaseException:
            self.close()
            raise
        self.banner = Exchange(b"", self.oracle.take(), self.ours.take(), note="power-on")
        self.exchanges.append(self.banner)
        return self

    def close(self) -> None:
        for device in (self.oracle, self.ours):
            device.close()

    # --------------------------------------------------------------- sending
    def send(
        self,
        data: bytes | str,
        until: Until | None = None,
        *,
        moving: bool = False,
        timeout: float = 20.0,
        note: str = "",
    ) -> Exchange:
        """Send ``data`` to both; read until ``until`` (default: one ok/error per line end)."""
        raw = data.encode() if isinstance(data, str) else data
        until = until or Until(terminals=line_ends(raw))
        for device in (self.oracle, self.ours):
            device.write(raw)
        start = time.monotonic()
        if not self.oracle.read_until(until.met, timeout):
            raise HarnessError(
                f"the oracle did not complete {until} after {raw!r} within {timeout} s; "
                f"it said {self.oracle.pending()!r}"
            )
        spent = time.monotonic() - start
        self.ours.read_until(until.met, 4.0 + 2 * spent)
        if until.quiet:
            self.oracle.read_quiet(until.quiet)
            self.ours.read_quiet(until.quiet)
        exchange = Exchange(raw, self.oracle.take(), self.ours.take(), moving, note)
        self.exchanges.append(exchange)
        return exchange

    def lines(self, *lines: str, moving: bool = False) -> list[Exchange]:
        """Send each line (``\\n`` added) and wait for its reply before the next."""
        return [self.send(line + "\n", moving=moving) for line in lines]

    def settle(self) -> Exchange:
        """``G4 P0``: its ``ok`` comes once the planner is empty (GRBL synchronises dwells)."""
        return self.send("G4 P0\n", note="settle")

    def status(self, *, moving: bool = False) -> Exchange:
        return self.send(b"?", Until(statuses=1), moving=moving)

    def reset(self) -> Exchange:
        """``%``: the banner, and what follows it (the unlock hint after an alarm)."""
        return self.send(b"%", Until(text=BANNER_END, quiet=0.1))

    def finish(self, quiet: float = 0.15) -> Exchange:
        """Collect whatever either side still prints (``quiet`` wall seconds of silence)."""
        return self.send(b"", Until(quiet=quiet), note="trailing output")

    def stream(self, lines: Sequence[str], window: int = 127, timeout: float = 60.0) -> Exchange:
        """Character-counting streaming of ``lines`` to both at once (at most ``window`` bytes
        unacknowledged per side), until every line is answered or ``timeout`` wall seconds."""
        payloads = [(line + "\n").encode() for line in lines]
        senders = [_Streamer(d, payloads, window) for d in (self.oracle, self.ours)]
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not all(s.done() for s in senders):
            for sender in senders:
                sender.step()
            pump_both(self.oracle, self.ours, 0.005)
        self.first_write = senders[1].first_write
        exchange = Exchange(
            b"".join(payloads), self.oracle.take(), self.ours.take(), note="streamed"
        )
        self.exchanges.append(exchange)
        return exchange

    # --------------------------------------------------------------- comparing
    def differences(self) -> list[str]:
        """Every exchange whose replies differ after normalisation, described."""
        out = []
        for i, ex in enumerate(self.exchanges):
            oracle, ours = ex.oracle, normalise_ours(ex.ours)
            if ex.moving:
                oracle, ours = mask_status_numbers(oracle), mask_status_numbers(ours)
            if oracle != ours:
                what = f"{ex.note}: " if ex.note else ""
                out.append(
                    f"#{i} {what}sent {_short(ex.sent)}\n"
                    f"    oracle: {oracle!r}\n    ours:   {ours!r}"
                )
        return out

    def check(self) -> None:
        """Fail with every difference found (all exchanges, not just the first)."""
        self.finish()
        diffs = self.differences()
        if diffs:
            raise AssertionError("oracle and emulator differ:\n" + "\n".join(diffs))


class _Streamer:
    """One side of :meth:`Pair.stream`: keeps at most ``window`` unacknowledged bytes."""

    def __init__(self, device: Device, payloads: list[bytes], window: int) -> None:
        self.device, self.payloads, self.window = device, payloads, window
        self.base = len(device.received)
        self.next = 0
        self.in_flight: list[int] = []
        self.answered = 0
        self.first_write = 0.0  # wall time just before the first byte was written

    def done(self) -> bool:
        return self.answered >= len(self.payloads)

    def step(self) -> None:
        replies = lines_of(bytes(self.device.received[self.base :]))
        answered = sum(map(is_terminal, replies))
        while self.in_flight and self.answered < answered:
            self.in_flight.pop(0)
            self.answered += 1
        while self.next < len(self.payloads) and (
            sum(self.in_flight) + len(self.payloads[self.next]) <= self.window
        ):
            if not self.next:
                self.first_write = time.monotonic()
            self.device.write(self.payloads[self.next])
            self.in_flight.append(len(self.payloads[self.next]))
            self.next += 1


def _short(data: bytes, limit: int = 300) -> str:
    text = repr(data)
    return text if len(text) <= limit else text[:limit] + f"...({len(data)} bytes)"


# --------------------------------------------------------------------------------------------
# Simulated time


def oracle_log(workdir: Path) -> list[tuple[float, str]]:
    """The oracle's ``-l`` log: every output line with its simulated time in seconds."""
    entries = []
    for raw in (workdir / "oracle.log").read_text("latin-1").splitlines():
        stamp, _, text = raw.partition(" ")
        entries.append((float(stamp), text))
    return entries


def motion_ends(device: Device) -> list[float]:
    """Our emulator's ends of motion (wall instants mapped exactly from its simulated clock)."""
    words = device.control("motion-ends").split()
    return [float(w) for w in words[2:]]


# --------------------------------------------------------------------------------------------
# Replay: the oracle's bytes at its own simulated instants, into our pure firmware model

ORACLE_TX_BYTE = 93.5e-6
"""Simulated seconds per byte the oracle's UART sends (measured on its ``-l`` log: the banner's
``D1: 78\\r\\n`` lines end 0.748 ms apart, an ``ok\\r\\n`` 0.374 ms after the line before)."""

ORACLE_REPORT_DELAY = 1.6e-3
"""Simulated seconds from a status report's sampling to its first byte on the wire, at most
(measured: after ``M50\n?`` the status line ends 17.98 ms after the ``ok`` line, 1.62 ms more
than its 175 bytes take)."""

ANCHORED_STATUS = b"\n    ?"
"""An empty line, then ``?`` 0.5 ms later (four filtered spaces): the oracle prints the ``ok``
first and samples its report right after it (see :meth:`OracleRecording.poll`)."""

REPLAY_STEPS_PER_UNIT = (56.73, 113.33, 64.0, 16.0, 22.22, 11.11, 200.0)
"""``$100..$106`` at power-on in JOINT order (J1..J6, rail): the status angles back to steps."""


@dataclass
class Sent:
    """One write to the oracle during a recording: the bytes and how many output lines the
    host had received before it (replies to it come later)."""

    data: bytes
    anchor: int


class OracleRecording:
    """The oracle alone, driven by a script; what was written and when, for :func:`replay`.

    Every write must provoke a reply line the replay can time it by: a status (a chunk that
    ends with ``?``, so ``!`` and ``~`` are sent as ``!?`` and ``~?``) or one ok/error per
    line end."""

    def __init__(self, workdir: Path) -> None:
        workdir.mkdir(parents=True, exist_ok=True)
        self.workdir = workdir
        self.device = spawn_oracle(workdir)
        self.sent: list[Sent] = []
        try:
            self.device.connect()
        except BaseException:
            self.device.close()
            raise

    def received_lines(self) -> int:
        return len(lines_of(bytes(self.device.received)))

    def write(self, data: bytes) -> None:
        if not (data.endswith(b"?") or line_ends(data)):
            raise ValueError(f"{data!r} provokes no reply line to time it by")
        self.sent.append(Sent(data, self.received_lines()))
        self.device.write(data)

    def send(self, data: bytes | str, until: Until | None = None, timeout: float = 30.0) -> None:
        """Write ``data`` and read until ``until`` (default: one reply line per line end, or
        the status of a trailing ``?``)."""
        raw = data.encode() if isinstance(data, str) else data
        if until is None:
            until = Until(terminals=line_ends(raw), statuses=1 if raw.endswith(b"?") else 0)
        self.write(raw)
        if not self.device.read_until(until.met, timeout):
            raise HarnessError(f"oracle: {until} not met after {raw!r}: {self.device.pending()!r}")
        if until.quiet:
            self.device.read_quiet(until.quiet)
        self.device.take()

    def poll(
        self,
        interval: float,
        done: Callable[[bytes], bool],
        timeout: float = 60.0,
        *,
        anchored: bool = True,
    ) -> None:
        """``?`` every ``interval`` wall seconds (each after the previous status) until
        ``done(everything received since the poll began)``.

        ``anchored``: each ``?`` follows an empty line (``\\n?``), whose ``ok`` times it: the
        oracle samples its report right after that ``ok``, while the status line itself ends
        16-28 ms later, the more the faster the arm moves (its stepper interrupts slow the
        report down: 1.6 ms beyond the line's bytes at rest, 11.2 ms at 1890 steps/s). Not
        while held: lines wait until ``~`` there."""
        start = len(self.device.received)
        deadline = time.monotonic() + timeout
        while not done(bytes(self.device.received[start:])):
            if time.monotonic() > deadline:
                raise HarnessError(f"oracle: poll did not end: {self.device.pending()!r}")
            before = self.device.received.count(b">")
            self.write(ANCHORED_STATUS if anchored else b"?")
            if not self.device.read_until(lambda _d: self._statuses() > before, 5.0):  # noqa: B023
                raise HarnessError("oracle: no status within 5 s")
            self.device.read_quiet(interval)
        self.device.take()

    def _statuses(self) -> int:
        return self.device.received.count(b">")

    def close(self) -> None:
        self.device.close()


@dataclass
class ReplayResult:
    """Our model's transcript beside the oracle's, line by line (after the power-on banner)."""

    oracle: list[bytes]
    ours: list[bytes]
    equal_statuses: int = 0
    moving_statuses: int = 0
    differences: list[str] = field(default_factory=list)
    step_differences: list[int] = field(default_factory=list)
    """Per differing status line: the largest difference of an axis, in motor steps."""
    time_shifts: list[float] = field(default_factory=list)
    """Per differing status line: seconds by which our model reaches the oracle's step counts
    later (positive) or earlier than the oracle's sampling instant (nearest within 0.1 s)."""
    path_distances: list[int] = field(default_factory=list)
    """Per differing status line: how far (largest axis difference, motor steps) the oracle's
    step counts are from the nearest point of our model's step path within 0.1 s: 0 when our
    path passes exactly through them and only the sampling instant differs."""


def status_steps(line: bytes) -> tuple[int, ...] | None:
    """Motor steps (joint order J1..J6, rail) of a status line's angles (None: no angles)."""
    match = re.search(rb"Angle\(ABCDXYZ\):([-\d.,]+),Cartesian", line)
    if match is None:
        return None
    a = [float(x) for x in match.group(1).split(b",")]
    joints = (a[4], a[5], a[6], a[0], a[1], a[2], a[3])
    return tuple(round(q * s) for q, s in zip(joints, REPLAY_STEPS_PER_UNIT, strict=True))


def _claim(
    lines: list[bytes],
    claimed: set[int],
    start: int,
    wanted: Callable[[bytes], bool],
    count: int,
    what: bytes,
) -> list[int]:
    found = []
    for i in range(start, len(lines)):
        if i not in claimed and wanted(lines[i]):
            found.append(i)
            if len(found) == count:
                break
    if len(found) < count:
        raise HarnessError(f"no reply to {what!r} in the oracle's transcript")
    claimed.update(found)
    return found


def _reply_times(
    recording: OracleRecording,
) -> tuple[list[bytes], list[float], list[tuple[float, bool]]]:
    """The oracle's lines, the simulated instant each began to be sent, and per write: when
    its timing reply began and whether that reply is a status (else its last ok/error).

    A write ending ``?`` with a line end (``\\n?``) is timed by its ``ok`` unless the oracle
    printed the status first (it read the ``?`` before the line): then by the status."""
    log = oracle_log(recording.workdir)
    lines = lines_of(bytes(recording.device.received))
    if len(log) < len(lines):
        raise HarnessError(f"oracle log has {len(log)} lines, the host received {len(lines)}")
    starts = [t - (len(text) + 2) * ORACLE_TX_BYTE for t, text in log[: len(lines)]]
    claimed: set[int] = set()
    replies = []
    for sent in recording.sent:
        data, anchor = sent.data, sent.anchor
        ends = line_ends(data)
        terminals = _claim(lines, claimed, anchor, is_terminal, ends, data) if ends else []
        status = _claim(lines, claimed, anchor, is_status, 1, data) if data.endswith(b"?") else []
        if status and (not terminals or status[0] < terminals[-1]):
            replies.append((starts[status[0]] - ORACLE_REPORT_DELAY, True))
        else:
            replies.append((starts[terminals[-1]], False))
    return lines, starts, replies


def replay(recording: OracleRecording, settle: float = 1.0) -> ReplayResult:
    """Feed our pure firmware model (:class:`mirobot_emulator.firmware.Firmware`) the recorded
    writes so that each one's timing reply begins at the oracle's simulated instant (our own
    latency for it measured on a copy of the model), and compare every line.

    Our clock starts where the oracle's banner line ``Using reset pos!`` began."""
    import copy

    from mirobot_emulator.firmware import Firmware

    lines, starts, replies = _reply_times(recording)
    banner_end = next(i for i, line in enumerate(lines) if BANNER_END.startswith(line + b"\r"))
    t0 = starts[banner_end]
    fw = Firmware("classic")
    fw.read_output()
    ours: list[tuple[float, bytes]] = []
    timeline: list[tuple[float, tuple[int, ...]]] = []

    def steps_now() -> tuple[int, ...]:
        return tuple(round(q * s) for q, s in zip(fw.joints, REPLAY_STEPS_PER_UNIT, strict=True))

    def run_to(t: float, trace: float = 0.0005) -> None:
        while fw.now < t - 1e-12:
            deadline = fw.next_deadline()
            step = t - fw.now if deadline is None else min(max(deadline - fw.now, 0.0), t - fw.now)
            fw.advance(min(step, trace) if fw.planner.busy else step)
            timeline.append((fw.now, steps_now()))
            for line in lines_of(fw.read_output()):
                ours.append((fw.now, line))

    expected = {True: 0, False: 0}  # replies owed to earlier writes: statuses, ok/error

    def seen(status: bool) -> int:
        return sum(1 for _t, line in ours if (is_status(line) if status else is_terminal(line)))

    def latency(data: bytes, status: bool) -> float:
        """Seconds from writing ``data`` now until our model begins its timing reply (on a
        copy, counting past the replies still owed to earlier writes)."""
        probe = copy.deepcopy(fw)
        start = probe.now
        probe.receive(data)
        wanted = is_status if status else is_terminal
        need = expected[status] - seen(status) + (1 if status else line_ends(data))
        got = 0
        while True:
            got += sum(map(wanted, lines_of(probe.read_output())))
            if got >= need:
                return probe.now - start
            deadline = probe.next_deadline()
            if deadline is None or deadline - start > 30.0:
                return 0.0
            probe.advance(max(deadline - probe.now, 0.0))

    def run_until_printed(count: int) -> None:
        """Causality: the host wrote after it had read ``count`` lines; so must ours."""
        while len(ours) < count:
            deadline = fw.next_deadline()
            if deadline is None:
                return
            run_to(max(deadline, fw.now + 1e-6))

    for sent, (reply, by_status) in zip(recording.sent, replies, strict=True):
        run_until_printed(sent.anchor - banner_end - 1)
        for _ in range(8):  # our latency shrinks as the write waits (a parse ends meanwhile)
            target = reply - t0 - latency(sent.data, by_status)
            if target <= fw.now + 1e-7:
                break
            run_to(target)
        fw.receive(sent.data)
        expected[True] += sent.data.endswith(b"?")
        expected[False] += line_ends(sent.data)
    run_to(max(starts[-1] - t0, fw.now) + settle)
    result = ReplayResult(lines[banner_end + 1 :], [line for _t, line in ours])
    _compare(result, [at for at, _line in ours], timeline)
    return result


def _compare(
    result: ReplayResult, our_times: list[float], timeline: list[tuple[float, tuple[int, ...]]]
) -> None:
    """Other lines in order, statuses in order (a status and an ``ok`` printed within a
    fraction of a millisecond of each other may come in either order)."""
    others = [line for line in result.oracle if not is_status(line)]
    mine = [line for line in result.ours if not is_status(line)]
    if others != mine:
        result.differences.append(f"other lines: oracle {others!r}\n          ours   {mine!r}")
    ours = [(t, line) for t, line in zip(our_times, result.ours, strict=True) if is_status(line)]
    theirs_all = [line for line in result.oracle if is_status(line)]
    for k, (theirs, (at, line)) in enumerate(zip(theirs_all, ours, strict=False)):
        moving = not theirs.startswith(b"<Idle")
        result.moving_statuses += moving
        if theirs == line:
            result.equal_statuses += 1
            continue
        result.differences.append(f"status {k}: oracle {theirs!r}\n          ours   {line!r}")
        a, b = status_steps(theirs), status_steps(line)
        if a is None or b is None:
            continue
        result.step_differences.append(max(abs(x - y) for x, y in zip(a, b, strict=True)))
        near = [
            (max(abs(x - y) for x, y in zip(a, s, strict=True)), abs(t - at), t - at)
            for t, s in timeline
            if abs(t - at) <= 0.1
        ]
        if near:
            result.time_shifts.append(min(near)[2])
            result.path_distances.append(min(near)[0])
    if len(theirs_all) != len(ours):
        result.differences.append(f"{len(theirs_all)} oracle statuses, {len(ours)} ours")
