"""Benchmarks of mirobot-async against the virtual Mirobot: ``python benchmarks/run.py [--quick]``.

Prints one markdown table (machine in its header), then item 10's tables. See issue 6 for what
items 1-9 measure and why, issue 12 for item 10 ("a real program", :mod:`real_program`).
Sans-IO figures run in this process (:mod:`sansio`), as does item 11 (a user's test on the
in-process virtual arm, :mod:`in_process`); everything else drives the emulator *process* over a
real pseudo-terminal (:func:`mirobot_async.virtual.start_emulator`).
``--item10`` runs item 10 alone (at real time it takes a few minutes).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import gc
import os
import statistics
import sys
import time
from collections.abc import AsyncIterator, Callable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
import psutil
from figures import (
    Config,
    Stat,
    Table,
    fmt_mb,
    fmt_ms,
    fmt_rate,
    fmt_ratio,
    machine_header,
    percentile,
    rate,
)
from in_process import item_in_process
from mirobot_emulator.motion import AxisLimits, joint_block
from mirobot_emulator.settings import default_settings
from real_program import Item10Config, measure_item10, render_item10
from sansio import item_sansio

from mirobot_async import LineResult, Mirobot, StreamResult
from mirobot_async._client.transport import Implementation
from mirobot_async.virtual import EmulatorProcess, start_emulator

WIRE_BYTES_PER_S = 115200 / 10  # 8N1: 10 bits per byte


# ---- the emulator process and the client ----------------------------------------------------

LAYERS: dict[Implementation, str] = {
    "fast": "pyserial-asyncio-fast",
    "original": "pyserial-asyncio",
}
DEFAULT_LAYER: Implementation = "fast"


def bench_line(index: int) -> str:
    """A cheap line the firmware acknowledges at once (no motion): ``M3 S<pwm>``, ~9 bytes."""
    return f"M3 S{index % 1001}"


def bench_lines(count: int) -> list[str]:
    return [bench_line(i) for i in range(count)]


def wire_bytes(lines: Sequence[str]) -> int:
    return sum(len(line) + 1 for line in lines)


@contextlib.asynccontextmanager
async def connected(url: str, layer: Implementation = DEFAULT_LAYER) -> AsyncIterator[Mirobot]:
    """A client on ``url`` (already unlocked: the emulator keeps its state across connections)."""
    async with Mirobot.connect(url, implementation=layer) as arm:
        await warm_up(arm)
        yield arm


async def unlock(url: str) -> None:
    """Both profiles power on locked (2021 also in Alarm): unlock once per emulator."""
    async with Mirobot.connect(url) as arm:
        await arm.unlock()


async def warm_up(arm: Mirobot, lines: int = 300) -> None:
    await arm.stream(bench_lines(lines))
    for _ in range(20):
        await arm.send("M3 S0")


async def ack_round_trips(arm: Mirobot, count: int) -> list[float]:
    samples = []
    for _ in range(count):
        start = time.perf_counter()
        await arm.send("M3 S0")
        samples.append(time.perf_counter() - start)
    return samples


async def pipelined_seconds(arm: Mirobot, lines: Sequence[str]) -> float:
    start = time.perf_counter()
    result = await arm.stream(lines)
    elapsed = time.perf_counter() - start
    assert result.ok and result.acknowledged == len(lines), result
    return elapsed


async def stop_and_wait_seconds(arm: Mirobot, lines: Sequence[str]) -> float:
    start = time.perf_counter()
    for line in lines:
        await arm.send(line)
    return time.perf_counter() - start


async def status_round_trips(arm: Mirobot, count: int) -> list[float]:
    """Status round trips, spaced by the client's minimum gap between two ``?``."""
    samples = []
    for _ in range(count):
        start = time.perf_counter()
        await arm.status()
        samples.append(time.perf_counter() - start)
        await asyncio.sleep(arm.status_min_gap)
    return samples


