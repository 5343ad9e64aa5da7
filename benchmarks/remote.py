"""Remote arms: 16 arms through ser2net beside 16 direct ptys, from one event loop.

``python benchmarks/remote.py [--arms 16] [--seconds 2] [--paths direct,socket,rfc2217,listen]``

It starts ``--arms`` emulator processes on ptys (firmware 2021, time scale 0: every line is
acknowledged at once, so the figures are the host's and the link's, not the arm's), and for each
ser2net path one ser2net process in front of all of them on loopback (one port per arm, as one
lab host serving many arms would; stopped before the next path), plus ``--arms`` emulators
serving TCP for ``listen``. For each path all arms are connected from this one event loop, then:

* **lines/s**: every arm streams ``M3 S<n>`` lines for ``--seconds`` at once; the aggregate is
  the acknowledged lines of all arms over the wall time;
* **status**: every arm asks ``status()`` back to back for ``--seconds`` at once; p50 and p99
  of the round trips (all arms' samples together).

Paths: ``direct`` (the pty), ``socket`` (``socket://`` through ser2net's raw TCP accepter),
``rfc2217`` (``rfc2217://...?ign_set_control`` through ser2net's telnet RFC 2217 accepter),
``listen`` (``socket://`` to emulators serving TCP themselves, ``--listen 127.0.0.1:0``).
Prints one markdown table with the machine in its header. Needs ser2net (``apt-get install
ser2net``) for the two ser2net paths; they are left out, with a note, without it.
Takes 30-60 s (mostly starting 2 x 16 emulator processes).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import platform
import shutil
import socket
import statistics
import sys
import tempfile
import time
import warnings
from collections.abc import AsyncIterator, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from mirobot_async import Mirobot
from mirobot_async.virtual import EmulatorProcess

SER2NET = shutil.which("ser2net") or shutil.which("ser2net", path="/usr/sbin:/usr/local/sbin:/sbin")
PATHS = ("direct", "socket", "rfc2217", "listen")
FIRMWARE = "2021"


# ---- processes ------------------------------------------------------------------------------


def free_ports(count: int) -> list[int]:
    """``count`` distinct loopback TCP ports that were free a moment ago."""
    sockets = []
    try:
        for _ in range(count):
            probe = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sockets.append(probe)
            probe.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in sockets]
    finally:
        for probe in sockets:
            probe.close()


ACCEPTERS = {"socket": "tcp(nodelay)", "rfc2217": "telnet(rfc2217),tcp(nodelay)"}
URL_OPTIONS = {"socket": "", "rfc2217": "?ign_set_control"}


def ser2net_config(devices: Sequence[str], ports: Sequence[int], kind: str) -> str:
    """ser2net 4.x YAML: one loopback accepter per device (raw TCP or telnet RFC 2217).

    ``tcp(nodelay)`` and ``chardelay: false``: replies are forwarded at once (without them a
    status round trip costs ~44 ms of Nagle against delayed ACKs, and up to 1 ms more).
    """
    out = ["%YAML 1.1", "---"]
    for index, (device, port) in enumerate(zip(devices, ports, strict=True)):
        out += [
            f"connection: &arm{index}",
            f"  accepter: {ACCEPTERS[kind]},127.0.0.1,{port}",
            f"  connector: serialdev,{device},115200n81,local",
            "  options:",
            "    chardelay: false",
            "    mdns: false",
        ]
    return "\n".join(out) + "\n"


async def wait_listening(process: asyncio.subprocess.Process, ports: Sequence[int]) -> None:
    """Wait (at most 10 s) until every port accepts a connection."""
    async with asyncio.timeout(10):
        for port in ports:
            while True:
                if process.returncode is not None:
                    raise RuntimeError(f"ser2net exited with status {process.returncode}")
                try:
                    _, writer = await asyncio.open_connection("127.0.0.1", port)
                except OSError:
                    await asyncio.sleep(0.01)  # polling the condition "port accepts"
                    continue
                writer.close()
                await writer.wait_closed()
                break


@contextlib.asynccontextmanager
async def run_ser2net(devices: Sequence[str], kind: str, workdir: Path) -> AsyncIterator[list[str]]:
    """One ser2net process in front of ``devices``; yields the client URLs. Stopped on exit."""
    assert SER2NET is not None
    ports = free_ports(len(devices))
    config = workdir / f"ser2net-{kind}.yaml"
    config.write_text(ser2net_config(devices, ports, kind))
    process = await asyncio.create_subprocess_exec(
        SER2NET,
        *("-n", "-u", "-c", str(config), "-P", str(workdir / "ser2net.pid")),
        stdin=asyncio.subprocess.DEVNULL,
        stdout=asyncio.subprocess.DEVNULL,
        stderr=asyncio.subprocess.DEVNULL,
    )
    try:
        await wait_listening(process, ports)
        yield [f"{kind}://127.0.0.1:{port}{URL_OPTIONS[kind]}" for port in ports]
    finally:
        if process.returncode is None:
            process.terminate()
            try:
                async with asyncio.timeout(3):
                    await process.wait()
            except TimeoutError:
                process.kill()
        await process.wait()


@contextlib.asynccontextmanager
async def run_emulators(count: int, extra_args: Sequence[str] = ()) -> AsyncIterator[list[str]]:
    """``count`` emulator processes (started concurrently); yields their URLs."""
    async with contextlib.AsyncExitStack() as stack:
        started = await asyncio.gather(
            *(EmulatorProcess.start(FIRMWARE, 0.0, extra_args=extra_args) for _ in range(count)),
            return_exceptions=True,
        )
        for item in started:  # every started process is stopped, even if another failed
            if isinstance(item, EmulatorProcess):
                await stack.enter_async_context(item)
        for item in started:
            if isinstance(item, BaseException):
                raise item
        yield [item.url for item in started if isinstance(item, EmulatorProcess)]


# ---- measurements ---------------------------------------------------------------------------


@dataclass
class PathResult:
    """What one path measured."""

    path: str
    arms: int
    connect_s: float = 0.0
    lines: int = 0
    stream_s: float = 0.0
    latencies: list[float] = field(default_factory=list)

    @property
    def lines_per_s(self) -> float:
        return self.lines / self.stream_s if self.stream_s else 0.0


def timed_lines(seconds: float) -> Iterator[str]:
    """``M3 S<n>`` lines (acknowledged at once, no motion) until ``seconds`` have passed."""
    end = time.perf_counter() + seconds
    index = 0
    while time.perf_counter() < end:
        yield f"M3 S{index % 1001}"
        index += 1


async def poll_status(arm: Mirobot, seconds: float, out: list[float]) -> None:
    """Back-to-back ``status()`` round trips for ``seconds``; appends each one's duration."""
    end = time.perf_counter() + seconds
    while (start := time.perf_counter()) < end:
        await arm.status(timeout=10)
        out.append(time.perf_counter() - start)


