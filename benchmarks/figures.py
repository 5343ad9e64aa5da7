"""What every benchmark item shares: the configuration, statistics, formatting and the table."""

from __future__ import annotations

import os
import platform
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

# ---- configuration --------------------------------------------------------------------------


@dataclass(frozen=True)
class Config:
    """Counts and repetitions: the full run, or a few-second smoke run (``--quick``)."""

    quick: bool
    reps: int = 5
    sansio_seconds: float = 0.3  # time spent per sans-IO figure and repetition
    round_trips: int = 1000  # item 2 / 5: samples per repetition
    stream_lines: int = 10_000  # item 3
    wait_lines: int = 2_000  # item 3: stop-and-wait lines (a rate: fewer lines suffice)
    wire_seconds: float = 1.5  # item 4: wire time per paced stream
    poll_seconds: float = 1.0  # item 5: sustained polling
    moves: int = 50  # item 6
    arms: int = 16  # item 7
    scale_seconds: float = 4.0  # item 7
    memory_lines: int = 100_000  # item 8

    @classmethod
    def make(cls, quick: bool) -> Config:
        if not quick:
            return cls(quick=False)
        return cls(
            quick=True,
            reps=1,
            sansio_seconds=0.02,
            round_trips=50,
            stream_lines=300,
            wait_lines=100,
            wire_seconds=0.3,
            poll_seconds=0.2,
            moves=3,
            arms=2,
            scale_seconds=0.5,
            memory_lines=2_000,
        )


# ---- statistics -----------------------------------------------------------------------------


@dataclass
class Stat:
    """One figure: its value in every repetition; reported as the median and min..max."""

    values: list[float] = field(default_factory=list)

    def add(self, value: float) -> None:
        self.values.append(value)

    @property
    def median(self) -> float:
        return statistics.median(self.values)

    @property
    def lo(self) -> float:
        return min(self.values)

    @property
    def hi(self) -> float:
        return max(self.values)


def percentile(samples: Sequence[float], q: float) -> float:
    return float(np.percentile(np.asarray(samples, dtype=float), q))


def repeat(reps: int, measure: Callable[[], float]) -> Stat:
    stat = Stat()
    for _ in range(reps):
        stat.add(measure())
    return stat


def rate(count: int, seconds: float) -> float:
    return count / seconds if seconds > 0 else float("inf")


# ---- formatting -----------------------------------------------------------------------------


def fmt_rate(value: float, unit: str = "/s") -> str:
    """A rate with a k/M prefix: ``12 k lines/s``, ``3.4 k/s``, ``16.21 MB/s``.

    ``unit`` is ``"/s"``, ``"B/s"`` or a word with a leading space (``" lines/s"``).
    """
    if value >= 1e6:
        number, prefix = f"{value / 1e6:.2f}", "M"
    elif value >= 1e4:
        number, prefix = f"{value / 1e3:.0f}", "k"
    elif value >= 1e3:
        number, prefix = f"{value / 1e3:.1f}", "k"
    else:
        number, prefix = f"{value:.0f}", ""
    if unit.startswith(" "):  # a word: "12 k lines/s", "408 polls/s"
        return f"{number} {prefix}{' ' if prefix else ''}{unit.strip()}"
    return f"{number} {prefix}{unit}" if prefix or unit[0] != "/" else f"{number}{unit}"


def fmt_ms(seconds: float) -> str:
    ms = seconds * 1e3
    return f"{ms:.3f} ms" if ms < 1 else f"{ms:.2f} ms" if ms < 10 else f"{ms:.1f} ms"


def fmt_ratio(value: float) -> str:
    return f"{value:.3f}" if value < 10 else f"{value:.1f}"


def fmt_mb(value: float) -> str:
    return f"{value:+.2f} MB"


@dataclass
class Row:
    item: str
    what: str
    median: str
    spread: str
    note: str = ""


class Table:
    """Rows of the one result table, plus notes printed under it."""

    def __init__(self) -> None:
        self.rows: list[Row] = []
        self.notes: list[str] = []

    def add(
        self, item: str, what: str, stat: Stat, fmt: Callable[[float], str], note: str = ""
    ) -> None:
        spread = "-" if len(stat.values) < 2 else f"{fmt(stat.lo)} .. {fmt(stat.hi)}"
        self.rows.append(Row(item, what, fmt(stat.median), spread, note))

    def add_text(self, item: str, what: str, value: str, spread: str = "-", note: str = "") -> None:
        self.rows.append(Row(item, what, value, spread, note))

    def render(self, header: str) -> str:
        cols = ("#", "Measurement", "Median", "Spread (min .. max)", "Target / ratio / note")
        cells = [cols] + [(r.item, r.what, r.median, r.spread, r.note) for r in self.rows]
        widths = [max(len(c[i]) for c in cells) for i in range(len(cols))]

        def line(c: Sequence[str]) -> str:
            return "| " + " | ".join(s.ljust(w) for s, w in zip(c, widths, strict=True)) + " |"

        out = [header, "", line(cols), "|" + "|".join("-" * (w + 2) for w in widths) + "|"]
        out += [line(c) for c in cells[1:]]
        if self.notes:
            out.append("")
            out += [f"- {n}" for n in self.notes]
        return "\n".join(out)


def machine_header(config: Config) -> str:
    """The table's header: CPU, cores, Python, OS, date, mode and the load average."""
    cpu = "unknown CPU"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for text in f:
                if text.startswith("model name"):
                    cpu = text.split(":", 1)[1].strip()
                    break
    except OSError:
        cpu = platform.processor() or cpu
    cores = os.cpu_count() or 1
    python = f"{platform.python_implementation()} {platform.python_version()}"
    system = f"{platform.system()} {platform.release()} {platform.machine()}"
    mode = (
        "quick smoke run (1 repetition, tiny counts: do not quote)"
        if config.quick
        else (f"{config.reps} repetitions per figure unless noted")
    )
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return (
        f"**mirobot-async benchmarks** - {cpu}, {cores} cores; {python}; {system}\n\n"
        f"{time.strftime('%Y-%m-%d')}, {mode}; "
        "emulator process on a pty, time scale 0 unless noted; "
        f"load average at the start {load}."
    )
