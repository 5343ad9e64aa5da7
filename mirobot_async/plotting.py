"""Status traces: the CSV format written by ``mirobot run --trace`` / ``mirobot monitor --csv``,
and the picture drawn by ``mirobot plot``.

A trace is a CSV file with a header row and one row per status sample::

    timestamp,state,j1,j2,j3,j4,j5,j6,rail,x,y,z,rx,ry,rz,pump,valve
    2025-01-31T14:03:07.412+01:00,Run,12.5,...

``timestamp`` is ISO 8601 with milliseconds and the UTC offset; angles in degrees, lengths in mm
(``rail`` is empty when the arm reports no rail); ``pump`` / ``valve`` are the PWM values.

Reading and writing need only the standard library. :func:`plot_trace` needs matplotlib (the
``plot`` extra: ``pip install 'mirobot-async[plot]'``), imported only when it is called; without
it :class:`PlottingUnavailableError` says how to install it.
"""

from __future__ import annotations

import csv
import datetime
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Final

from mirobot_async.replies import StatusReport

__all__ = [
    "PLOT_SIZE_PX",
    "TRACE_COLUMNS",
    "PlottingUnavailableError",
    "Trace",
    "TraceError",
    "TraceWriter",
    "plot_trace",
    "read_trace",
    "status_row",
]

TRACE_COLUMNS: Final = (
    "timestamp",
    "state",
    "j1",
    "j2",
    "j3",
    "j4",
    "j5",
    "j6",
    "rail",
    "x",
    "y",
    "z",
    "rx",
    "ry",
    "rz",
    "pump",
    "valve",
)
"""The header of a trace file, in order."""

PLOT_SIZE_PX: Final = (1200, 800)
"""Width and height of the PNG written by :func:`plot_trace`, in pixels."""

_DPI: Final = 100
_INSTALL_HINT: Final = (
    "plotting needs matplotlib, which is not installed; "
    "install the plot extra: pip install 'mirobot-async[plot]'"
)


class TraceError(ValueError):
    """A trace file is missing, unreadable or not in the trace format (message names the line)."""


class PlottingUnavailableError(RuntimeError):
    """matplotlib is not installed; the message says how to install the ``plot`` extra."""


# --------------------------------------------------------------------------------------------
# Writing


def _num(value: float) -> str:
    text = f"{value:.3f}"
    return "0.000" if text == "-0.000" else text


def status_row(report: StatusReport, when: datetime.datetime) -> list[str]:
    """One CSV row (in :data:`TRACE_COLUMNS` order) for ``report`` sampled at ``when``."""
    return [
        when.isoformat(timespec="milliseconds"),
        report.state.value,
        *(_num(angle) for angle in report.joints),
        "" if report.rail is None else _num(report.rail),
        *(_num(value) for value in report.pose),
        str(report.pump_pwm),
        str(report.valve_pwm),
    ]


class TraceWriter:
    """Writes status samples to a trace CSV, one flushed row per sample.

    ``append=True`` adds rows to an existing file (the header is written only if the file is
    empty); otherwise the file is replaced. Opening errors raise :class:`TraceError`.
    """

    def __init__(self, path: str | os.PathLike[str], *, append: bool = False) -> None:
        self.path = Path(path)
        self.rows = 0
        try:
            self._file: IO[str] = open(  # noqa: SIM115 - closed by close() / __exit__
                self.path, "a" if append else "w", newline="", encoding="utf-8"
            )
        except OSError as err:
            raise TraceError(f"cannot write {self.path}: {err.strerror or err}") from err
        self._writer = csv.writer(self._file)
        if self._file.tell() == 0:
            self._writer.writerow(TRACE_COLUMNS)
            self._file.flush()

    def write(self, report: StatusReport, when: datetime.datetime | None = None) -> None:
        """Append one sample (``when`` defaults to now, local time with its UTC offset)."""
        stamp = when if when is not None else datetime.datetime.now().astimezone()
        self._writer.writerow(status_row(report, stamp))
        self._file.flush()
        self.rows += 1

    def close(self) -> None:
        """Close the file (idempotent)."""
        self._file.close()

    def __enter__(self) -> TraceWriter:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


# --------------------------------------------------------------------------------------------
# Reading


@dataclass(frozen=True, slots=True)
class Trace:
    """A trace read back: parallel sequences, one entry per sample."""

    seconds: tuple[float, ...]
    """Time of each sample since the first one."""
    states: tuple[str, ...]
    joints: tuple[tuple[float, float, float, float, float, float], ...]
    positions: tuple[tuple[float, float, float], ...]
    """Tool position (x, y, z) in mm."""

    def __len__(self) -> int:
        return len(self.seconds)


def _parse_time(text: str) -> float:
    """Seconds since the epoch from an ISO 8601 timestamp or a plain number of seconds."""
    try:
        return float(text)
    except ValueError:
        pass
    moment = datetime.datetime.fromisoformat(text)
    if moment.tzinfo is None:
        moment = moment.astimezone()
    return moment.timestamp()


