"""The ``mirobot`` command line (also ``python -m mirobot_async``).

Subcommands that talk to an arm take ``--port URL``; without it they start an embedded virtual
Mirobot (the emulator, on a fresh pseudo-terminal) for the duration of the command, so every
command works on a machine with no arm. ``--firmware`` and ``--time-scale`` choose that virtual
arm's profile and speed; ``-v`` logs the wire traffic to stderr.

Exit status: 0 success; 1 the robot refused or failed (a refused line, an alarm, a timeout, a
lost link), or ``check`` found problems; 2 a usage problem (bad argument, missing file, port that
cannot be opened); 130 interrupted by Ctrl-C (``monitor`` exits 0: Ctrl-C is how it ends).
Errors are one line on stderr, ``mirobot: error: ...``, never a traceback (``-v`` adds the
traceback of unexpected errors).

Layout: :func:`build_parser` (argparse), one ``cmd_*`` function per subcommand, :func:`main`
which runs it and maps exceptions to exit statuses in one place (:func:`_failure`).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import datetime
import importlib
import inspect
import logging
import math
import os
import signal
import sys
import time
import traceback
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final, NoReturn, TextIO

from mirobot_async import gcode
from mirobot_async.errors import (
    MirobotAlarmError,
    MirobotCommandError,
    MirobotConnectionError,
    MirobotError,
    MirobotLinkLostError,
    MirobotUsageError,
)
from mirobot_async.plotting import PlottingUnavailableError, TraceError, TraceWriter
from mirobot_async.replies import State, StatusReport

if TYPE_CHECKING:
    from mirobot_async.client import Mirobot, StreamResult

__all__ = [
    "DEFAULT_TIME_SCALE",
    "EXIT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_USAGE",
    "JOINT_KEYS",
    "POSE_KEYS",
    "CliError",
    "ProgramLine",
    "ProgressBar",
    "build_parser",
    "format_status_line",
    "format_status_table",
    "main",
    "parse_assignments",
    "read_program",
]

_log = logging.getLogger("mirobot_async.cli")

PROG: Final = "mirobot"
EXIT_OK: Final = 0
EXIT_FAILED: Final = 1
EXIT_USAGE: Final = 2
EXIT_INTERRUPTED: Final = 130

DEFAULT_TIME_SCALE: Final = 10.0
"""Speed of the embedded virtual Mirobot (simulated seconds per wall second)."""
DEFAULT_MONITOR_INTERVAL: Final = 0.5
DEFAULT_TRACE_INTERVAL: Final = 0.05
"""``run --trace`` samples the status at about 20 Hz."""

JOINT_KEYS: Final = ("j1", "j2", "j3", "j4", "j5", "j6", "rail")
POSE_KEYS: Final = ("x", "y", "z", "rx", "ry", "rz")
_KEY_ALIASES: Final = {"d": "rail", "a": "rx", "b": "ry", "c": "rz"}

_PUMP_PWM: Final = {
    "on": gcode.PUMP_SUCK,
    "blow": gcode.PUMP_BLOW,
    "off": gcode.PUMP_OFF,
}


class CliError(Exception):
    """A usage problem (argument, file, port): printed as one line, exit status 2."""


def _note(message: str) -> None:
    """A remark for the user on stderr (never on stdout, which carries the results)."""
    print(f"{PROG}: {message}", file=sys.stderr, flush=True)


# --------------------------------------------------------------------------------------------
# Argument values


def parse_assignments(items: Sequence[str], keys: Sequence[str], what: str) -> dict[str, float]:
    """``["j1=10", "j3=-5.5"]`` -> ``{"j1": 10.0, "j3": -5.5}``; keys are case-insensitive.

    ``keys`` are the allowed names (plus the aliases ``d`` for ``rail`` and ``a``/``b``/``c`` for
    ``rx``/``ry``/``rz`` when those are allowed); ``what`` names them in messages ("joint").
    Raises :class:`CliError` for a malformed item, an unknown or repeated key, a value that is
    not a finite number, or no item at all. Ranges are checked by the :mod:`~mirobot_async.gcode`
    builders.
    """
    allowed = ", ".join(keys)
    example = f"{keys[0]}=10"
    if not items:
        raise CliError(f"give at least one {what} target as KEY=VALUE ({allowed}), e.g. {example}")
    values: dict[str, float] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip().lower()
        key = _KEY_ALIASES.get(key, key) if _KEY_ALIASES.get(key) in keys else key
        if not sep or not key:
            raise CliError(f"{item!r} is not KEY=VALUE (e.g. {example}); keys: {allowed}")
        if key not in keys:
            raise CliError(f"unknown {what} {key!r} in {item!r}: use {allowed}")
        if key in values:
            raise CliError(f"{key} is given twice")
        try:
            number = float(text)
        except ValueError:
            raise CliError(f"{item}: {text.strip()!r} is not a number") from None
        if not math.isfinite(number):
            raise CliError(f"{item}: the value must be a finite number")
        values[key] = number
    return values


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r} must be a number > 0")
    return value


def _time_scale(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"{text!r} must be a number >= 0 (0: moves end at once)")
    return value


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
    return value


# --------------------------------------------------------------------------------------------
# Parser


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is ONE line: ``mirobot: error: ... (see 'mirobot X --help')``."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{PROG}: error: {message} (see '{self.prog} --help')\n")


def _common_options() -> _Parser:
    common = _Parser(add_help=False)
    common.add_argument(
        "-v",
        "--verbose",
        action="count",
        default=argparse.SUPPRESS,
        help="log the wire traffic (every line sent and received) to stderr",
    )
    return common


def _robot_options() -> _Parser:
    robot = _Parser(add_help=False)
    group = robot.add_argument_group("robot connection")
    group.add_argument(
        "--port",
        metavar="URL",
        help="the arm's serial port or pyserial URL (/dev/ttyUSB0, COM3, socket://host:port); "
        "without it an embedded virtual Mirobot is started for this command",
    )
    group.add_argument(
        "--firmware",
        choices=gcode.FIRMWARE_PROFILES,
        help="firmware profile of the embedded virtual Mirobot (default: 2021); with --port, "
        "the arm's firmware (default: detected)",
    )
    group.add_argument(
        "--time-scale",
        type=_time_scale,
        default=None,
        metavar="X",
        help="speed of the embedded virtual Mirobot in simulated seconds per wall second "
        f"(default: {DEFAULT_TIME_SCALE:g}; 0: every move ends at once)",
    )
    return robot


def _add_prepare_options(parser: argparse.ArgumentParser, embedded: str) -> None:
    """``--home`` / ``--unlock`` / ``--no-home``; ``embedded`` is what the embedded virtual
    Mirobot gets by default (it starts locked, like an arm after power-on)."""
    done = "homed" if embedded == "home" else "unlocked"
    group = parser.add_argument_group(
        "before starting",
        f"an arm is locked after power-on: by default the embedded virtual Mirobot is {done} "
        "first and a real arm (--port) is used as it is",
    )
    choice = group.add_mutually_exclusive_group()
    choice.add_argument(
        "--home", dest="prepare", action="store_const", const="home", help="home the arm first"
    )
    choice.add_argument(
        "--unlock",
        dest="prepare",
        action="store_const",
        const="unlock",
        help="unlock the axes first, without homing ($X, M50)",
    )
    choice.add_argument(
        "--no-home",
        "--as-is",
        dest="prepare",
        action="store_const",
        const="none",
        help="use the arm as it is, even the embedded virtual one",
    )
    parser.set_defaults(prepare=None, embedded_prepare=embedded)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``mirobot`` (each subcommand sets ``handler``)."""
    common = _common_options()
    robot = _robot_options()
    parser = _Parser(
        prog=PROG,
        description="Drive a WLKATA Mirobot, or the virtual one: status, monitoring, homing,\n"
        "jogging, running and checking G-code programs, tracing and plotting.\n"
        "Without --port, a virtual Mirobot is started for the duration of the command.",
        epilog="examples:\n"
        "  mirobot run examples/pick_and_place.gcode      (on an embedded virtual Mirobot)\n"
        "  mirobot status --port /dev/ttyUSB0\n"
        "  mirobot run examples/square.gcode --trace square.csv && mirobot plot square.csv\n\n"
        "exit status: 0 done; 1 the robot refused or failed, or 'check' found problems;\n"
        "2 bad argument, file or port; 130 interrupted (Ctrl-C)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        parents=[_common_options()],  # its own copy: set_defaults() changes the action
    )
    parser.set_defaults(verbose=0)
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def add(name: str, handler: object, help_text: str, *, talks: bool = True) -> _Parser:
        sub = commands.add_parser(
            name,
            help=help_text,
            description=help_text,
            parents=[common, robot] if talks else [common],
        )
        sub.set_defaults(handler=handler)
        assert isinstance(sub, _Parser)
        return sub

    add("status", cmd_status, "print one status report as a table")

    monitor = add("monitor", cmd_monitor, "watch the status live until Ctrl-C")
    monitor.add_argument(
        "--interval",
        type=_positive_float,
        default=DEFAULT_MONITOR_INTERVAL,
        metavar="S",
        help=f"seconds between samples (default: {DEFAULT_MONITOR_INTERVAL:g})",
    )
    monitor.add_argument(
        "--csv", metavar="FILE", help="also append every sample to this CSV file (a trace)"
    )
    monitor.add_argument("--samples", type=_positive_int, metavar="N", help="stop after N samples")

    home = add("home", cmd_home, "run the homing cycle ($H)")
    home.add_argument(
        "--sequential", action="store_true", help="home the axes one after another ($HH)"
    )
    add("unlock", cmd_unlock, "unlock the axes without homing (clears an alarm)")
    add("reset", cmd_reset, "soft-reset the controller (the arm is locked again afterwards)")

    move = add("move", None, "move the arm: 'move joints ...' or 'move pose ...'")
    move_kinds = move.add_subparsers(dest="kind", metavar="KIND", required=True)
    joints = move_kinds.add_parser(
        "joints",
        help="joint-space move, e.g. j1=30 j2=10",
        description="Joint-space move to angles in degrees (j1..j6) and rail position in mm.",
        parents=[common, robot],
    )
    joints.add_argument("targets", nargs="*", metavar="JOINT=DEG", help="j1..j6 (deg), rail (mm)")
    joints.add_argument(
        "--speed", type=_positive_float, metavar="DEG_PER_MIN", help="speed (default: the fastest)"
    )
    joints.add_argument("--relative", action="store_true", help="angles are increments")
    joints.set_defaults(handler=cmd_move_joints)
    _add_prepare_options(joints, "home")
    pose = move_kinds.add_parser(
        "pose",
        help="Cartesian move, e.g. x=200 y=0 z=150",
        description="Cartesian move of the tool to x, y, z (mm) and rx, ry, rz (deg).",
        parents=[common, robot],
    )
    pose.add_argument("targets", nargs="*", metavar="AXIS=VALUE", help="x y z (mm), rx ry rz (deg)")
    pose.add_argument("--linear", action="store_true", help="move in a straight line (G1)")
    pose.add_argument(
        "--speed",
        type=_positive_float,
        metavar="MM_PER_MIN",
        help="speed (required with --linear, default 2000 there)",
    )
    pose.add_argument("--relative", action="store_true", help="values are increments")
    pose.set_defaults(handler=cmd_move_pose)
    _add_prepare_options(pose, "home")

    pump = add("pump", cmd_pump, "air pump of the suction cup: on (suck), blow, off")
    pump.add_argument("action", choices=("on", "blow", "off"))
    _add_prepare_options(pump, "unlock")
    gripper = add("gripper", cmd_gripper, "open or close the gripper")
    gripper.add_argument("action", choices=("open", "close"))
    gripper.add_argument(
        "--legacy",
        action="store_true",
        help="the older gripper on PWM 2 (M4 E65/E40) instead of the servo gripper (M3 S40/S60)",
    )
    _add_prepare_options(gripper, "unlock")

    run = add("run", cmd_run, "stream a G-code program with a progress bar")
    run.add_argument("file", metavar="FILE", help="G-code program (one command per line)")
    run.add_argument(
        "--trace", metavar="FILE.csv", help="record status samples (about 20 Hz) to this CSV"
    )
    run.add_argument(
        "--continue-on-error",
        action="store_true",
        help="report refused lines and go on (exit status 1 at the end)",
    )
    _add_prepare_options(run, "home")

    check = add("check", cmd_check, "validate a G-code program offline", talks=False)
    check.add_argument("file", metavar="FILE")
    check.add_argument(
        "--firmware",
        choices=gcode.FIRMWARE_PROFILES,
        default="2021",
        help="firmware profile to check against (default: 2021)",
    )

    plot = add("plot", cmd_plot, "plot a trace: tool path (top, side) and joints", talks=False)
    plot.add_argument("trace", metavar="TRACE.csv", help="from 'run --trace' or 'monitor --csv'")
    plot.add_argument(
        "-o", "--output", metavar="FILE.png", help="PNG to write (default: TRACE with .png)"
    )
    plot.add_argument("--title", help="title of the figure")

    emulator = commands.add_parser(
        "emulator",
        help="run the virtual Mirobot on a pty (same as mirobot-emulator; see "
        "'mirobot emulator --help')",
        add_help=False,
    )
    emulator.add_argument("arguments", nargs=argparse.REMAINDER)
    emulator.set_defaults(handler=cmd_emulator)
    return parser


