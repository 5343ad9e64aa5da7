"""Item 10, "a real program": the same program from several clients over a paced link.

Each program of :mod:`programs` runs on an emulator process at a real time scale, its link paced
at 115200 baud with a USB latency timer, from each client in turn:

* ``stream()``: ``await arm.stream(lines, wait=True)`` (ends on the ``ok`` of a ``G4 P0``
  written after the last line: the firmware answers it when its planner is empty);
* the path call ``arm.move_path(poses, linear=True, speed=...)`` if the client has one;
* a ``move_pose(wait=True)`` loop (``move_joints`` for joint steps, ``send`` for other lines);
* plain pyserial: write a line, read until ``ok``, next line; then poll ``?`` every 50 ms until
  ``Idle`` (what most scripts do).

For each run: the wall time from the first byte to the client's return, divided by the
program's motion time (:func:`programs.ideal_run`: the emulator's firmware model fed by an ideal
host); the starvations (the emulator's planner ran empty while lines remained: ends of motion
reported by its ``motion-ends`` control command inside the run, minus the final one); and the
tail (the client's return minus the last end of motion).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import time
from collections.abc import AsyncIterator, Awaitable, Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import serial
from programs import IdealRun, Program, full_programs, ideal_run, quick_programs

from mirobot_async import Mirobot
from mirobot_async.virtual import EmulatorError, EmulatorProcess

MOTION_ENDS_POLL_S = 0.5
"""The emulator keeps its last 64 ends of motion: fetch them this often during a run."""
PYSERIAL_POLL_S = 0.05
WIRE_BAUD = 115200
STATUS_INTERVAL_S = 0.1
"""The concurrent ``statuses(interval=...)`` consumer of the tail and ok-latency figures."""

STATUS_REPORT_BYTES = 190
"""A 2021 status report with its CR LF: 16.5 ms of the robot's output wire at 115200 baud."""

CLIENTS = ("stream()", "move_path()", "move_pose(wait=True) loop", "pyserial send/wait-ok loop")


@dataclass(frozen=True)
class Item10Config:
    """What to run: programs, USB latencies, (program keys, clients) per latency, time scale,
    repetitions of the tail and ok-latency figures."""

    programs: tuple[Program, ...]
    latencies: tuple[int, ...]
    clients: dict[int, tuple[str, ...]]
    keys: dict[int, tuple[str, ...]]
    time_scale: float
    tail_reps: int
    ok_samples: int

    @classmethod
    def make(cls, quick: bool) -> Item10Config:
        if quick:
            programs = tuple(quick_programs())
            keys = tuple(p.key for p in programs)
            return cls(programs, (16,), {16: CLIENTS}, {16: keys}, 10.0, tail_reps=5, ok_samples=20)
        # At 1 ms only the programs and clients where the latency can matter (real time: each
        # run takes the program's motion time, about a minute for (a) and (b)).
        return cls(
            tuple(full_programs()),
            (16, 1),
            {16: CLIENTS, 1: ("stream()", "move_path()", "pyserial send/wait-ok loop")},
            {16: ("a", "b", "c"), 1: ("b", "c")},
            1.0,
            tail_reps=20,
            ok_samples=100,
        )


@dataclass
class Run:
    """One client's run of one program."""

    program: Program
    latency: int
    client: str
    ideal: IdealRun
    wall: float | None = None  # None: the client has no such call
    starvations: int | None = None
    tail: float | None = None
    move_tails: list[float] = field(default_factory=list)  # wait loop: one per move
    counter: int | None = None  # the emulator's own starvation counter, if it has one
    load: float = 0.0
    error: str = ""


class MotionEnds:
    """Ends of motion fetched from the emulator during a run (it keeps only the last 64)."""

    def __init__(self, emulator: EmulatorProcess) -> None:
        self._emulator = emulator
        self.ends: set[float] = set()

    async def fetch(self) -> None:
        reply = await self._emulator.control("motion-ends")
        self.ends.update(float(word) for word in reply.split()[2:])

    @contextlib.asynccontextmanager
    async def watching(self) -> AsyncIterator[None]:
        async def poll() -> None:
            while True:
                await asyncio.sleep(MOTION_ENDS_POLL_S)
                await self.fetch()

        task = asyncio.create_task(poll())
        try:
            yield
        finally:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
            await self.fetch()

    def between(self, start: float, end: float) -> list[float]:
        return sorted(t for t in self.ends if start < t <= end)


