"""What ``arm.view()`` costs a script: the same program streamed with and without the view.

``python benchmarks/view_overhead.py [--runs 3] [--lines 80] [--quick]``: an in-process virtual
arm at time scale 1 (real time), ``--lines`` short joint moves (1 deg at 1200 deg/min, 50 ms of
motion each) streamed with ``wait=True``, alternately bare and inside ``arm.view()`` (no page
connected: the view still follows the status and predicts and draws the path of every line).
Reports, per case, the median wall time of the stream (the arm's own motion time bounds it from
below) and this process's CPU (its share of the wall time); the ratio is measured in the same run.
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import time

from mirobot_async import Mirobot
from mirobot_async.virtual import start_emulator


def program(count: int) -> list[str]:
    return ["M21 G90 G21 G1 F1200"] + [f"G1 X{(i % 2) * 1.0:.1f}" for i in range(1, count + 1)]


async def one_run(lines: list[str], view: bool) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of one stream on a fresh arm."""
    async with (
        start_emulator(firmware="2021", time_scale=1.0, in_process=True) as url,
        Mirobot.connect(url) as arm,
    ):
        await arm.unlock()
        if view:
            async with arm.view(open_browser=False):
                return await _timed(arm, lines)
        return await _timed(arm, lines)


async def _timed(arm: Mirobot, lines: list[str]) -> tuple[float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    result = await arm.stream(lines, wait=True)
    assert result.ok, result.errors
    return time.perf_counter() - wall, time.process_time() - cpu


async def main(runs: int, count: int) -> None:
    lines = program(count)
    figures: dict[bool, list[tuple[float, float]]] = {False: [], True: []}
    for _ in range(runs):
        for view in (False, True):
            figures[view].append(await one_run(lines, view))
    print(f"{count} moves of 1 deg at 1200 deg/min, each reversing the last, time scale 1\n")
    print("| case | stream wall time (median) | process CPU (median, share of the wall time) |")
    print("|---|---:|---:|")
    medians = {}
    for view, name in ((False, "bare"), (True, "inside arm.view()")):
        wall = statistics.median(w for w, _ in figures[view])
        cpu = statistics.median(c for _, c in figures[view])
        medians[view] = wall
        print(f"| {name} | {wall:.3f} s | {cpu:.2f} s ({100 * cpu / wall:.1f} %) |")
    print(f"\nratio of wall times (view / bare): {medians[True] / medians[False]:.3f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--lines", type=int, default=80)
    parser.add_argument("--quick", action="store_true", help="one run of 20 lines")
    options = parser.parse_args()
    if options.quick:
        options.runs, options.lines = 1, 20
    asyncio.run(main(options.runs, options.lines))
