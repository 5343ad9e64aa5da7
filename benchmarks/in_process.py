"""Item 11: a user's test on the in-process virtual arm, client and emulator CPU in one process.

``python benchmarks/in_process.py [--runs 30] [--quick]``: connect to a fresh
``start_emulator(in_process=True)`` arm at time scale 0, home, one joint move, then stream 100
``M21 G90 G01 X.. F2000`` lines (the test a user writes with the in-process arm; what it costs is
what every such test costs). Reports the median time per test on each profile, and how much of it
is CPU of the emulator's firmware model (spent inside its clock), CPU of the client (the rest of
this process's CPU: the client, asyncio, the link seam), and waiting (wall time without CPU: the
client's timers, e.g. its 2 ms minimum gap between two ``?``, and other processes on a loaded
machine).
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import statistics
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from figures import Config, Stat, Table, fmt_ms

from mirobot_async import Mirobot
from mirobot_async.virtual import InProcessArm

PROFILES = ("classic", "2021")
STREAM_LINES = 100


def user_lines(distinct: bool = False) -> list[str]:
    """The test's program: 100 absolute J1 moves in joint mode, each stating its modes, back
    and forth over 10 targets; ``distinct``: no two lines (nor moves) alike, so that nothing
    seen before can be reused."""
    if distinct:
        return [f"M21 G90 G01 X{i * 0.37 - 18:.2f} F{2000 + i}" for i in range(STREAM_LINES)]
    return [f"M21 G90 G01 X{i % 10} F2000" for i in range(STREAM_LINES)]


class _TimedClock:
    """The arm's clock with the CPU time spent inside it (the firmware model runs there) added
    up."""

    def __init__(self, clock: Any, spent: list[float]) -> None:
        self._clock = clock
        self._spent = spent

    def _timed(self, name: str, *args: Any) -> Any:
        start = time.process_time()
        try:
            return getattr(self._clock, name)(*args)
        finally:
            self._spent[0] += time.process_time() - start

    def sync(self, wall: float) -> None:
        self._timed("sync", wall)

    def deliver(self, data: bytes, crossed: float | None, wall: float) -> None:
        self._timed("deliver", data, crossed, wall)

    def feed(self, data: bytes) -> None:
        self._timed("feed", data)

    def next_wall_deadline(self) -> float | None:
        result: float | None = self._timed("next_wall_deadline")
        return result


@dataclass(frozen=True)
class Run:
    """One run of the user's test, in seconds."""

    wall: float
    cpu: float
    emulator_cpu: float


async def one_test(firmware: str, distinct: bool = False) -> Run:
    """One run of the user's test."""
    spent = [0.0]
    start, cpu = time.perf_counter(), time.process_time()
    with InProcessArm(firmware, 0.0) as arm:
        arm._sim = _TimedClock(arm._sim, spent)
        async with Mirobot.connect(arm.url) as robot:
            await robot.home()
            await robot.move_joints(j1=10)
            result = await robot.stream(user_lines(distinct))
    run = Run(time.perf_counter() - start, time.process_time() - cpu, spent[0])
    assert result.ok and result.acknowledged == STREAM_LINES, result
    return run


async def measure(firmware: str, runs: int, distinct: bool = False) -> list[Run]:
    """``runs`` runs of the user's test after one warm-up."""
    await one_test(firmware, distinct)
    measured = []
    for _ in range(runs):
        gc.collect()
        measured.append(await one_test(firmware, distinct))
    return measured


def item_in_process(config: Config, table: Table, runs: int | None = None) -> None:
    """Item 11 rows: the user's in-process test on each profile."""
    count = runs if runs is not None else (3 if config.quick else 30)
    for firmware, distinct in [(p, False) for p in PROFILES] + [("classic", True)]:
        measured = asyncio.run(measure(firmware, count, distinct))
        client = statistics.median(r.cpu - r.emulator_cpu for r in measured)
        emulator = statistics.median(r.emulator_cpu for r in measured)
        waiting = statistics.median(max(0.0, r.wall - r.cpu) for r in measured)
        table.add(
            "11",
            f"In-process test, {firmware}: home, 1 move, {STREAM_LINES}-line stream"
            + (" (no two lines alike)" if distinct else ""),
            Stat([r.wall for r in measured]),
            fmt_ms,
            f"median of {count}; CPU: client {fmt_ms(client)}, emulator model "
            f"{fmt_ms(emulator)}; waiting {fmt_ms(waiting)}",
        )


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=None, help="tests per profile (default 30)")
    parser.add_argument("--quick", action="store_true", help="smoke run (3 tests per profile)")
    args = parser.parse_args(argv)
    config = Config.make(args.quick)
    table = Table()
    item_in_process(config, table, args.runs)
    from figures import machine_header

    header = machine_header(config).replace(
        "emulator process on a pty, time scale 0 unless noted",
        "in-process virtual arm (client and emulator on one event loop), time scale 0",
    )
    print(table.render(header))
    return 0


if __name__ == "__main__":
    sys.exit(main())