async def starvation_counter(emulator: EmulatorProcess) -> int | None:
    """The emulator's own starvation counter (control query ``starvations``), None while its
    firmware model does not expose one (the query is refused)."""
    try:
        reply = await emulator.control("starvations")
    except EmulatorError:
        return None
    words = reply.split()
    return int(words[2]) if len(words) > 2 and words[2].isdigit() else None


async def prepare(url: str, program: Program) -> None:
    """Bring the arm to the program's start and wait until it is there (not timed)."""
    async with Mirobot.connect(url) as arm:
        for line in program.setup:
            await arm.send(line)
        await arm.wait_idle()


@contextlib.asynccontextmanager
async def status_consumer(arm: Mirobot, interval: float | None) -> AsyncIterator[None]:
    """A concurrent ``statuses(interval)`` consumer for the block (none if ``interval`` is None)."""
    if interval is None:
        yield
        return

    async def consume() -> None:
        async for _report in arm.statuses(interval=interval):
            pass

    task = asyncio.create_task(consume())
    try:
        yield
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task


async def client_stream(arm: Mirobot, program: Program, returns: list[float]) -> None:
    result = await arm.stream(program.lines, wait=True)
    assert result.ok and result.acknowledged == len(program.lines), result


async def client_path(arm: Mirobot, program: Program, returns: list[float]) -> None:
    poses = program.poses
    assert poses is not None
    await arm.move_path(poses, linear=True, speed=program.speed)  # type: ignore[attr-defined]


async def client_wait_loop(arm: Mirobot, program: Program, returns: list[float]) -> None:
    for step in program.steps:
        if step.kind == "pose" and step.values is not None:
            await arm.move_pose(*step.values, linear=True, speed=step.speed, wait=True)
            returns.append(time.monotonic())
        elif step.kind == "joints" and step.values is not None:
            await arm.move_joints(*step.values, speed=step.speed, wait=True)
            returns.append(time.monotonic())
        else:
            await arm.send(step.line)


def pyserial_program(url: str, lines: Sequence[str]) -> tuple[float, float]:
    """Send each line and wait for its ``ok``, then poll ``?`` until Idle; (start, return)."""
    with serial.Serial(url, WIRE_BAUD, timeout=10) as port:
        port.reset_input_buffer()
        start = time.monotonic()
        for line in lines:
            port.write(line.encode("ascii") + b"\n")
            while True:
                reply = port.readline()
                if not reply:
                    raise TimeoutError(f"no ok for {line!r}")
                if reply.startswith(b"ok") or reply.startswith(b"error"):
                    break
        while True:
            port.write(b"?")
            reply = port.readline()
            while reply and not reply.startswith(b"<"):
                reply = port.readline()
            if reply.startswith(b"<Idle"):
                return start, time.monotonic()
            time.sleep(PYSERIAL_POLL_S)


ClientCall = Callable[[Mirobot, Program, list[float]], Awaitable[None]]
CLIENT_CALLS: dict[str, ClientCall] = {
    "stream()": client_stream,
    "move_path()": client_path,
    "move_pose(wait=True) loop": client_wait_loop,
}


def client_missing(client: str, program: Program) -> str:
    """Why ``client`` cannot run ``program`` ("" when it can)."""
    if client == "move_path()":
        if not hasattr(Mirobot, "move_path"):
            return "n/a: Mirobot has no move_path yet"
        if program.poses is None:
            return "n/a: not a pose-only program"
    return ""


async def run_client(emulator: EmulatorProcess, run: Run, interval: float | None = None) -> None:
    """One run: prepare, time the client, collect the ends of motion and the counter."""
    program = run.program
    missing = client_missing(run.client, program)
    if missing:
        run.error = missing
        return
    await prepare(emulator.url, program)
    ends = MotionEnds(emulator)
    await ends.fetch()
    counter_before = await starvation_counter(emulator)
    returns: list[float] = []
    run.load = _load()
    async with ends.watching():
        if run.client == "pyserial send/wait-ok loop":
            start, done = await asyncio.to_thread(pyserial_program, emulator.url, program.lines)
        else:
            async with (
                Mirobot.connect(emulator.url) as arm,
                status_consumer(arm, interval),
            ):
                start = time.monotonic()
                await CLIENT_CALLS[run.client](arm, program, returns)
                done = time.monotonic()
    counter_after = await starvation_counter(emulator)
    inside = ends.between(start, done)
    run.wall = done - start
    run.starvations = max(0, len(inside) - 1)
    run.tail = done - inside[-1] if inside else None
    if counter_before is not None and counter_after is not None:
        run.counter = max(0, counter_after - counter_before - 1)  # the first block after setup
    previous = start
    for returned in returns:
        mine = ends.between(previous, returned)
        if mine:
            run.move_tails.append(returned - mine[-1])
        previous = returned


