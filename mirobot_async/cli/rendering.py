"""What the command line prints: status tables and lines, the progress of a run, the live
monitor, and the summaries of a stopped or interrupted run.

On a terminal the progress bar and the monitor are drawn with ``rich``; otherwise (pipes, CI
logs) they are plain lines, printed now and then, with no control characters.
"""

from __future__ import annotations

import asyncio
import datetime
import math
import time
from collections.abc import Callable, Sequence
from types import TracebackType
from typing import TYPE_CHECKING, Final, TextIO

from mirobot_async.cli.exits import note
from mirobot_async.replies import StatusReport

if TYPE_CHECKING:
    import rich.live
    import rich.progress

    from mirobot_async.cli.programs import ProgramLine

__all__ = [
    "LiveView",
    "ProgressBar",
    "RichProgressBar",
    "describe_failures",
    "describe_interrupted_run",
    "format_status_line",
    "format_status_table",
    "line_ranges",
    "progress_bar",
]


def _n(value: float) -> str:
    text = f"{value:.3f}"
    return "0.000" if text == "-0.000" else text


_MODES: Final = {0: "joint (M21)", 1: "Cartesian (M20)"}


def format_status_table(report: StatusReport) -> str:
    """A status report as a small table (no trailing newline)."""
    names = ["J1", "J2", "J3", "J4", "J5", "J6"]
    values = [_n(v) for v in report.joints]
    if report.rail is not None:
        names.append("rail")
        values.append(_n(report.rail))
    mode = (
        "-"
        if report.motion_mode is None
        else _MODES.get(report.motion_mode, str(report.motion_mode))
    )
    return "\n".join(
        [
            f"{'state':<8}{report.state.value}",
            f"{'':<8}" + "".join(f"{name:>10}" for name in names),
            f"{'joints':<8}" + "".join(f"{value:>10}" for value in values),
            f"{'':<8}" + "".join(f"{name:>10}" for name in ("x", "y", "z", "rx", "ry", "rz")),
            f"{'pose':<8}" + "".join(f"{_n(value):>10}" for value in report.pose),
            f"{'pwm':<8}pump {report.pump_pwm}, valve {report.valve_pwm}",
            f"{'mode':<8}{mode}",
        ]
    )


def format_status_line(report: StatusReport, when: datetime.datetime | None = None) -> str:
    """A status report on one line (``monitor`` when stdout is not a terminal)."""
    stamp = (when or datetime.datetime.now()).strftime("%H:%M:%S.%f")[:-3]
    joints = " ".join(_n(v) for v in report.joints)
    rail = "" if report.rail is None else f" rail {_n(report.rail)}"
    pose = " ".join(_n(v) for v in report.pose)
    return (
        f"{stamp} {report.state.value:<5} joints {joints}{rail} | pose {pose} | "
        f"pump {report.pump_pwm} valve {report.valve_pwm}"
    )