def _parse_rows(lines: Iterable[str], name: str) -> Trace:
    reader = csv.DictReader(lines)
    header = reader.fieldnames
    if header is None:
        raise TraceError(f"{name}: the file is empty (expected a trace CSV with a header row)")
    missing = [
        col
        for col in ("timestamp", "j1", "j2", "j3", "j4", "j5", "j6", "x", "y", "z")
        if col not in header
    ]
    if missing:
        raise TraceError(
            f"{name}:1: not a trace file: missing column(s) {', '.join(missing)} "
            f"(expected {','.join(TRACE_COLUMNS)})"
        )
    times: list[float] = []
    states: list[str] = []
    joints: list[tuple[float, float, float, float, float, float]] = []
    positions: list[tuple[float, float, float]] = []
    for row in reader:
        lineno = reader.line_num
        try:
            stamp = _parse_time(row["timestamp"] or "")
            j = tuple(float(row[f"j{n}"] or "") for n in range(1, 7))
            p = tuple(float(row[axis] or "") for axis in ("x", "y", "z"))
        except (ValueError, TypeError) as err:
            raise TraceError(f"{name}:{lineno}: bad sample: {err}") from err
        if not all(math.isfinite(v) for v in (stamp, *j, *p)):
            raise TraceError(f"{name}:{lineno}: bad sample: a value is not a finite number")
        times.append(stamp)
        states.append(row.get("state") or "")
        joints.append((j[0], j[1], j[2], j[3], j[4], j[5]))
        positions.append((p[0], p[1], p[2]))
    start = times[0] if times else 0.0
    return Trace(
        seconds=tuple(t - start for t in times),
        states=tuple(states),
        joints=tuple(joints),
        positions=tuple(positions),
    )


def read_trace(path: str | os.PathLike[str]) -> Trace:
    """Read a trace CSV. Raises :class:`TraceError` naming the file and line on any problem."""
    name = os.fspath(path)
    try:
        with open(path, newline="", encoding="utf-8") as file:
            return _parse_rows(file, name)
    except OSError as err:
        raise TraceError(f"cannot read {name}: {err.strerror or err}") from err
    except (UnicodeDecodeError, csv.Error) as err:
        raise TraceError(f"{name}: not a trace CSV: {err}") from err


# --------------------------------------------------------------------------------------------
# Plotting


def plot_trace(trace: Trace, output: str | os.PathLike[str], *, title: str | None = None) -> None:
    """Draw ``trace`` to a PNG of :data:`PLOT_SIZE_PX` pixels: the tool path seen from above (XY)
    and from the side (XZ), and the joint angles over time.

    Raises :class:`TraceError` for an empty trace, :class:`PlottingUnavailableError` without
    matplotlib, and :class:`OSError` if the file cannot be written.
    """
    if len(trace) == 0:
        raise TraceError("the trace has no samples: nothing to plot")
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as err:
        raise PlottingUnavailableError(_INSTALL_HINT) from err

    width, height = PLOT_SIZE_PX
    figure = Figure(figsize=(width / _DPI, height / _DPI), dpi=_DPI, layout="constrained")
    FigureCanvasAgg(figure)
    grid = figure.add_gridspec(2, 2, height_ratios=(3, 2))
    top = figure.add_subplot(grid[0, 0])
    side = figure.add_subplot(grid[0, 1])
    angles = figure.add_subplot(grid[1, :])

    xs = [p[0] for p in trace.positions]
    ys = [p[1] for p in trace.positions]
    zs = [p[2] for p in trace.positions]
    for axes, horizontal, vertical, labels, view in (
        (top, xs, ys, ("x (mm)", "y (mm)"), "top view (XY)"),
        (side, xs, zs, ("x (mm)", "z (mm)"), "side view (XZ)"),
    ):
        axes.plot(horizontal, vertical, color="tab:blue", linewidth=1.5, label="tool path")
        axes.plot(horizontal[0], vertical[0], "o", color="tab:green", markersize=8, label="start")
        axes.plot(horizontal[-1], vertical[-1], "s", color="tab:red", markersize=8, label="end")
        axes.margins(0.1)
        axes.set_aspect("equal", adjustable="datalim")
        axes.set_xlabel(labels[0])
        axes.set_ylabel(labels[1])
        axes.set_title(f"Tool path, {view}")
        axes.grid(True, alpha=0.3)
        axes.legend(loc="best", fontsize="small")

    for index in range(6):
        angles.plot(
            trace.seconds,
            [j[index] for j in trace.joints],
            linewidth=1.5,
            label=f"J{index + 1}",
        )
    angles.set_xlabel("time (s)")
    angles.set_ylabel("angle (deg)")
    angles.set_title("Joint angles")
    angles.grid(True, alpha=0.3)
    angles.legend(loc="upper right", ncols=6, fontsize="small")

    duration = trace.seconds[-1]
    figure.suptitle(
        title or f"Mirobot trace: {len(trace)} samples over {duration:.1f} s", fontsize="large"
    )
    figure.savefig(os.fspath(output), dpi=_DPI, format="png")