@contextlib.asynccontextmanager
async def background_stream(arm: Mirobot) -> AsyncIterator[Callable[[], int]]:
    """Stream lines until the block ends; yields a function returning the lines acknowledged."""
    stop = False
    acked = 0

    def lines() -> Iterator[str]:
        index = 0
        while not stop:
            yield bench_line(index)
            index += 1

    def count(_line: LineResult) -> None:
        nonlocal acked
        acked += 1

    async def run() -> StreamResult:
        return await arm.stream(lines(), on_progress=count)

    task = asyncio.create_task(run())
    await asyncio.sleep(0.05)  # let the pipeline fill
    try:
        yield lambda: acked
    finally:
        stop = True
        result = await task
        assert result.ok, result


# ---- items 2, 3, 4 (and 9): acknowledgements, streaming, the wire ---------------------------


@dataclass
class LinkFigures:
    """Items 2-4 for one serial layer: one value per repetition each."""

    ack_p50: Stat = field(default_factory=Stat)
    ack_p99: Stat = field(default_factory=Stat)
    pipelined: Stat = field(default_factory=Stat)  # lines/s
    stop_and_wait: Stat = field(default_factory=Stat)  # lines/s
    speedup: Stat = field(default_factory=Stat)  # pipelined / stop-and-wait
    wire: Stat = field(default_factory=Stat)  # utilisation of 115200 baud, pipelined
    wire_stop_and_wait: Stat = field(default_factory=Stat)