# --------------------------------------------------------------------------------------------
# Output formatting


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


class ProgressBar:
    """Lines acknowledged out of ``total``, elapsed time and an estimate of the time left.

    On a terminal the bar is redrawn in place (``\\r``) at most every ``redraw`` seconds;
    otherwise a line is printed when a new tenth of the lines is acknowledged (at most every
    ``min_gap`` seconds) and at least every ``quiet_period`` seconds. Once every line is
    acknowledged the arm may still be moving: the bar then says so until :meth:`finish`.
    """

    def __init__(
        self,
        total: int,
        stream: TextIO,
        *,
        tty: bool | None = None,
        clock: Callable[[], float] = time.monotonic,
        width: int = 30,
        redraw: float = 0.1,
        min_gap: float = 1.0,
        quiet_period: float = 5.0,
    ) -> None:
        self.total = total
        self.done = 0
        self._stream = stream
        self._tty = stream.isatty() if tty is None else tty
        self._clock = clock
        self._width = width
        self._redraw = redraw
        self._min_gap = min_gap
        self._quiet_period = quiet_period
        self._start = clock()
        self._last_draw = -math.inf
        self._printed_tenth = 0
        self._drawn_width = 0
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
            eta = "all sent, the arm is finishing its moves"
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
        """Record that ``done`` lines are acknowledged (None: only the time passed) and redraw
        or print when it is time."""
        if done is not None:
            self.done = max(self.done, min(done, self.total))
        if self._finished:
            return
        now = self._clock()
        since = now - self._last_draw
        if self._tty:
            if since >= self._redraw or (done is not None and self.done >= self.total):
                self._draw(now)
            return
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
        """Show the final state with ``outcome`` and end the line (idempotent)."""
        if self._finished:
            return
        self._finished = True
        self._outcome = outcome
        now = self._clock()
        if self._tty:
            self._draw(now)
            self._stream.write("\n")
            self._stream.flush()
        else:
            self._print(now)

    def _draw(self, now: float) -> None:
        text = self.render(now)
        pad = max(0, self._drawn_width - len(text))
        self._stream.write("\r" + text + " " * pad)
        self._stream.flush()
        self._drawn_width = len(text)
        self._last_draw = now

    def _print(self, now: float) -> None:
        self._stream.write(self.render(now) + "\n")
        self._stream.flush()
        self._last_draw = now
        self._printed_tenth = self.done * 10 // max(self.total, 1)


