"""Status traces: the CSV format written by ``mirobot run --trace`` / ``mirobot monitor --csv``,
and the picture drawn by ``mirobot plot``.

A trace is a CSV file with a header row and one row per status sample::

    timestamp,state,j1,j2,j3,j4,j5,j6,rail,x,y,z,rx,ry,rz,pump,valve,time_scale
    2025-01-31T14:03:07.412+01:00,Run,12.5,...,10

``timestamp`` is ISO 8601 with milliseconds and the UTC offset (wall time); angles in degrees,
lengths in mm (``rail`` is empty when the arm reports no rail); ``pump`` / ``valve`` are the PWM
values; ``time_scale`` is the virtual arm's speed (robot seconds per wall second; empty for a
real arm, whose time is the wall time). The plot's time axis is the robot's time: wall intervals
times the time scale (wall time when the virtual arm ran at time scale 0, where moves take no
time). Files without the ``time_scale`` column (older traces) are read as a real arm's.

Events (alarm, hold) are marked where the status first showed them; outputs (pump, valve,
gripper) where they took effect. The firmware reports an ``M3``/``M4`` output as soon as it reads
the line, which can be while moves queued ahead of it are still running (the vendor firmware does
the same), but switches it once those moves have ended: the mark is put at the first sample from
there on where the arm stands (see :meth:`Trace.took_effect`).

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

from mirobot_async._core.replies import StatusReport

__all__ = [
    "PLOT_SIZE_PX",
    "TRACE_COLUMNS",
    "PlottingUnavailableError",
    "Trace",
    "TraceError",
    "TraceEvent",
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
    "time_scale",
)
"""The header of a trace file, in order."""

PLOT_SIZE_PX: Final = (1200, 800)
"""Width and height of the PNG written by :func:`plot_trace`, in pixels."""

_DPI: Final = 100
_AT_REST_MM: Final = 0.05
"""Tool travel between two samples below which the arm is taken to stand (mm)."""
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


def status_row(
    report: StatusReport, when: datetime.datetime, time_scale: float | None = None
) -> list[str]:
    """One CSV row (in :data:`TRACE_COLUMNS` order) for ``report`` sampled at ``when`` from an
    arm running at ``time_scale`` (None: a real arm)."""
    return [
        when.isoformat(timespec="milliseconds"),
        report.state.value,
        *(_num(angle) for angle in report.joints),
        "" if report.rail is None else _num(report.rail),
        *(_num(value) for value in report.pose),
        str(report.pump_pwm),
        str(report.valve_pwm),
        "" if time_scale is None else f"{time_scale:g}",
    ]


class TraceWriter:
    """Writes status samples to a trace CSV, one flushed row per sample.

    ``append=True`` adds rows to an existing file (the header is written only if the file is
    empty; a file with another header is refused); otherwise the file is replaced.
    ``time_scale`` is the virtual arm's speed (None: a real arm). Opening errors raise
    :class:`TraceError`.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        append: bool = False,
        time_scale: float | None = None,
    ) -> None:
        self.path = Path(path)
        self.rows = 0
        self.time_scale = time_scale
        if append:
            _check_header(self.path)
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
        self._writer.writerow(status_row(report, stamp, self.time_scale))
        self._file.flush()
        self.rows += 1

    def close(self) -> None:
        """Close the file (idempotent)."""
        self._file.close()

    def __enter__(self) -> TraceWriter:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def _check_header(path: Path) -> None:
    """Refuse to append to a file whose header is not :data:`TRACE_COLUMNS`."""
    try:
        with open(path, newline="", encoding="utf-8") as file:
            first = file.readline()
    except FileNotFoundError:
        return
    except (OSError, UnicodeDecodeError) as err:
        raise TraceError(f"cannot append to {path}: {err}") from err
    if first.strip() and next(csv.reader([first])) != list(TRACE_COLUMNS):
        raise TraceError(
            f"cannot append to {path}: it is not a trace in this format "
            f"(header {first.strip()!r}); give another file"
        )


# --------------------------------------------------------------------------------------------
# Reading


@dataclass(frozen=True, slots=True)
class TraceEvent:
    """Something that happened at one sample: the pump, valve or gripper output changed, or
    the arm went into Alarm or Hold."""

    index: int
    """The sample at which it was first seen."""
    seconds: float
    kind: str
    """``"output"`` (pump / valve / gripper PWM) or ``"state"`` (Alarm, Hold)."""
    label: str