async def measure_link(config: Config) -> dict[Implementation, LinkFigures]:
    """Items 2-4 with both serial layers, interleaved repetition by repetition."""
    figures: dict[Implementation, LinkFigures] = {layer: LinkFigures() for layer in LAYERS}
    stream = bench_lines(config.stream_lines)
    waited = stream[: config.wait_lines]
    line_bytes = wire_bytes(stream) / len(stream)
    wire_count = max(20, int(config.wire_seconds * WIRE_BYTES_PER_S / line_bytes))
    wire_stream = bench_lines(wire_count)
    wire_waited = wire_stream[: max(10, wire_count // 8)]
    async with (
        start_emulator(time_scale=0) as fast_url,
        start_emulator(time_scale=0, extra_args=["--baud", "115200"]) as paced_url,
    ):
        await unlock(fast_url)
        await unlock(paced_url)
        layers = list(LAYERS)
        for rep in range(config.reps):
            for layer in layers if rep % 2 == 0 else layers[::-1]:
                fig = figures[layer]
                async with connected(fast_url, layer) as arm:
                    samples = await ack_round_trips(arm, config.round_trips)
                    fig.ack_p50.add(percentile(samples, 50))
                    fig.ack_p99.add(percentile(samples, 99))
                    pipelined = rate(len(stream), await pipelined_seconds(arm, stream))
                    waiting = rate(len(waited), await stop_and_wait_seconds(arm, waited))
                    fig.pipelined.add(pipelined)
                    fig.stop_and_wait.add(waiting)
                    fig.speedup.add(pipelined / waiting)
                async with connected(paced_url, layer) as arm:
                    seconds = await pipelined_seconds(arm, wire_stream)
                    fig.wire.add(wire_bytes(wire_stream) / seconds / WIRE_BYTES_PER_S)
                    seconds = await stop_and_wait_seconds(arm, wire_waited)
                    fig.wire_stop_and_wait.add(wire_bytes(wire_waited) / seconds / WIRE_BYTES_PER_S)
    return figures


def report_link(config: Config, table: Table, figures: dict[Implementation, LinkFigures]) -> None:
    fig = figures[DEFAULT_LAYER]
    table.add("2", "Ack round trip (`M3 S0` -> ok), p50", fig.ack_p50, fmt_ms)
    table.add("2", "Ack round trip, p99", fig.ack_p99, fmt_ms)
    table.add(
        "3",
        f"Pipelined stream of {config.stream_lines:,} lines",
        fig.pipelined,
        lambda v: fmt_rate(v, " lines/s"),
        f"x{fig.speedup.median:.2f} stop-and-wait (ratio spread "
        f"{fmt_ratio(fig.speedup.lo)} .. {fmt_ratio(fig.speedup.hi)})",
    )
    table.add(
        "3",
        f"Stop-and-wait, {config.wait_lines:,} lines (send, await ok, send...)",
        fig.stop_and_wait,
        lambda v: fmt_rate(v, " lines/s"),
    )
    met = "met" if fig.wire.median >= 0.95 else "NOT met"
    table.add(
        "4",
        "Wire utilisation at 115200 baud, pipelined",
        fig.wire,
        fmt_ratio,
        f"target >= 0.95: {met} (bytes sent / s / 11,520)",
    )
    table.add("4", "Wire utilisation, stop-and-wait", fig.wire_stop_and_wait, fmt_ratio)


def report_serial_layers(table: Table, figures: dict[Implementation, LinkFigures]) -> None:
    """Item 9: pyserial-asyncio vs pyserial-asyncio-fast, side by side, 'fast' advantage > 1."""
    orig, fast = figures["original"], figures["fast"]
    rows: list[tuple[str, Stat, Stat, Callable[[float], str], bool]] = [
        ("ack round trip p50", orig.ack_p50, fast.ack_p50, fmt_ms, True),
        ("ack round trip p99", orig.ack_p99, fast.ack_p99, fmt_ms, True),
        ("pipelined lines/s", orig.pipelined, fast.pipelined, fmt_rate, False),
        ("stop-and-wait lines/s", orig.stop_and_wait, fast.stop_and_wait, fmt_rate, False),
        ("wire utilisation", orig.wire, fast.wire, fmt_ratio, False),
        ("wire utilisation, stop-and-wait", orig.wire_stop_and_wait, fast.wire_stop_and_wait,
         fmt_ratio, False),
    ]  # fmt: skip
    advantages = []
    for what, a, b, fmt, lower_is_better in rows:
        advantage = a.median / b.median if lower_is_better else b.median / a.median
        if "wire utilisation" not in what:  # capped by the wire: says nothing about the layer
            advantages.append(advantage)
        spread = "-"
        if len(a.values) > 1:
            spread = f"{fmt(a.lo)} .. {fmt(a.hi)} vs {fmt(b.lo)} .. {fmt(b.hi)}"
        table.add_text(
            "9",
            f"{what}: pyserial-asyncio vs -fast",
            f"{fmt(a.median)} vs {fmt(b.median)}",
            spread,
            f"fast/original advantage x{advantage:.2f}",
        )
    overall = float(np.exp(np.mean(np.log(advantages))))
    if overall >= 1.10:
        verdict = f"pyserial-asyncio-fast wins clearly (x{overall:.2f} geometric mean)"
    elif overall <= 1 / 1.10:
        verdict = f"pyserial-asyncio wins clearly (x{1 / overall:.2f} geometric mean)"
    else:
        verdict = f"no clear winner (fast/original x{overall:.2f} geometric mean)"
    table.add_text("9", "Serial layer verdict (items 2-3)", verdict)


# ---- item 5: status round trips -------------------------------------------------------------


async def item_status(config: Config, table: Table) -> None:
    idle_p50, idle_p99, busy_p50, busy_p99, polls = Stat(), Stat(), Stat(), Stat(), Stat()
    samples_per_rep = max(10, config.round_trips // 2)
    async with start_emulator(time_scale=0) as url:
        await unlock(url)
        async with connected(url) as arm:
            for _ in range(config.reps):
                samples = await status_round_trips(arm, samples_per_rep)
                idle_p50.add(percentile(samples, 50))
                idle_p99.add(percentile(samples, 99))
                async with background_stream(arm):
                    samples = await status_round_trips(arm, samples_per_rep)
                busy_p50.add(percentile(samples, 50))
                busy_p99.add(percentile(samples, 99))
                count, start = 0, time.perf_counter()
                while time.perf_counter() - start < config.poll_seconds:
                    await arm.status()
                    count += 1
                polls.add(rate(count, time.perf_counter() - start))
            gap = arm.status_min_gap
    table.add("5", "Status `?` round trip, idle, p50", idle_p50, fmt_ms)
    table.add("5", "Status round trip, idle, p99", idle_p99, fmt_ms)
    table.add("5", "Status round trip while streaming, p50", busy_p50, fmt_ms)
    table.add("5", "Status round trip while streaming, p99", busy_p99, fmt_ms)
    table.add(
        "5",
        "Sustained status polls (back-to-back)",
        polls,
        lambda v: fmt_rate(v, " polls/s"),
        f"capped by the client's {gap * 1e3:g} ms minimum gap between two `?`",
    )


# ---- item 6: motion completion latency ------------------------------------------------------


def move_duration(start: float, end: float) -> float:
    """Duration of a rapid (G0) J1 move from ``start`` to ``end`` degrees, per the timing model
    of the emulator with its default 2021 settings (the same function the firmware calls)."""
    limits = AxisLimits.from_settings(default_settings("2021"))
    q0 = (start, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    q1 = (end, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    return joint_block(q0, q1, None, limits).duration


async def item_motion(config: Config, table: Table) -> None:
    """50 short joint moves at real speed: client return time minus the emulator's end of motion.

    The emulator reports when its planner went from busy to idle (control command
    ``motion-ends``: ``time.monotonic()`` instants, the firmware's simulated end mapped through
    its clock), fetched once after the moves so as not to disturb them, and matched in order.
    The figure from the timing model (call time + the move's modelled duration, an upper bound)
    is kept as a cross-check.
    """
    step = 0.75  # degrees: a ~0.25 s triangular move at the default 50 deg/s^2
    calls, returns, durations = [], [], []
    emulator = await EmulatorProcess.start("2021", 1)
    async with emulator:
        await unlock(emulator.url)
        async with Mirobot.connect(emulator.url) as arm:
            await arm.move_joints(j1=0.0)
            position = 0.0
            for i in range(config.moves):
                target = step if i % 2 == 0 else 0.0
                durations.append(move_duration(position, target))
                calls.append(time.monotonic())
                report = await arm.move_joints(j1=target)
                returns.append(time.monotonic())
                assert report is not None and abs(report.joints[0] - target) < 0.01, report
                position = target
        reply = await emulator.control("motion-ends")
    ends = [float(word) for word in reply.split()[2:]][-config.moves :]
    assert len(ends) == config.moves, reply
    for call, end, done in zip(calls, ends, returns, strict=True):
        assert call < end <= done, (call, end, done)  # each end falls inside its own move
    latencies = [done - end for end, done in zip(ends, returns, strict=True)]
    modelled = [
        done - call - duration
        for call, done, duration in zip(calls, returns, durations, strict=True)
    ]
    p50, p99 = percentile(latencies, 50), percentile(latencies, 99)
    met = "met" if p99 <= 0.010 else "NOT met"
    spread = f"{fmt_ms(min(latencies))} .. {fmt_ms(max(latencies))}"
    table.add_text(
        "6",
        f"Motion completion latency, {config.moves} x {step:g} deg J1 moves, p50",
        fmt_ms(p50),
        spread,
        f"real speed; moves of {fmt_ms(statistics.median(durations))} (model); 1 run",
    )
    table.add_text(
        "6", "Motion completion latency, p99", fmt_ms(p99), spread, f"target <= 10 ms: {met}"
    )
    table.add_text(
        "6",
        "Motion completion latency from the timing model, p50 / p99",
        f"{fmt_ms(percentile(modelled, 50))} / {fmt_ms(percentile(modelled, 99))}",
        f"{fmt_ms(min(modelled))} .. {fmt_ms(max(modelled))}",
        "upper bound: call time + modelled duration (includes the line's trip)",
    )
    table.notes.append(
        "Item 6: the end of motion is the emulator's own report (control command `motion-ends`: "
        "the instant its planner went from busy to idle, the firmware's simulated end mapped to "
        "`time.monotonic()` through the emulator's clock; that clock is system-wide on Linux), "
        f"fetched once after the {config.moves} moves and matched in order; the latency is the "
        "client's "
        "return (`time.monotonic()`) minus it. The model row instead takes the call time + the "
        "move's duration from the timing model (mirobot_emulator.motion, default 2021 "
        "settings), an upper bound. `move_joints(wait=True)` polls the status back-to-back."
    )


# ---- item 7: many arms from one event loop --------------------------------------------------


async def drive_arm(arm: Mirobot, seconds: float, status_samples: list[float]) -> int:
    """Stream for ``seconds`` while polling the status at 10 Hz; return the lines acknowledged."""
    async with background_stream(arm) as acknowledged:
        deadline = time.perf_counter() + seconds
        tick = time.perf_counter()
        while (now := time.perf_counter()) < deadline:
            await arm.status()
            status_samples.append(time.perf_counter() - now)
            tick += 0.1
            await asyncio.sleep(max(0.0, min(tick, deadline) - time.perf_counter()))
    return acknowledged()


async def item_scale(config: Config, table: Table) -> None:
    throughput, status_p99 = Stat(), Stat()
    async with contextlib.AsyncExitStack() as stack:
        urls = await asyncio.gather(
            *(stack.enter_async_context(start_emulator(time_scale=0)) for _ in range(config.arms))
        )
        await asyncio.gather(*(unlock(url) for url in urls))
        arms = await asyncio.gather(*(stack.enter_async_context(connected(url)) for url in urls))
        for _ in range(config.reps):
            samples: list[float] = []
            start = time.perf_counter()
            counts = await asyncio.gather(
                *(drive_arm(arm, config.scale_seconds, samples) for arm in arms)
            )
            throughput.add(rate(sum(counts), time.perf_counter() - start))
            status_p99.add(percentile(samples, 99))
    table.add(
        "7",
        f"{config.arms} emulators, one event loop: aggregate stream",
        throughput,
        lambda v: fmt_rate(v, " lines/s"),
        f"each arm also polled at 10 Hz; {config.arms} emulator processes share the CPU",
    )
    table.add("7", f"{config.arms} emulators: status round trip p99", status_p99, fmt_ms)


# ---- item 8: memory -------------------------------------------------------------------------


def rss() -> float:
    gc.collect()
    return float(psutil.Process().memory_info().rss)


async def item_memory(config: Config, table: Table) -> None:
    growth = Stat()
    reps = min(config.reps, 3)
    async with start_emulator(time_scale=0) as url:
        await unlock(url)
        async with connected(url) as arm:
            await arm.stream(bench_line(i) for i in range(config.memory_lines // 10))
            for _ in range(reps):
                before = rss()
                result = await arm.stream(bench_line(i) for i in range(config.memory_lines))
                assert result.ok and result.acknowledged == config.memory_lines, result
                growth.add((rss() - before) / 1024 / 1024)
    met = "met" if growth.hi < 5 else "NOT met"
    table.add(
        "8",
        f"RSS growth over {config.memory_lines:,} streamed lines",
        growth,
        fmt_mb,
        f"target < 5 MB: {met} (worst of {reps} runs, after a warm-up)",
    )


# ---- main -----------------------------------------------------------------------------------


async def run_all(config: Config) -> Table:
    table = Table()
    item_sansio(config, table)
    link = await measure_link(config)
    report_link(config, table, link)
    await item_status(config, table)
    await item_motion(config, table)
    await item_scale(config, table)
    await item_memory(config, table)
    report_serial_layers(table, link)
    table.notes.append(
        "Items 2-8 use pyserial-asyncio-fast (the default serial layer); item 9 repeats items 2-4 "
        "with each layer, interleaved. Lines are `M3 S<n>` (about 9 bytes with the newline; the "
        "firmware answers `ok` at once). Latencies: p50/p99 per repetition, then the median "
        "over repetitions."
    )
    return table


def _loads() -> str:
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smoke run of a few seconds")
    parser.add_argument("--item10", action="store_true", help="run item 10 (a real program) only")
    args = parser.parse_args(argv)
    config = Config.make(args.quick)
    header = machine_header(config)
    started = time.perf_counter()
    parts = []
    if not args.item10:
        table = asyncio.run(run_all(config))
        item_in_process(config, table)  # its own event loops (the in-process virtual arm)
        parts.append(table.render(header))
    else:  # item 10 alone: its own tables say how it ran
        parts.append(header.split("\n\n")[0] + f"\n\nLoad average at the start {_loads()}.")
    item10 = Item10Config.make(args.quick)
    runs, latencies = asyncio.run(measure_item10(item10))
    parts.append(render_item10(item10, runs, latencies))
    parts.append(f"Total run time {time.perf_counter() - started:.0f} s.")
    print("\n\n".join(parts))
    return 0


if __name__ == "__main__":
    sys.exit(main())