# --------------------------------------------------------------------------------------------
# Files


@dataclass(frozen=True, slots=True)
class ProgramLine:
    """A command of a program file: its 1-based line number and the text to send."""

    number: int
    text: str


def _strip_comments(line: str) -> str:
    """The line without ``( ... )`` and ``; ...`` comments and surrounding space."""
    out: list[str] = []
    depth = False
    for char in line:
        if depth:
            depth = char != ")"
            continue
        if char == ";":
            break
        if char == "(":
            depth = True
            continue
        out.append(char)
    return " ".join("".join(out).split())


def _read_lines(path: str) -> list[str]:
    """The lines of a text file (latin-1, so that any byte is reported, not a decode error)."""
    try:
        with open(path, encoding="latin-1", newline=None) as file:
            return file.read().splitlines()
    except FileNotFoundError:
        raise CliError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise CliError(f"{path}: is a directory, not a G-code file") from None
    except OSError as err:
        raise CliError(f"cannot read {path}: {err.strerror or err}") from None


def read_program(path: str) -> list[ProgramLine]:
    """The commands of a G-code file: comments and blank lines dropped, line numbers kept."""
    program = []
    for number, raw in enumerate(_read_lines(path), start=1):
        text = _strip_comments(raw)
        if text:
            program.append(ProgramLine(number, text))
    return program