async def measure(path: str, urls: Sequence[str], seconds: float) -> PathResult:
    """Connect every URL from this loop, then stream and poll on all arms at once."""
    result = PathResult(path, len(urls))
    async with contextlib.AsyncExitStack() as stack:
        start = time.perf_counter()
        arms = await asyncio.gather(
            *(stack.enter_async_context(Mirobot.connect(url, timeout=10)) for url in urls)
        )
        result.connect_s = time.perf_counter() - start
        await asyncio.gather(*(arm.unlock() for arm in arms))
        start = time.perf_counter()
        streams = await asyncio.gather(*(arm.stream(timed_lines(seconds)) for arm in arms))
        result.stream_s = time.perf_counter() - start
        for stream in streams:
            if not stream.ok:
                raise RuntimeError(f"{path}: a stream failed: {stream}")
        result.lines = sum(stream.acknowledged for stream in streams)
        await asyncio.gather(*(poll_status(arm, seconds, result.latencies) for arm in arms))
    return result


# ---- report ---------------------------------------------------------------------------------


def percentile(values: Sequence[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q / 100 * (len(ordered) - 1)))]


def machine_header(arms: int, seconds: float) -> str:
    cpu = platform.processor() or "unknown CPU"
    with contextlib.suppress(OSError), open("/proc/cpuinfo", encoding="utf-8") as info:
        cpu = next((t.split(":", 1)[1].strip() for t in info if t.startswith("model name")), cpu)
    ser2net = "not installed"
    if SER2NET is not None:
        import subprocess

        done = subprocess.run([SER2NET, "-v"], capture_output=True, text=True, check=False)
        ser2net = (done.stdout or done.stderr).strip() or "installed"
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return (
        f"**mirobot-async remote arms** - {cpu}, {os.cpu_count()} cores; "
        f"{platform.python_implementation()} {platform.python_version()}; "
        f"{platform.system()} {platform.release()} {platform.machine()}; {ser2net}\n\n"
        f"{time.strftime('%Y-%m-%d')}; {arms} arms from one event loop, emulator {FIRMWARE} at "
        f"time scale 0, all on loopback; {seconds:g} s of streaming and {seconds:g} s of status "
        f"polling per path; load average at the start {load}."
    )