def _load() -> float:
    return os.getloadavg()[0]


# ---- tail and ok latency with and without a statuses() consumer -----------------------------


@dataclass
class LatencyFigures:
    """Tails of a short streamed program and ok round trips, per consumer setting."""

    tails: dict[str, list[float]] = field(default_factory=dict)
    oks: dict[str, list[float]] = field(default_factory=dict)
    load: float = 0.0


TAIL_LINES = (
    "M21 G90 G1 X0.75 Y0 Z0 A0 B0 C0 F2000",
    "M21 G90 G1 X0 Y0 Z0 A0 B0 C0 F2000",
)


COMPLETIONS = ("stream(wait=True)", "stream() + wait_idle()")
"""The two ways to wait for a stream's motion: the dwell barrier, or polling statuses."""


async def _stream_tail(arm: Mirobot, ends: MotionEnds, completion: str) -> float | None:
    start = time.monotonic()
    if completion == "stream(wait=True)":
        result = await arm.stream(TAIL_LINES, wait=True)
    else:
        result = await arm.stream(TAIL_LINES)
        await arm.wait_idle()
    assert result.ok, result
    done = time.monotonic()
    await ends.fetch()
    inside = ends.between(start, done)
    return done - inside[-1] if inside else None


async def measure_latencies(emulator: EmulatorProcess, config: Item10Config) -> LatencyFigures:
    """Tail of two short streamed joint moves (each completion of :data:`COMPLETIONS`), and
    ``send("G90")`` round trips, each without and with a concurrent ``statuses(interval=0.1)``
    consumer."""
    figures = LatencyFigures(load=_load())
    ends = MotionEnds(emulator)
    async with Mirobot.connect(emulator.url) as arm:
        await arm.send(TAIL_LINES[1])
        await arm.wait_idle()
        for consumer, interval in (("no consumer", None), ("statuses(0.1 s)", STATUS_INTERVAL_S)):
            oks: list[float] = []
            async with status_consumer(arm, interval):
                for completion in COMPLETIONS:
                    tails: list[float] = []
                    for _ in range(config.tail_reps):
                        tail = await _stream_tail(arm, ends, completion)
                        if tail is not None:
                            tails.append(tail)
                    figures.tails[f"{completion} | {consumer}"] = tails
                for _ in range(config.ok_samples):
                    t = time.monotonic()
                    await arm.send("G90")
                    oks.append(time.monotonic() - t)
            for completion in COMPLETIONS:
                figures.oks[f"{completion} | {consumer}"] = oks
    return figures


# ---- the whole item ---------------------------------------------------------------------------


async def measure_item10(config: Item10Config) -> tuple[list[Run], dict[int, LatencyFigures]]:
    ideals = {program.key: ideal_run(program) for program in config.programs}
    runs: list[Run] = []
    latencies: dict[int, LatencyFigures] = {}
    for latency in config.latencies:
        args = ["--baud", str(WIRE_BAUD), "--usb-latency-ms", str(latency)]
        emulator = await EmulatorProcess.start("2021", config.time_scale, extra_args=args)
        async with emulator:
            async with Mirobot.connect(emulator.url) as arm:
                await arm.unlock()
            for program in config.programs:
                if program.key not in config.keys[latency]:
                    continue
                for client in config.clients[latency]:
                    run = Run(program, latency, client, ideals[program.key])
                    try:
                        await run_client(emulator, run)
                    except Exception as exc:
                        run.error = f"failed: {type(exc).__name__}: {exc}"[:120]
                    runs.append(run)
            latencies[latency] = await measure_latencies(emulator, config)
    return runs, latencies


def _ms(seconds: float | None) -> str:
    return "-" if seconds is None else f"{seconds * 1e3:.1f}"


def _p(samples: Sequence[float], q: float) -> float:
    return float(np.percentile(np.asarray(samples, dtype=float), q))