def _duration(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.1f}s"
    minutes, secs = divmod(round(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


_FINISHING: Final = "all sent, the arm is finishing its moves"


class ProgressBar:
    """Plain progress lines (not a terminal): lines acknowledged out of ``total``, elapsed time
    and an estimate of the time left.

    A line is printed when a new tenth of the lines is acknowledged (at most every ``min_gap``
    seconds) and at least every ``quiet_period`` seconds. Once every line is acknowledged the arm
    may still be moving: the text then says so until :meth:`finish`.
    """

    def __init__(
        self,
        total: int,
        stream: TextIO,
        *,
        clock: Callable[[], float] = time.monotonic,
        width: int = 30,
        min_gap: float = 1.0,
        quiet_period: float = 5.0,
    ) -> None:
        self.total = total
        self.done = 0
        self._stream = stream
        self._clock = clock
        self._width = width
        self._min_gap = min_gap
        self._quiet_period = quiet_period
        self._start = clock()
        self._last_print = -math.inf
        self._printed_tenth = 0
        self._finished = False
        self._outcome = ""

    def render(self, now: float | None = None) -> str:
        """The progress text for the current state (no line ending)."""
        elapsed = (self._clock() if now is None else now) - self._start
        fraction = min(self.done / self.total, 1.0) if self.total else 1.0
        filled = int(fraction * self._width)
        bar = "#" * filled + "-" * (self._width - filled)
        if self._finished:
            eta = self._outcome
        elif self.done >= self.total:
            eta = _FINISHING
        elif self.done == 0:
            eta = "ETA ?"
        else:
            eta = "ETA " + _duration(elapsed / self.done * (self.total - self.done))
        digits = len(str(self.total))
        return (
            f"[{bar}] {self.done:>{digits}}/{self.total} lines {fraction:4.0%}  "
            f"elapsed {_duration(elapsed)}  {eta}"
        )

    def update(self, done: int | None = None) -> None:
        """Record that ``done`` lines are acknowledged (None: only the time passed) and print a
        line when it is time."""
        if done is not None:
            self.done = max(self.done, min(done, self.total))
        if self._finished:
            return
        now = self._clock()
        since = now - self._last_print
        tenth = self.done * 10 // max(self.total, 1)
        if (tenth > self._printed_tenth and since >= self._min_gap) or (
            since >= self._quiet_period
        ):
            self._print(now)

    async def tick(self, period: float = 0.2) -> None:
        """Keep the elapsed time moving while nothing is acknowledged (run it as a task)."""
        while not self._finished:
            await asyncio.sleep(period)
            self.update()

    def finish(self, outcome: str = "done") -> None:
        """Show the final state with ``outcome`` (idempotent)."""
        if self._finished:
            return
        self._finished = True
        self._outcome = outcome
        self._print(self._clock())

    def _print(self, now: float) -> None:
        self._stream.write(self.render(now) + "\n")
        self._stream.flush()
        self._last_print = now
        self._printed_tenth = self.done * 10 // max(self.total, 1)


class RichProgressBar:
    """The progress of a run drawn in place with ``rich`` (a terminal): same interface as
    :class:`ProgressBar`. Redrawn by :meth:`tick` (no thread of its own)."""

    def __init__(self, total: int, stream: TextIO, *, force_terminal: bool | None = None) -> None:
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self.total = total
        self.done = 0
        self._finished = False
        console = Console(file=stream, force_terminal=force_terminal)
        self._progress: rich.progress.Progress = Progress(
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("lines"),
            TimeElapsedColumn(),
            TextColumn("ETA"),
            TimeRemainingColumn(),
            TextColumn("{task.description}"),
            console=console,
            auto_refresh=False,
            redirect_stdout=False,
            redirect_stderr=False,
        )
        self._task = self._progress.add_task("", total=total)
        self._progress.start()

    def update(self, done: int | None = None) -> None:
        """Record that ``done`` lines are acknowledged (None: only the time passed)."""
        if self._finished:
            return
        if done is not None:
            self.done = max(self.done, min(done, self.total))
        description = _FINISHING if self.done >= self.total else ""
        self._progress.update(self._task, completed=self.done, description=description)
        self._progress.refresh()

    async def tick(self, period: float = 0.1) -> None:
        """Redraw (the elapsed time moves) until :meth:`finish` (run it as a task)."""
        while not self._finished:
            await asyncio.sleep(period)
            self.update()

    def finish(self, outcome: str = "done") -> None:
        """Show the final state with ``outcome`` and stop drawing (idempotent)."""
        if self._finished:
            return
        self._progress.update(self._task, completed=self.done, description=outcome)
        self._finished = True
        self._progress.refresh()
        self._progress.stop()


def progress_bar(total: int, stream: TextIO) -> ProgressBar | RichProgressBar:
    """The rich bar on a terminal, plain lines otherwise."""
    if stream.isatty():
        return RichProgressBar(total, stream)
    return ProgressBar(total, stream)


class LiveView:
    """``monitor`` output: a table redrawn in place with ``rich`` on a terminal, else one line
    per sample. Use as a context manager (it stops the live display)."""

    def __init__(self, stream: TextIO, *, force_terminal: bool | None = None) -> None:
        self._stream = stream
        self._live: rich.live.Live | None = None
        self.samples = 0
        if force_terminal or (force_terminal is None and stream.isatty()):
            from rich.console import Console
            from rich.live import Live

            console = Console(file=stream, force_terminal=True)
            self._live = Live(
                console=console, auto_refresh=False, redirect_stdout=False, redirect_stderr=False
            )

    def __enter__(self) -> LiveView:
        if self._live is not None:
            self._live.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._live is not None:
            self._live.stop()

    def show_silence(self, when: datetime.datetime) -> None:
        """The arm answered no status request for a while: most likely it is homing."""
        stamp = when.strftime("%H:%M:%S.%f")[:-3]
        text = (
            f"{stamp} Home? no status reply: the arm is probably homing (it answers no '?' "
            "while it searches its switches); waiting"
        )
        if self._live is None:
            self._stream.write(text + "\n")
            self._stream.flush()
            return
        from rich.text import Text

        self._live.update(Text(text), refresh=True)

    def show(self, report: StatusReport, when: datetime.datetime) -> None:
        """Show one sample."""
        self.samples += 1
        if self._live is None:
            self._stream.write(format_status_line(report, when) + "\n")
            self._stream.flush()
            return
        from rich.table import Table

        table = Table(
            title=f"sample {self.samples} at {when.strftime('%H:%M:%S.%f')[:-3]}  (Ctrl-C to stop)",
            show_header=False,
        )
        rail = report.rail is not None
        for _ in range(8 if rail else 7):
            table.add_column(justify="right")
        table.add_row(
            "", "J1", "J2", "J3", "J4", "J5", "J6", *(["rail"] if rail else []), style="bold"
        )
        table.add_row(
            "joints",
            *(_n(v) for v in report.joints),
            *([_n(report.rail)] if report.rail is not None else []),
        )
        table.add_row("", "x", "y", "z", "rx", "ry", "rz", style="bold")
        table.add_row("pose", *(_n(v) for v in report.pose))
        table.add_row(
            "state",
            report.state.value,
            "pump",
            str(report.pump_pwm),
            "valve",
            str(report.valve_pwm),
        )
        self._live.update(table, refresh=True)


def line_ranges(numbers: Sequence[int]) -> str:
    """``[3, 4, 5, 9]`` -> ``"3-5, 9"`` (at most a few ranges, then ``...``)."""
    ranges: list[str] = []
    start = previous = None
    for number in [*numbers, None]:
        if start is not None and (number is None or number != (previous or 0) + 1):
            ranges.append(str(start) if start == previous else f"{start}-{previous}")
            start = None
        if number is not None and start is None:
            start = number
        previous = number
    if len(ranges) > 4:
        ranges = [*ranges[:3], "...", ranges[-1]]
    return ", ".join(ranges)


def describe_interrupted_run(
    name: str, program: Sequence[ProgramLine], sent: int, acknowledged: int
) -> list[str]:
    """What was still queued when a run was interrupted, as lines for stderr.

    ``sent`` program lines were written, ``acknowledged`` of them answered: GRBL answers a
    motion when it enters the planner, so those may still have been queued in the arm; the
    others were in its input buffer; the rest of the program was never sent.
    """
    numbers = [line.number for line in program]
    sent = min(sent, len(numbers))
    acknowledged = min(acknowledged, sent)
    messages = []
    unanswered = numbers[acknowledged:sent]
    if unanswered:
        messages.append(
            f"{len(unanswered)} line(s) sent but not executed (queued in the arm): "
            f"{name} line {line_ranges(unanswered)}"
        )
    if acknowledged:
        messages.append(
            f"{acknowledged} line(s) accepted by the arm (up to line {numbers[acknowledged - 1]}); "
            "the last moves among them may not have finished"
        )
    not_sent = numbers[sent:]
    if not_sent:
        messages.append(f"{len(not_sent)} line(s) not sent: {name} line {line_ranges(not_sent)}")
    return messages


def describe_failures(
    program: Sequence[ProgramLine],
    sent: int,
    acknowledged: int,
    first_failed: int,
    failures: int,
    *,
    continue_on_error: bool,
) -> None:
    """Sum up a run with refused lines on stderr (``first_failed`` is a 1-based index into
    ``program``)."""
    note(
        f"{failures} line{' was' if failures == 1 else 's were'} refused; "
        f"{acknowledged} of {len(program)} acknowledged"
    )
    already_sent = sent - first_failed
    if not continue_on_error and already_sent > 0:
        note(
            f"stopped at line {program[first_failed - 1].number}, but the {already_sent} "
            "line(s) after it had already been sent (pipelined) before the refusal arrived"
        )