def render(results: Sequence[PathResult], header: str, notes: Sequence[str]) -> str:
    cols = (
        "Path",
        "Arms",
        "Lines/s (all arms)",
        "Lines/s per arm",
        "Status p50",
        "Status p99",
        "Status samples",
        "Connect all",
    )
    rows = [cols]
    for r in results:
        lat = r.latencies
        rows.append(
            (
                r.path,
                str(r.arms),
                f"{r.lines_per_s:,.0f}",
                f"{r.lines_per_s / r.arms:,.0f}",
                f"{statistics.median(lat) * 1000:.2f} ms" if lat else "-",
                f"{percentile(lat, 99) * 1000:.2f} ms" if lat else "-",
                str(len(lat)),
                f"{r.connect_s:.2f} s",
            )
        )
    widths = [max(len(row[i]) for row in rows) for i in range(len(cols))]

    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(c.ljust(w) for c, w in zip(cells, widths, strict=True)) + " |"

    out = [header, "", line(cols), "|" + "|".join("-" * (w + 2) for w in widths) + "|"]
    out += [line(row) for row in rows[1:]]
    out += [""] + [f"- {note}" for note in notes] if notes else []
    return "\n".join(out)


PATH_NAMES = {
    "direct": "direct pty",
    "socket": "ser2net, socket://",
    "rfc2217": "ser2net, rfc2217://",
    "listen": "emulator --listen, socket://",
}


async def main(arms: int, seconds: float, paths: Sequence[str]) -> str:
    header = machine_header(arms, seconds)
    notes: list[str] = []
    results: list[PathResult] = []
    wanted = list(paths)
    if SER2NET is None and {"socket", "rfc2217"} & set(wanted):
        notes.append("ser2net paths left out: ser2net is not installed (apt-get install ser2net)")
        wanted = [p for p in wanted if p not in ("socket", "rfc2217")]
    with tempfile.TemporaryDirectory(prefix="mirobot-remote-") as tmp:
        pty_paths = [p for p in wanted if p != "listen"]
        if pty_paths:  # one set of pty emulators; each ser2net process is gone before the next
            async with run_emulators(arms) as devices:
                for path in pty_paths:
                    async with contextlib.AsyncExitStack() as stack:
                        urls = devices
                        if path in ACCEPTERS:
                            server = run_ser2net(devices, path, Path(tmp))
                            urls = await stack.enter_async_context(server)
                        print(f"measuring {PATH_NAMES[path]} ...", file=sys.stderr)
                        results.append(await measure(PATH_NAMES[path], urls, seconds))
        if "listen" in wanted:
            async with run_emulators(arms, ("--listen", "127.0.0.1:0")) as urls:
                print(f"measuring {PATH_NAMES['listen']} ...", file=sys.stderr)
                results.append(await measure(PATH_NAMES["listen"], urls, seconds))
    if "rfc2217" in wanted:
        notes.append(
            "rfc2217:// is served by the client's polled transport (pyserial's RFC 2217 object "
            "has no file descriptor): every arm is polled each millisecond and has its own "
            "pyserial reader thread"
        )
    return render(results, header, notes)


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--arms", type=int, default=16, help="arms per path (default 16)")
    parser.add_argument(
        "--seconds", type=float, default=2.0, help="streaming and polling time per path (2)"
    )
    parser.add_argument(
        "--paths",
        default=",".join(PATHS),
        help=f"comma-separated subset of {','.join(PATHS)} (default: all)",
    )
    args = parser.parse_args(argv)
    args.paths = [p.strip() for p in args.paths.split(",") if p.strip()]
    unknown = set(args.paths) - set(PATHS)
    if unknown:
        parser.error(f"unknown path(s): {', '.join(sorted(unknown))}")
    return args


if __name__ == "__main__":
    # pyserial 3.5's rfc2217 handler calls Thread.setDaemon()/setName() (deprecated in 3.10)
    warnings.filterwarnings("ignore", r"set(Daemon|Name)\(\) is deprecated", DeprecationWarning)
    options = parse_args()
    print(asyncio.run(main(options.arms, options.seconds, options.paths)))
