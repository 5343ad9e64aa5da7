"""Several arms on one controller bus: aggregate lines/s and status p99 (issue 16).

``python benchmarks/bus.py [--arms 4] [--seconds 3] [--baud 38400]``

Starts one bus emulator process (``--arms`` controller+arm nodes behind one pty, firmware 2021,
time scale 1: the bus's byte timing and the controllers' 2 ms turnaround are real time) and
connects one :class:`~mirobot_async.Mirobot` per address through
:class:`~mirobot_async.bus.ControllerBus`, all from this one event loop. For each line end
(``\\r\\n``, what the vendor's clients send; ``\\n``):

* **lines/s**: every arm streams ``G90`` lines (acknowledged at once: the figure is the bus's,
  not the arms' motion) for ``--seconds`` at once; the aggregate is the acknowledged lines of
  all arms over the wall time;
* **status idle**: every arm asks ``status()`` back to back for ``--seconds``; p50 / p99 of the
  round trips (all arms' samples together);
* **status under load**: one arm per node polls ``status()`` every 20 ms while the others
  stream; p50 / p99 of those polls.

Prints one markdown table with the machine in its header. Takes about ``6 x --seconds`` s.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mirobot_async import Mirobot
from mirobot_async.bus import BusTiming, ControllerBus

_LAUNCHER = """
import sys
from mirobot_emulator.bus import Bus
from mirobot_emulator.server.loop import EmulatorServer
from mirobot_emulator.server.options import ServerOptions

nodes, baud = int(sys.argv[1]), int(sys.argv[2])
server = EmulatorServer(
    ServerOptions(time_scale=1.0), firmware_factory=lambda: Bus(nodes, baud=baud)
)
print(server.open(), flush=True)
server.serve()
"""


def percentile(samples: list[float], q: float) -> float:
    """The ``q`` quantile (0..1) of ``samples``, nearest rank."""
    ordered = sorted(samples)
    return ordered[min(len(ordered) - 1, max(0, round(q * len(ordered)) - 1))]


async def stream_for(arm: Mirobot, seconds: float) -> int:
    """Stream ``G90`` lines until ``seconds`` have passed; return how many were acknowledged."""
    end = time.monotonic() + seconds

    async def lines():  # type: ignore[no-untyped-def]
        while time.monotonic() < end:
            yield "G90"

    result = await arm.stream(lines())
    return result.acknowledged


async def statuses_for(arm: Mirobot, seconds: float, gap: float) -> list[float]:
    """``status()`` round trips (s) for ``seconds``, ``gap`` s apart."""
    samples: list[float] = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        started = time.monotonic()
        await arm.status()
        samples.append(time.monotonic() - started)
        if gap:
            await asyncio.sleep(gap)
    return samples


async def measure(path: str, arms_count: int, seconds: float, baud: int, line_end: str) -> dict:
    timing = BusTiming()
    async with ControllerBus.open(path, baud=baud, timing=timing, line_end=line_end) as bus:
        arms = [await bus.connect_arm(n) for n in range(1, arms_count + 1)]
        for arm in arms:
            await arm.send("$X")  # out of the power-on alarm: lines are acknowledged "ok"
        started = time.monotonic()
        counts = await asyncio.gather(*(stream_for(arm, seconds) for arm in arms))
        wall = time.monotonic() - started
        idle = await asyncio.gather(*(statuses_for(arm, seconds, 0.0) for arm in arms))
        idle_samples = [s for part in idle for s in part]
        streaming = [stream_for(arm, seconds) for arm in arms[1:]]
        polled, *_ = await asyncio.gather(statuses_for(arms[0], seconds, 0.02), *streaming)
        return {
            "line_end": repr(line_end),
            "lines_s": sum(counts) / wall,
            "idle_p50": statistics.median(idle_samples) * 1000,
            "idle_p99": percentile(idle_samples, 0.99) * 1000,
            "load_p50": statistics.median(polled) * 1000,
            "load_p99": percentile(polled, 0.99) * 1000,
            "stray": bus.stats.stray_lines,
        }


def machine_header(arms: int, baud: int) -> str:
    cpu = platform.processor() or "unknown CPU"
    with contextlib.suppress(OSError), open("/proc/cpuinfo", encoding="utf-8") as info:
        cpu = next((t.split(":", 1)[1].strip() for t in info if t.startswith("model name")), cpu)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (
        f"**mirobot-async controller bus** - {arms} arms on one emulated RS485 bus at {baud} "
        f"baud; {cpu}, {os.cpu_count()} cores, load {load:.1f}; "
        f"{platform.python_implementation()} {platform.python_version()}\n"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--arms", type=int, default=4)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--baud", type=int, default=38400)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        script = Path(tmp) / "bus_launcher.py"
        script.write_text(_LAUNCHER)
        rows = []
        for line_end in ("\r\n", "\n"):
            process = subprocess.Popen(
                [sys.executable, str(script), str(args.arms), str(args.baud)],
                stdout=subprocess.PIPE,
                text=True,
            )
            try:
                assert process.stdout is not None
                path = process.stdout.readline().strip()
                rows.append(
                    asyncio.run(measure(path, args.arms, args.seconds, args.baud, line_end))
                )
            finally:
                process.terminate()
                process.wait(5)
    print(machine_header(args.arms, args.baud))
    print("| line end | lines/s (all arms) | status idle p50 / p99 (ms) |", end="")
    print(" status while 3 arms stream p50 / p99 (ms) | stray lines |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['line_end']} | {r['lines_s']:.0f} | {r['idle_p50']:.1f} / {r['idle_p99']:.1f} "
            f"| {r['load_p50']:.1f} / {r['load_p99']:.1f} | {r['stray']} |"
        )


if __name__ == "__main__":
    main()
