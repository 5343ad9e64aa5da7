"""The arguments of ``mirobot``: KEY=VALUE targets, number types, and the argparse parser.

Subcommands that talk to an arm take the robot connection options (``--port``, ``--firmware``,
``--time-scale``, ``--record``, ``-v``); the offline ones (``check``, ``plot``) take none of them.
Commands that move the arm take ``--on-interrupt hold|reset``.
"""

from __future__ import annotations

import argparse
import math
import os
from typing import Final, NoReturn

from mirobot_async._cli import commands
from mirobot_async._cli.demo import DEFAULT_EXAMPLE, cmd_demo
from mirobot_async._cli.exits import EXIT_USAGE, PROG
from mirobot_async._core import gcode

__all__ = ["DEFAULT_MONITOR_INTERVAL", "add_envelope_option", "build_parser"]

DEFAULT_MONITOR_INTERVAL: Final = 0.5
PORT_ENV: Final = "MIROBOT_PORT"
"""Environment variable: the default of ``--port`` (a port, a URL or ``auto``)."""
_DEFAULT_TIME_SCALE_TEXT: Final = "10"  # session.DEFAULT_TIME_SCALE, without importing asyncio


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


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is ONE line: ``mirobot: error: ... (see 'mirobot X --help')``."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{PROG}: error: {message} (see '{self.prog} --help')\n")


def _robot_options() -> _Parser:
    robot = _Parser(add_help=False)
    group = robot.add_argument_group("robot connection")
    where = group.add_mutually_exclusive_group()
    where.add_argument(
        "--port",
        metavar="URL",
        default=os.environ.get(PORT_ENV) or None,
        help="the arm's serial port or pyserial URL (/dev/ttyUSB0, COM3, socket://host:port), "
        f"or 'auto' (default: ${PORT_ENV}); without either an embedded virtual Mirobot is "
        "started for this command",
    )
    where.add_argument(
        "--auto",
        dest="port",
        action="store_const",
        const="auto",
        help="find the arm: the one port that answers as a Mirobot (see 'mirobot ports'; "
        "sends only ? and $$); several answering is an error",
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
        f"(default: {_DEFAULT_TIME_SCALE_TEXT}; 0: every move ends at once)",
    )
    group.add_argument(
        "--record",
        metavar="FILE",
        help="append a tape of this session to FILE (JSON Lines: a header naming the link kind, "
        "banner and firmware family, then every byte sent and every line received, with their "
        "instants; written as it goes, closed when the command ends; see docs/tapes.md)",
    )
    group.add_argument(
        "-v",
        "--verbose",
        action="count",
        default=argparse.SUPPRESS,
        help="log the wire traffic (every line sent and received) to stderr",
    )
    return robot