@dataclass(frozen=True, slots=True)
class Trace:
    """A trace read back: parallel sequences, one entry per sample."""

    seconds: tuple[float, ...]
    """Time of each sample since the first one, in the robot's time (see :attr:`robot_time`)."""
    states: tuple[str, ...]
    joints: tuple[tuple[float, float, float, float, float, float], ...]
    positions: tuple[tuple[float, float, float], ...]
    """Tool position (x, y, z) in mm."""
    pumps: tuple[int | None, ...] = ()
    valves: tuple[int | None, ...] = ()
    robot_time: bool = True
    """False when a virtual arm ran at time scale 0 (moves took no time): wall time then."""

    def __len__(self) -> int:
        return len(self.seconds)

    def took_effect(self, index: int) -> int:
        """The sample at which an output first reported at ``index`` took effect: the firmware
        reports an ``M3``/``M4`` as soon as it reads the line but runs it once the moves queued
        ahead have ended, where the arm stands. That is the sample before ``index`` when the arm
        stood there (the line ran between the two samples, and the arm went on), else the first
        sample from ``index`` on where the arm is at rest (not ``Run``, or the tool within
        :data:`_AT_REST_MM` of the next sample), or where its speed dips to a clear minimum
        between two moves (a stop shorter than a sample)."""
        if index >= 1 and (
            self.states[index - 1] != "Run"
            or (
                index >= 2
                and math.dist(self.positions[index - 2], self.positions[index - 1]) <= _AT_REST_MM
            )
        ):
            return index - 1  # read and run while the arm stood there, seen as it moved on
        fastest = 0.0
        for j in range(index, len(self) - 1):
            step = math.dist(self.positions[j], self.positions[j + 1])
            if self.states[j] != "Run" or step <= _AT_REST_MM:
                return j
            speed = self._speed(j)
            if j > index:
                before = self._speed(j - 1)
                if before < 0.3 * fastest and speed > 2.0 * before:
                    return j  # slowed down to here, faster after: a stop between samples
            fastest = max(fastest, speed)
        return len(self) - 1 if self.states[-1] != "Run" else index

    def _speed(self, j: int) -> float:
        """Tool speed from sample ``j`` to the next (mm/s; samples are not evenly spaced)."""
        dt = max(self.seconds[j + 1] - self.seconds[j], 1e-6)
        return math.dist(self.positions[j], self.positions[j + 1]) / dt

    def events(self) -> list[TraceEvent]:
        """Changes of the pump / valve outputs and entries into Alarm or Hold, in order."""
        found: list[TraceEvent] = []
        for index in range(len(self)):
            before = index - 1
            for values, describe in ((self.pumps, _pump_label), (self.valves, _valve_label)):
                if index < len(values) and values[index] is not None:
                    value = values[index]
                    previous = values[before] if before >= 0 else None
                    if before >= 0 and previous is not None and value != previous:
                        assert value is not None
                        took = self.took_effect(index)
                        found.append(
                            TraceEvent(took, self.seconds[took], "output", describe(value))
                        )
            state = self.states[index]
            if state in ("Alarm", "Hold") and (before < 0 or self.states[before] != state):
                found.append(TraceEvent(index, self.seconds[index], "state", state.lower()))
        return found


def _pump_label(pwm: int) -> str:
    """PWM output 1 drives the pump (1000 suck, 500 blow, 0 off) or the servo gripper."""
    names = {
        1000: "suction on",
        500: "blow",
        0: "pump off",
        40: "gripper open",
        60: "gripper closed",
    }
    return names.get(pwm, f"PWM1 {pwm}")


def _valve_label(pwm: int) -> str:
    """PWM output 2 drives the valve or the older gripper (65 open, 40 closed)."""
    names = {65: "gripper open (PWM2)", 40: "gripper closed (PWM2)", 0: "valve off"}
    return names.get(pwm, f"valve {pwm}")


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


def _optional_pwm(text: str | None, column: str) -> int | None:
    """A ``pump`` / ``valve`` cell: None when empty, else a whole number (``ValueError`` for
    anything else, ``inf`` and ``nan`` included)."""
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or not value.is_integer():
        raise ValueError(f"{column} {text!r} is not a whole PWM value")
    return int(value)