def render_item10(config: Item10Config, runs: list[Run], lat: dict[int, LatencyFigures]) -> str:
    """Item 10's tables (markdown) and their notes."""
    scale = config.time_scale
    stopping: list[str] = []
    out = [
        "**Item 10: a real program** (2021 profile, link paced at 115200 baud, "
        f"time scale {scale:g}{'' if scale == 1 else ': NOT real time, do not quote'})",
        "",
        "| Program | USB latency | Client | Wall s | Motion s | Wall / motion | Starvations "
        "| Tail ms | Load |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for key, ideal in {run.program.key: run.ideal for run in runs}.items():
        blends = ideal.stopping_seconds / ideal.seconds if ideal.seconds else 1.0
        stopping.append(f"({key}) {ideal.stopping_seconds / scale:.2f} s, x{blends:.3f}")
    for run in runs:
        motion = run.ideal.seconds / scale
        if run.wall is None:
            cells = ["-", f"{motion:.2f}", run.error or "-", "-", "-", "-"]
        else:
            starv = f"{run.starvations}"
            if run.ideal.starvations:
                starv += f" (program: {run.ideal.starvations})"
            if run.counter is not None:
                starv += f" (counter {run.counter})"
            if run.move_tails:
                tail = (
                    f"{_ms(run.tail)}; per move p50 {_ms(_p(run.move_tails, 50))} "
                    f"p99 {_ms(_p(run.move_tails, 99))}"
                )
            else:
                tail = _ms(run.tail)
            cells = [
                f"{run.wall:.2f}",
                f"{motion:.2f}",
                f"{run.wall / motion:.3f}",
                starv,
                tail,
                f"{run.load:.1f}",
            ]
        out.append(
            f"| {run.program.key} | {run.latency} ms | {run.client} | " + " | ".join(cells) + " |"
        )
    status_wire_ms = STATUS_REPORT_BYTES * 10 / WIRE_BAUD * 1e3
    out += [
        "",
        "| USB latency | Completion | Statuses consumer | Tail p50 / p99 ms "
        "| ok round trip p50 / p99 ms | Tail target ms | Load |",
        "|---|---|---|---|---|---|---|",
    ]
    for latency, figures in lat.items():
        target = status_wire_ms + latency + 5
        for label, tails in figures.tails.items():
            oks = figures.oks[label]
            tail_text = f"{_ms(_p(tails, 50))} / {_ms(_p(tails, 99))}" if tails else "-"
            met = "met" if tails and _p(tails, 99) * 1e3 <= target else "NOT met"
            out.append(
                f"| {latency} ms | {label} | {tail_text} | "
                f"{_ms(_p(oks, 50))} / {_ms(_p(oks, 99))} | <= {target:.1f}: {met} "
                f"| {figures.load:.1f} |"
            )
    out += [
        "",
        "- Programs: " + "; ".join(p.title for p in config.programs) + ".",
        "- Motion s: the emulator's firmware model (the code the emulator runs) fed by an ideal "
        "host (each line written as soon as the 128-byte receive ring has room, no wire), from "
        "the first byte to the end of motion. Wall s: the client's first byte to its return.",
        "- Starvations: the emulator's ends of motion (control command `motion-ends`) inside the "
        "run, minus the final one: the times its planner ran empty while lines remained. "
        "'program: N': the ideal host sees N too (lines that wait for motion). 'counter N': "
        "the emulator's own starvation counter (control query `starvations`), when its "
        "firmware model exposes one (minus the first block after the setup move).",
        "- Tail: the client's return minus the last end of motion. The wait loop also gives one "
        "tail per move. Second table: tail of two streamed 0.75 deg joint moves, ended by "
        "`stream(wait=True)` (a `G4 P0` barrier) or by `stream()` + `wait_idle()` (status "
        f"polling) ({config.tail_reps} runs each) and `send('G90')` round trips "
        f"({config.ok_samples}), "
        "without and with a concurrent `statuses(interval=0.1)` consumer; target: one status "
        "report's wire time (~190 B, 16.5 ms) + the USB latency + 5 ms.",
        "- Load: the 1-minute load average when the run started (shared machine).",
        "- The firmware model fed one line at a time, each after the previous motion ended (the "
        "best a wait=True loop can do) takes, in wall seconds, x its motion time (x1.000: the "
        "emulator's planner does not blend these lines): " + "; ".join(stopping) + ".",
    ]
    return "\n".join(out)