def _add_prepare_options(parser: argparse.ArgumentParser, embedded: str) -> None:
    """``--home`` / ``--unlock`` / ``--no-home``; ``embedded`` is what the embedded virtual
    Mirobot gets by default (it starts locked, like an arm after power-on)."""
    done = "homed" if embedded == "home" else "unlocked"
    group = parser.add_argument_group(
        "before starting",
        f"an arm is locked after power-on: by default the embedded virtual Mirobot is {done} "
        "first and a real arm (--port) is used as it is; a locked arm is refused before the "
        "first motion line (where its status does not show the lock, a zero-length joint "
        "move that moves nothing finds it)",
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


def _add_interrupt_option(parser: argparse.ArgumentParser) -> None:
    """``--on-interrupt hold|reset`` for a command that moves the arm."""
    parser.add_argument(
        "--on-interrupt",
        choices=("hold", "reset"),
        default="hold",
        help="what Ctrl-C or SIGTERM does to the moving arm: 'hold' sends feed hold (!): it "
        "decelerates and stops, queued moves stay in it; 'reset' sends soft reset (%%): it "
        "stops at once and its queue is cleared (default: hold). Exit status 130 either way",
    )


# --- envelope option (--envelope FILE) -------------------------------------------------------


def _add_view_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--view`` (and ``--no-browser``): the 3D view on the command's own connection."""
    parser.add_argument(
        "--view",
        action="store_true",
        help=f"also show the arm in 3D in a browser: its motion, {what} (needs the view extra; "
        "the URL, with its secret, is printed on stderr)",
    )
    parser.add_argument(
        "--no-browser", action="store_true", help="with --view: print the URL, open no browser"
    )


def add_envelope_option(parser: argparse.ArgumentParser) -> None:
    """``--envelope FILE`` for a command that moves the arm: every line is checked against the
    workspace safety envelope in that TOML file (see examples/envelope.toml)."""
    parser.add_argument(
        "--envelope",
        metavar="FILE",
        help="a safety envelope (TOML: [box] x/y/z, [joints] 1..6, rail = [min, max]; see "
        "examples/envelope.toml): every line is checked against it before it is sent, and a "
        "move that would leave it is refused with nothing sent",
    )


# --- end of the envelope option ----------------------------------------------------------------


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("mirobot-async")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree
        from mirobot_async import __version__

        return __version__


def _replay_handler(args: argparse.Namespace) -> int:
    from mirobot_async._cli.tapes import cmd_replay  # the emulator loads only when replaying

    return cmd_replay(args)


async def _doctor_handler(args: argparse.Namespace) -> int:
    from mirobot_async._cli.doctor import cmd_doctor  # the emulator loads only for the replay

    return await cmd_doctor(args)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``mirobot`` (each subcommand sets ``handler``)."""
    robot = _robot_options()
    parser = _Parser(
        prog=PROG,
        description="Drive a WLKATA Mirobot, or the virtual one: status, monitoring, homing,\n"
        "jogging, running and checking G-code programs, tracing and plotting.\n"
        "Without --port, a virtual Mirobot is started for the duration of the command.",
        epilog="examples:\n"
        "  mirobot demo                                   (an example on a virtual Mirobot)\n"
        "  mirobot run examples/pick_and_place.gcode      (on an embedded virtual Mirobot)\n"
        "  mirobot status --port /dev/ttyUSB0\n"
        "  mirobot run examples/square.gcode --trace square.csv && mirobot plot square.csv\n"
        "  cat program.gcode | mirobot run -\n"
        "  mirobot home --port /dev/ttyUSB0 --record session.jsonl  (a tape of the session)\n\n"
        "Ctrl-C (or SIGTERM) while the arm moves sends feed hold (!) at once, says what was\n"
        "still queued and exits 130 (--on-interrupt reset sends soft reset instead).\n\n"
        "exit status: 0 done; 1 the robot refused or failed, the arm is locked, the safety\n"
        "envelope refused a line (move, run), or 'check' found problems; 2 bad argument, file\n"
        "or port; 130 interrupted (Ctrl-C, SIGTERM)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "-v",
        "--verbose",
        action="count",
        default=0,
        help="log the wire traffic (every line sent and received) to stderr",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    commands_parser = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def add(name: str, handler: object, help_text: str, *, talks: bool = True) -> _Parser:
        sub = commands_parser.add_parser(
            name, help=help_text, description=help_text, parents=[robot] if talks else []
        )
        sub.set_defaults(handler=handler)
        assert isinstance(sub, _Parser)
        return sub

    add("status", commands.cmd_status, "print one status report as a table")

    monitor = add("monitor", commands.cmd_monitor, "watch the status live until Ctrl-C")
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
    _add_view_option(monitor, "the path of what another task sends on this connection")

    home = add(
        "home",
        commands.cmd_home,
        "run the homing cycle ($H); Ctrl-C stops it with a soft reset (%%), the only thing "
        "that stops homing",
    )
    home.add_argument(
        "--sequential", action="store_true", help="home the axes one after another ($HH)"
    )
    add("unlock", commands.cmd_unlock, "unlock the axes without homing (clears an alarm)")
    add(
        "reset",
        commands.cmd_reset,
        "soft-reset the controller (%%): stops at once and clears the queue; a reset that stops "
        "motion leaves the arm in Alarm (home or unlock), one at rest does not lock it",
    )

    move = add("move", None, "move the arm: 'move joints ...' or 'move pose ...'")
    move_kinds = move.add_subparsers(dest="kind", metavar="KIND", required=True)
    joints = move_kinds.add_parser(
        "joints",
        help="joint-space move, e.g. j1=30 j2=10",
        description="Joint-space move to angles in degrees (j1..j6) and rail position in mm.",
        parents=[robot],
    )
    joints.add_argument("targets", nargs="*", metavar="JOINT=DEG", help="j1..j6 (deg), rail (mm)")
    joints.add_argument(
        "--speed", type=_positive_float, metavar="DEG_PER_MIN", help="speed (default: the fastest)"
    )
    joints.add_argument("--relative", action="store_true", help="angles are increments")
    joints.set_defaults(handler=commands.cmd_move_joints)
    _add_prepare_options(joints, "home")
    _add_interrupt_option(joints)
    add_envelope_option(joints)
    pose = move_kinds.add_parser(
        "pose",
        help="Cartesian move, e.g. x=200 y=0 z=150",
        description="Cartesian move of the tool to x, y, z (mm) and rx, ry, rz (deg).",
        parents=[robot],
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
    pose.set_defaults(handler=commands.cmd_move_pose)
    _add_prepare_options(pose, "home")
    _add_interrupt_option(pose)
    add_envelope_option(pose)

    pump = add("pump", commands.cmd_pump, "air pump of the suction cup: on (suck), blow, off")
    pump.add_argument("action", choices=("on", "blow", "off"))
    _add_prepare_options(pump, "unlock")
    gripper = add("gripper", commands.cmd_gripper, "open or close the gripper")
    gripper.add_argument("action", choices=("open", "close"))
    gripper.add_argument(
        "--legacy",
        action="store_true",
        help="the older gripper on PWM 2 (M4 E65/E40) instead of the servo gripper (M3 S40/S60)",
    )
    _add_prepare_options(gripper, "unlock")
    _add_interrupt_option(gripper)

    run = add("run", commands.cmd_run, "stream a G-code program with a progress bar")
    run.add_argument(
        "file", metavar="FILE", help="G-code program (one command per line); - reads stdin"
    )
    run.add_argument(
        "--trace", metavar="FILE.csv", help="record status samples (every 50 ms of robot time)"
    )
    run.add_argument(
        "--continue-on-error",
        action="store_true",
        help="report refused lines and go on (exit status 1 at the end)",
    )
    run.add_argument(
        "--no-check",
        action="store_true",
        help="send the program without the check 'mirobot check' does: the lines it flags are "
        "listed as warnings and sent all the same (an --envelope still refuses the whole "
        "program before its first byte)",
    )
    _add_prepare_options(run, "home")
    _add_interrupt_option(run)
    add_envelope_option(run)
    _add_view_option(
        run, "the program's predicted path and its refused lines; it waits for the page first"
    )

    demo = add(
        "demo",
        cmd_demo,
        "run one of the example programs shipped with mirobot-async (default: "
        f"{DEFAULT_EXAMPLE}) on the embedded virtual Mirobot, or on --port",
    )
    demo.add_argument(
        "name", nargs="?", default=DEFAULT_EXAMPLE, metavar="NAME", help="the example to run"
    )
    demo.add_argument("--list", action="store_true", help="list the examples and exit")
    demo.add_argument("--trace", metavar="FILE.csv", help="record status samples (G-code examples)")
    demo.set_defaults(continue_on_error=False, no_check=False, file=None)
    _add_prepare_options(demo, "home")
    _add_interrupt_option(demo)

    check = add("check", commands.cmd_check, "validate a G-code program offline", talks=False)
    check.add_argument("file", metavar="FILE", help="G-code program; - reads stdin")
    check.add_argument(
        "--firmware",
        choices=gcode.FIRMWARE_PROFILES,
        default="2021",
        help="firmware profile to check against (default: 2021)",
    )
    check.add_argument(
        "--envelope",
        metavar="FILE",
        help="also check the program against this safety envelope (TOML, as run takes it), "
        "predicted from the arm at rest after homing (every joint 0): the lines it refuses, "
        "with run's reasons",
    )

    plot = add(
        "plot", commands.cmd_plot, "plot a trace: tool path (top, side), joints", talks=False
    )
    plot.add_argument("trace", metavar="TRACE.csv", help="from 'run --trace' or 'monitor --csv'")
    plot.add_argument(
        "-o", "--output", metavar="FILE.png", help="PNG to write (default: TRACE with .png)"
    )
    plot.add_argument("--title", help="title of the figure")

    ports = add(
        "ports",
        commands.cmd_ports,
        "list serial ports and probe each for a Mirobot (sends only ? and $$)",
        talks=False,
    )
    ports.add_argument(
        "devices", nargs="*", metavar="DEVICE", help="probe these (default: every port found)"
    )
    ports.add_argument(
        "--timeout",
        type=_positive_float,
        default=3.0,
        metavar="S",
        help="seconds to wait for each port's status reply (default: 3)",
    )
    ports.add_argument("--no-probe", action="store_true", help="only list, open nothing")

    # --- mirobot view / mirobot urdf ------------------------------------------------------
    view = add(
        "view",
        commands.cmd_view,
        "the arm in 3D in a browser: live status, a program's predicted path, a teach pendant "
        "(needs the view extra: pip install 'mirobot-async[view]')",
    )
    view.add_argument(
        "program", nargs="?", metavar="PROGRAM", help="G-code program to preview (and run)"
    )
    view.add_argument(
        "--listen",
        default="127.0.0.1:0",
        metavar="HOST:PORT",
        help="where to serve the page (default: 127.0.0.1 and a free port; the URL, with this "
        "run's secret, is the first line of standard output; other than loopback needs "
        "--allow-remote)",
    )
    view.add_argument(
        "--run",
        action="store_true",
        help="stream PROGRAM once a browser shows the scene (else: the Run button)",
    )
    view.add_argument(
        "--allow-remote",
        action="store_true",
        help="allow a --listen address other than loopback (anyone on that network with the "
        "printed URL, which carries this run's secret, can drive the arm)",
    )
    view.add_argument(
        "--export-dir",
        metavar="DIR",
        help="the folder the pendant's Export writes into (default: the current folder)",
    )
    view.add_argument(
        "--replay",
        metavar="FILE",
        help="scrub a run that happened, offline (no arm): a trace CSV (run --trace) or a tape "
        "(.jsonl[.gz]) with a time slider: the pose, the path so far and the events",
    )
    view.add_argument("--no-browser", action="store_true", help="do not open a browser")
    add_envelope_option(view)  # drawn as a box; every jog and streamed line is checked
    urdf = add(
        "urdf",
        commands.cmd_urdf,
        "print a URDF of the arm built from this package's kinematics (for ROS, MoveIt, viewers)",
        talks=False,
    )
    urdf.add_argument(
        "--firmware",
        choices=gcode.FIRMWARE_PROFILES,
        default="2021",
        help="geometry of this firmware profile (default: 2021)",
    )
    # --- end of mirobot view / mirobot urdf -----------------------------------------------

    # --- mcp: a Model Context Protocol server for AI agents -------------------------------
    mcp = add(
        "mcp",
        commands.cmd_mcp,
        "serve the arm to an AI agent over MCP (stdio; for Claude Desktop, Cursor...): tools "
        "status, home, move_joints, move_pose, run_program, hold, reset...; every motion is "
        "checked against the safety envelope (--envelope, else a conservative default box)",
    )
    mcp.add_argument(
        "--dry-run",
        action="store_true",
        help="with --port: run every motion tool first on a virtual twin (the embedded "
        "emulator) and only then on the arm; what fails on the twin is not sent to the arm",
    )
    add_envelope_option(mcp)
    # --- end of mcp ------------------------------------------------------------------------

    # --- replay: tapes against the emulator ----------------------------------------------
    replay = add(
        "replay",
        _replay_handler,
        "replay tapes (recordings of what an arm received and printed: the firmware's tapes, "
        "--record, mirobot doctor) against the emulator and say per tape: equal, or the first "
        "difference (bytes and instants); exit 0 all equal, 1 a difference, 2 a bad tape",
        talks=False,
    )
    replay.add_argument("tapes", nargs="+", metavar="TAPE", help="tape files (.jsonl or .jsonl.gz)")
    replay.add_argument(
        "--firmware",
        choices=gcode.FIRMWARE_PROFILES,
        help="the emulator profile to replay against (default: the family the tape names)",
    )
    replay.add_argument("--json", action="store_true", help="one JSON object per tape")
    # --- end of replay ----------------------------------------------------------------------

    # --- doctor: the first thing to run on an arm we have never seen ------------------------
    doctor = add(
        "doctor",
        _doctor_handler,
        "probe the arm without moving it (banner, ?, $$, $I, lines every firmware refuses, a "
        "zero-length move when the axes are locked), record the probe as a tape (--record FILE, "
        "default mirobot-doctor-<time>.jsonl) and say where the arm answers otherwise than the "
        "emulator's profile for its family; exit 0 no difference, 1 differences",
    )
    doctor.add_argument(
        "--motion",
        action="store_true",
        help="also home and move J1 by 10 and J2 by 5 degrees (asks first on a terminal)",
    )
    doctor.add_argument("--yes", action="store_true", help="with --motion: do not ask")
    doctor.add_argument(
        "--against",
        choices=gcode.FIRMWARE_PROFILES,
        help="compare with this emulator profile (default: the family the arm shows)",
    )
    # --- end of doctor ----------------------------------------------------------------------

    emulator = commands_parser.add_parser(
        "emulator",
        help="run the virtual Mirobot on a pty (same as mirobot-emulator; see "
        "'mirobot emulator --help')",
        add_help=False,
    )
    emulator.add_argument("arguments", nargs=argparse.REMAINDER)
    emulator.set_defaults(handler=commands.cmd_emulator)
    return parser