def _robot_seconds(walls: list[float], scales: list[float]) -> tuple[tuple[float, ...], bool]:
    """Robot time since the first sample: each wall interval times the time scale of the sample
    that ends it. Wall time (and False) when any scale is 0 (moves took no time)."""
    if not walls:
        return (), True
    if any(scale <= 0 for scale in scales):
        return tuple(t - walls[0] for t in walls), False
    seconds = [0.0]
    for index in range(1, len(walls)):
        seconds.append(seconds[-1] + max(0.0, walls[index] - walls[index - 1]) * scales[index])
    return tuple(seconds), True


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
    scales: list[float] = []
    states: list[str] = []
    joints: list[tuple[float, float, float, float, float, float]] = []
    positions: list[tuple[float, float, float]] = []
    pumps: list[int | None] = []
    valves: list[int | None] = []
    for row in reader:
        lineno = reader.line_num
        try:
            stamp = _parse_time(row["timestamp"] or "")
            j = tuple(float(row[f"j{n}"] or "") for n in range(1, 7))
            p = tuple(float(row[axis] or "") for axis in ("x", "y", "z"))
            scale = float(row.get("time_scale") or 1.0)
            pump = _optional_pwm(row.get("pump"), "pump")
            valve = _optional_pwm(row.get("valve"), "valve")
        except (ValueError, TypeError) as err:
            raise TraceError(f"{name}:{lineno}: bad sample: {err}") from err
        if not all(math.isfinite(v) for v in (stamp, scale, *j, *p)):
            raise TraceError(f"{name}:{lineno}: bad sample: a value is not a finite number")
        times.append(stamp)
        scales.append(scale)
        states.append(row.get("state") or "")
        joints.append((j[0], j[1], j[2], j[3], j[4], j[5]))
        positions.append((p[0], p[1], p[2]))
        pumps.append(pump)
        valves.append(valve)
    seconds, robot_time = _robot_seconds(times, scales)
    return Trace(
        seconds=seconds,
        states=tuple(states),
        joints=tuple(joints),
        positions=tuple(positions),
        pumps=tuple(pumps),
        valves=tuple(valves),
        robot_time=robot_time,
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

_EVENT_COLOURS: Final = {"output": "tab:purple", "state": "tab:red"}


def plot_trace(trace: Trace, output: str | os.PathLike[str], *, title: str | None = None) -> None:
    """Draw ``trace`` to a PNG of :data:`PLOT_SIZE_PX` pixels: the tool path seen from above (XY)
    and from the side (XZ) with start, end and events marked, and the joint angles over the
    robot's time with the events (pump, gripper, valve, alarm, hold) as labelled lines.

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
    events = trace.events()

    xs = [p[0] for p in trace.positions]
    ys = [p[1] for p in trace.positions]
    zs = [p[2] for p in trace.positions]
    for axes, horizontal, vertical, labels, view in (
        (top, xs, ys, ("x (mm)", "y (mm)"), "top view (XY)"),
        (side, xs, zs, ("x (mm)", "z (mm)"), "side view (XZ)"),
    ):
        axes.plot(
            horizontal,
            vertical,
            color="tab:blue",
            linewidth=1.5,
            marker=".",
            markersize=2,
            label="tool path",
        )
        # The start is a wide ring drawn under the end's small square: both stay visible
        # when the program ends where it started.
        axes.plot(
            horizontal[0],
            vertical[0],
            "o",
            markersize=15,
            markerfacecolor="none",
            markeredgecolor="tab:green",
            markeredgewidth=2.5,
            label="start",
            zorder=4,
        )
        axes.plot(
            horizontal[-1],
            vertical[-1],
            "s",
            color="tab:red",
            markersize=6,
            label="end",
            zorder=5,
        )
        for number, event in enumerate(events, start=1):
            axes.annotate(
                str(number),
                (horizontal[event.index], vertical[event.index]),
                xytext=(6, 6),
                textcoords="offset points",
                fontsize="small",
                color=_EVENT_COLOURS[event.kind],
                fontweight="bold",
            )
            axes.plot(
                horizontal[event.index],
                vertical[event.index],
                "D",
                markersize=5,
                color=_EVENT_COLOURS[event.kind],
                zorder=6,
            )
        axes.margins(0.12)
        axes.set_aspect("equal", adjustable="datalim")
        axes.set_xlabel(labels[0])
        axes.set_ylabel(labels[1])
        axes.set_title(f"Tool path, {view}")
        axes.grid(True, alpha=0.3)
        axes.legend(loc="best", fontsize="small")

    for index in range(6):
        angles.plot(
            trace.seconds, [j[index] for j in trace.joints], linewidth=1.5, label=f"J{index + 1}"
        )
    for number, event in enumerate(events, start=1):
        colour = _EVENT_COLOURS[event.kind]
        angles.axvline(event.seconds, color=colour, linestyle="--", linewidth=1, alpha=0.8)
        angles.annotate(
            f"{number} {event.label}",
            (event.seconds, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(3, -3 - 11 * (number % 3)),
            textcoords="offset points",
            va="top",
            fontsize="small",
            color=colour,
        )
    angles.axvline(trace.seconds[0], color="tab:green", linewidth=2, alpha=0.6)
    angles.axvline(trace.seconds[-1], color="tab:red", linewidth=2, alpha=0.6)
    angles.set_xlabel(
        "robot time (s)"
        if trace.robot_time
        else "wall time (s): the virtual arm ran at time scale 0, its moves took no time"
    )
    angles.set_ylabel("angle (deg)")
    angles.set_title(
        "Joint angles; dashed: events when the status first showed them "
        "(numbered as on the tool path)"
    )
    angles.grid(True, alpha=0.3)
    angles.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize="small")

    duration = trace.seconds[-1]
    clock = "robot time" if trace.robot_time else "wall time"
    figure.suptitle(
        title or f"Mirobot trace: {len(trace)} samples over {duration:.1f} s ({clock})",
        fontsize="large",
    )
    figure.savefig(os.fspath(output), dpi=_DPI, format="png")