def _open_trace(
    path: str | None, *, append: bool
) -> contextlib.AbstractContextManager[TraceWriter | None]:
    if path is None:
        return contextlib.nullcontext()
    try:
        return TraceWriter(path, append=append)
    except TraceError as err:
        raise CliError(str(err)) from None


# --------------------------------------------------------------------------------------------
# The robot


def _firmware(args: argparse.Namespace) -> str:
    """The firmware profile for the embedded emulator and argument checks (default 2021)."""
    return str(args.firmware or "2021")


def _check_port(port: str) -> None:
    """Fail early, in plain words, for a device path that does not exist or is locked.

    "Locked" is an exclusive ``flock`` held by another program, as pyserial takes with
    ``exclusive=True``: the port is opened without blocking, tested and closed again.
    URLs (``socket://...``) and non-POSIX names (``COM3``) are left to the transport.
    """
    if "://" in port or not port.startswith("/"):
        return
    if not os.path.exists(port):
        raise CliError(f"{port}: no such port (is the arm plugged in and switched on?)")
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        return
    try:
        fd = os.open(port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError:
        return  # the transport reports it with the OS's words
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        raise CliError(f"{port} is busy: another program is using it") from None
    except OSError:
        return
    finally:
        os.close(fd)  # also releases the lock


@contextlib.asynccontextmanager
async def _robot(args: argparse.Namespace) -> AsyncIterator[Mirobot]:
    """The arm at ``--port``, or an embedded virtual Mirobot for the duration of the block."""
    from mirobot_async.client import Mirobot

    if args.port is not None:
        if args.time_scale is not None:
            _note("note: --time-scale only applies to the embedded virtual Mirobot; ignored")
        _check_port(args.port)
        async with Mirobot.connect(args.port, firmware=args.firmware) as arm:
            yield arm
        return

    from mirobot_async.testing import start_emulator

    firmware = _firmware(args)
    scale = DEFAULT_TIME_SCALE if args.time_scale is None else args.time_scale
    _note(
        f"no --port given; using an embedded virtual Mirobot "
        f"(firmware {firmware}, time-scale {scale:g})"
    )
    async with (
        start_emulator(firmware=firmware, time_scale=scale) as url,
        Mirobot.connect(url, firmware="classic" if firmware == "classic" else "2021") as arm,
    ):
        yield arm


@contextlib.asynccontextmanager
async def _sampling(arm: Mirobot, interval: float) -> AsyncIterator[AsyncIterator[StatusReport]]:
    """``arm.statuses(interval)``, closed at the end of the block (not left to the GC)."""
    statuses = arm.statuses(interval=interval)
    try:
        yield statuses
    finally:
        aclose = getattr(statuses, "aclose", None)
        if aclose is not None:
            await aclose()


async def _prepare(arm: Mirobot, args: argparse.Namespace) -> None:
    """Home or unlock before starting, as ``--home`` / ``--unlock`` / ``--no-home`` say."""
    mode = args.prepare
    if mode is None:
        mode = "none" if args.port is not None else args.embedded_prepare
        if mode == "home":
            _note("homing the virtual Mirobot first (--no-home to skip)")
        elif mode == "unlock":
            _note("unlocking the virtual Mirobot first (--as-is to skip)")
    if mode == "home":
        await arm.home()
    elif mode == "unlock":
        await arm.unlock()


async def _show_final_status(arm: Mirobot) -> None:
    print(format_status_table(await arm.status()), flush=True)


# --------------------------------------------------------------------------------------------
# Subcommands


async def cmd_status(args: argparse.Namespace) -> int:
    """``mirobot status``: one status report as a table."""
    async with _robot(args) as arm:
        report = await arm.status()
    print(format_status_table(report), flush=True)
    if report.state is State.ALARM and args.port is not None:
        _note("the arm is in Alarm (locked): 'mirobot home' or 'mirobot unlock' releases it")
    return EXIT_OK


class _LiveView:
    """``monitor`` output: a table redrawn in place on a terminal, else one line per sample."""

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream
        self._tty = stream.isatty()
        self._height = 0
        self.samples = 0

    def show(self, report: StatusReport, when: datetime.datetime) -> None:
        self.samples += 1
        if not self._tty:
            self._stream.write(format_status_line(report, when) + "\n")
            self._stream.flush()
            return
        text = (
            f"sample {self.samples} at {when.strftime('%H:%M:%S.%f')[:-3]}  (Ctrl-C to stop)\n"
            + format_status_table(report)
            + "\n"
        )
        if self._height:
            self._stream.write(f"\x1b[{self._height}F\x1b[J")
        self._stream.write(text)
        self._stream.flush()
        self._height = text.count("\n")


async def cmd_monitor(args: argparse.Namespace) -> int:
    """``mirobot monitor``: status samples until Ctrl-C (or ``--samples N``)."""
    view = _LiveView(sys.stdout)
    with _open_trace(args.csv, append=True) as trace:
        try:
            async with _robot(args) as arm, _sampling(arm, args.interval) as statuses:
                async for report in statuses:
                    when = datetime.datetime.now().astimezone()
                    view.show(report, when)
                    if trace is not None:
                        trace.write(report, when)
                    if args.samples is not None and view.samples >= args.samples:
                        break
        finally:
            if trace is not None and view.samples:
                _note(f"{trace.rows} samples written to {trace.path}")
    return EXIT_OK


async def cmd_home(args: argparse.Namespace) -> int:
    """``mirobot home [--sequential]``."""
    async with _robot(args) as arm:
        await arm.home(sequential=args.sequential)
        await _show_final_status(arm)
    return EXIT_OK


async def cmd_unlock(args: argparse.Namespace) -> int:
    """``mirobot unlock``."""
    async with _robot(args) as arm:
        await arm.unlock()
        await _show_final_status(arm)
    return EXIT_OK


async def cmd_reset(args: argparse.Namespace) -> int:
    """``mirobot reset``: soft reset (``%``); the firmware reprints its banner."""
    async with _robot(args) as arm:
        await arm.reset()
        await _show_final_status(arm)
    return EXIT_OK


def _values(targets: dict[str, float], keys: Sequence[str]) -> list[float | None]:
    """The targets in ``keys`` order, ``None`` for the ones not given (they stay)."""
    return [targets.get(key) for key in keys]


def _joint_targets(args: argparse.Namespace) -> dict[str, float]:
    targets = parse_assignments(args.targets, JOINT_KEYS, "joint")
    # Checks every value and the ranges before anything is started (MirobotUsageError: exit 2).
    gcode.move_joints(
        *_values(targets, JOINT_KEYS),
        speed=args.speed,
        relative=args.relative,
        firmware=_firmware(args),
    )
    return targets


def _pose_targets(args: argparse.Namespace) -> dict[str, float]:
    targets = parse_assignments(args.targets, POSE_KEYS, "axis")
    if args.linear and args.speed is None:
        args.speed = 2000.0
    gcode.move_pose(
        *_values(targets, POSE_KEYS), speed=args.speed, linear=args.linear, relative=args.relative
    )
    return targets


async def cmd_move_joints(args: argparse.Namespace) -> int:
    """``mirobot move joints j1=.. [--relative] [--speed]``."""
    targets = _joint_targets(args)
    async with _robot(args) as arm:
        await _prepare(arm, args)
        await arm.move_joints(
            *_values(targets, JOINT_KEYS), speed=args.speed, relative=args.relative
        )
        await _show_final_status(arm)
    return EXIT_OK


async def cmd_move_pose(args: argparse.Namespace) -> int:
    """``mirobot move pose x=.. [--linear] [--relative] [--speed]``."""
    targets = _pose_targets(args)
    async with _robot(args) as arm:
        await _prepare(arm, args)
        await arm.move_pose(
            *_values(targets, POSE_KEYS),
            speed=args.speed,
            linear=args.linear,
            relative=args.relative,
        )
        await _show_final_status(arm)
    return EXIT_OK


async def cmd_pump(args: argparse.Namespace) -> int:
    """``mirobot pump on|blow|off``."""
    async with _robot(args) as arm:
        await _prepare(arm, args)
        await arm.set_pump(_PUMP_PWM[args.action])
        await _show_final_status(arm)
    return EXIT_OK


async def cmd_gripper(args: argparse.Namespace) -> int:
    """``mirobot gripper open|close [--legacy]``."""
    closed = args.action == "close"
    async with _robot(args) as arm:
        await _prepare(arm, args)
        if closed:
            await arm.gripper_close(legacy=args.legacy)
        else:
            await arm.gripper_open(legacy=args.legacy)
        await _show_final_status(arm)
    return EXIT_OK


async def _record(arm: Mirobot, trace: TraceWriter, interval: float) -> None:
    """Append status samples to ``trace`` until cancelled."""
    async with _sampling(arm, interval) as statuses:
        async for report in statuses:
            trace.write(report)


def _failure_words(err: MirobotError) -> str:
    """What the firmware said (its own words) or, for other errors, the error message."""
    if isinstance(err, MirobotCommandError) and err.text:
        return err.text
    return str(err)


@contextlib.asynccontextmanager
async def _background(**jobs: Awaitable[None] | None) -> AsyncIterator[None]:
    """Run ``jobs`` (None: skipped; keyword: what it is, for messages) as tasks for the duration
    of the block, then cancel them.

    A job's failure never replaces the block's outcome: after a block that succeeded it is a
    warning on stderr (e.g. the trace is incomplete), after one that failed it is only logged
    at debug level (most likely the same cause, such as the link lost). A cancellation of the
    calling task while the jobs wind down (a second Ctrl-C) propagates: ``gather`` raises
    :class:`asyncio.CancelledError` only then, the jobs' own cancellations are results.
    """
    tasks = {
        name.replace("_", " "): asyncio.ensure_future(job)
        for name, job in jobs.items()
        if job is not None
    }
    succeeded = False
    try:
        yield
        succeeded = True
    finally:
        for task in tasks.values():
            task.cancel()
        results = await asyncio.gather(*tasks.values(), return_exceptions=True)
        for name, result in zip(tasks, results, strict=True):
            if isinstance(result, Exception):
                _log.debug("%s failed", name, exc_info=result)
                if succeeded:
                    _note(f"warning: {name} failed: {type(result).__name__}: {result}")


def _report_failures(
    args: argparse.Namespace, program: list[ProgramLine], result: StreamResult
) -> None:
    """Sum up a run with refused lines."""
    count = len(result.errors)
    first = result.errors[0].number
    _note(
        f"{count} line{' was' if count == 1 else 's were'} refused; "
        f"{result.acknowledged} of {len(program)} acknowledged"
    )
    already_sent = result.sent - first
    if not args.continue_on_error and already_sent > 0:
        _note(
            f"stopped at line {program[first - 1].number}, but the {already_sent} line(s) after "
            "it had already been sent (pipelined) before the refusal arrived"
        )


async def cmd_run(args: argparse.Namespace) -> int:
    """``mirobot run FILE``: stream the program, with a progress bar; final status at the end."""
    program = read_program(args.file)
    if not program:
        raise CliError(f"{args.file}: no commands in the file")
    with _open_trace(args.trace, append=False) as trace:
        async with _robot(args) as arm:
            await _prepare(arm, args)
            progress = ProgressBar(len(program), sys.stderr)
            recorder = None if trace is None else _record(arm, trace, DEFAULT_TRACE_INTERVAL)
            async with _background(progress_bar=progress.tick(), status_recording=recorder):
                try:
                    result = await arm.stream(
                        [line.text for line in program],
                        on_progress=lambda line: progress.update(line.number),
                        continue_on_error=args.continue_on_error,
                    )
                    with contextlib.suppress(MirobotAlarmError):  # the status shows the alarm
                        await arm.wait_idle()
                except BaseException:
                    progress.finish("stopped")
                    raise
                if not result.errors:
                    progress.finish("done")
                else:
                    progress.finish("done, with errors" if args.continue_on_error else "stopped")
            for failed in result.errors:
                line = program[failed.number - 1]
                words = "failed" if failed.error is None else _failure_words(failed.error)
                print(f"{args.file}:{line.number}: {line.text}: {words}", file=sys.stderr)
            final = await arm.status()
            if trace is not None:
                trace.write(final)
            print(format_status_table(final), flush=True)
    if trace is not None:
        _note(f"{trace.rows} status samples written to {trace.path}")
    if result.errors:
        _report_failures(args, program, result)
        return EXIT_FAILED
    return EXIT_OK


def cmd_check(args: argparse.Namespace) -> int:
    """``mirobot check FILE``: offline validation, problems as ``FILE:LINE: message``."""
    lines = _read_lines(args.file)
    problems = gcode.check_program(lines, firmware=args.firmware)
    for number, message in problems:
        print(f"{args.file}:{number}: {message}")
    if problems:
        count = len(problems)
        _note(f"{count} problem{'s' if count != 1 else ''} in {args.file}")
        return EXIT_FAILED
    commands = sum(1 for line in lines if gcode.normalize_line(line))
    print(f"OK: {len(lines)} lines ({commands} commands, firmware {args.firmware})")
    return EXIT_OK


def cmd_plot(args: argparse.Namespace) -> int:
    """``mirobot plot TRACE.csv -o FILE.png``."""
    from mirobot_async.plotting import PLOT_SIZE_PX, plot_trace, read_trace

    output = args.output or os.path.splitext(args.trace)[0] + ".png"
    try:
        trace = read_trace(args.trace)
        plot_trace(trace, output, title=args.title)
    except TraceError as err:
        raise CliError(str(err)) from None
    except OSError as err:
        raise CliError(f"cannot write {output}: {err.strerror or err}") from None
    width, height = PLOT_SIZE_PX
    print(f"wrote {output} ({width}x{height} px, {len(trace)} samples)")
    return EXIT_OK


def cmd_emulator(args: argparse.Namespace) -> int:
    """``mirobot emulator ...``: the ``mirobot-emulator`` command (normally dispatched by
    :func:`main` before argparse sees the arguments)."""
    return _run_emulator(args.arguments)


def _run_emulator(argv: Sequence[str]) -> int:
    # Imported by name: the emulator is a separate top-level package (not type-checked here).
    emulator = importlib.import_module("mirobot_emulator.__main__")
    status: int = emulator.main(list(argv))
    return status


# --------------------------------------------------------------------------------------------
# Running and exit statuses


def _failure(exc: BaseException, verbose: int) -> tuple[int, str]:
    """The exit status and the one-line message for an exception.

    The one place that maps exceptions to exit statuses.
    """
    if isinstance(exc, CliError | MirobotUsageError):
        return EXIT_USAGE, str(exc)
    if isinstance(exc, PlottingUnavailableError):
        return EXIT_USAGE, str(exc)
    if isinstance(exc, MirobotLinkLostError):
        return EXIT_FAILED, f"lost the link to the robot: {exc}"
    if isinstance(exc, MirobotConnectionError):
        return EXIT_USAGE, str(exc)
    if isinstance(exc, MirobotError):
        return EXIT_FAILED, str(exc)
    if verbose:
        traceback.print_exception(exc, file=sys.stderr)
    return EXIT_FAILED, f"unexpected {type(exc).__name__}: {exc} (run with -v for the traceback)"


@contextlib.contextmanager
def _logging_to_stderr(verbose: int) -> Iterator[None]:
    """Log ``mirobot_async`` records to stderr: everything (the wire traffic) with ``-v``, else
    only errors (what went wrong is said once, by the ``mirobot: error:`` line).

    Undone at the end, so that calling :func:`main` in-process leaves logging as it was.
    """
    logger = logging.getLogger("mirobot_async")
    saved = (logger.level, logger.propagate)
    handler = logging.StreamHandler(sys.stderr)
    if verbose:
        handler.setFormatter(logging.Formatter("%(relativeCreated)9.1f ms %(name)s: %(message)s"))
        logger.setLevel(logging.DEBUG)
    else:
        handler.setFormatter(logging.Formatter(f"{PROG}: %(levelname)s: %(message)s"))
        logger.setLevel(logging.ERROR)
    logger.addHandler(handler)
    logger.propagate = False
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(saved[0])
        logger.propagate = saved[1]


def _run_async(
    handler: Callable[[argparse.Namespace], Awaitable[int]], args: argparse.Namespace
) -> tuple[int, bool]:
    """Run an async subcommand; returns (status, interrupted by SIGINT)."""
    interrupted = False

    async def runner() -> int:
        nonlocal interrupted
        loop = asyncio.get_running_loop()
        task = asyncio.current_task()
        assert task is not None

        def on_sigint() -> None:
            nonlocal interrupted
            interrupted = True
            task.cancel()

        with contextlib.suppress(NotImplementedError, RuntimeError):  # e.g. not on Windows
            loop.add_signal_handler(signal.SIGINT, on_sigint)
        try:
            return await handler(args)
        finally:
            with contextlib.suppress(NotImplementedError, RuntimeError):
                loop.remove_signal_handler(signal.SIGINT)

    try:
        return asyncio.run(runner()), False
    except (KeyboardInterrupt, asyncio.CancelledError):
        return EXIT_INTERRUPTED, True
    except BaseException:
        if interrupted:  # whatever broke while stopping, Ctrl-C was the cause
            return EXIT_INTERRUPTED, True
        raise


def _emulator_argv(argv: Sequence[str]) -> list[str] | None:
    """The emulator's arguments if this is ``mirobot [-v] emulator ...``, else None."""
    for index, arg in enumerate(argv):
        if arg == "emulator":
            return list(argv[index + 1 :])
        if arg not in ("-v", "--verbose", "-vv"):
            return None
    return None


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``mirobot``; returns the exit status."""
    arguments = list(sys.argv[1:] if argv is None else argv)
    emulator_args = _emulator_argv(arguments)
    if emulator_args is not None:
        return _run_emulator(emulator_args)
    args = build_parser().parse_args(arguments)
    verbose: int = args.verbose
    with _logging_to_stderr(verbose):
        try:
            return _run_command(args)
        except KeyboardInterrupt:
            return EXIT_INTERRUPTED
        except BrokenPipeError:
            # stdout was closed early (``mirobot monitor | head``): not worth a message.
            with contextlib.suppress(OSError):
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return EXIT_FAILED
        except Exception as exc:
            status, message = _failure(exc, verbose)
            print(f"{PROG}: error: {message}", file=sys.stderr, flush=True)
            return status


def _run_command(args: argparse.Namespace) -> int:
    handler = args.handler
    if not inspect.iscoroutinefunction(handler):
        status: int = handler(args)
        return status
    status, interrupted = _run_async(handler, args)
    if interrupted:  # Ctrl-C is how monitor ends: not a failure
        return EXIT_OK if args.command == "monitor" else EXIT_INTERRUPTED
    return status
