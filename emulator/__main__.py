"""``mirobot-emulator`` / ``python -m mirobot_emulator``: a virtual Mirobot on a pty or TCP socket.

Prints the device path (or, with ``--listen HOST:PORT``, ``socket://HOST:PORT``) as the first
line of stdout (flushed), then serves until SIGINT or SIGTERM (exit status 0, link removed, no
traceback). Stdin is a control channel for fault injection (one command per line, answered
``ack <command>`` on stdout); EOF on stdin only stops reading it, unless
``--exit-on-stdin-eof`` (then the server stops once the commands read are answered: a parent
that dies, even by SIGKILL, leaves no emulator behind). The control command ``renew ARGS...``
makes the process what a new one started with ARGS would be (see
:data:`mirobot_emulator.server._control.RENEW`). Diagnostics go to stderr. See
:mod:`mirobot_emulator.server` for what is modelled and :mod:`mirobot_emulator._faults` for the
fault specifications and commands. With ``--bus N`` the port carries an RS485 bus of N
controllers, each with its arm (:mod:`mirobot_emulator.bus`).

Exit status: 0 after a signal or a ``close`` fault, 2 for bad arguments, 1 if the pty, the
socket or the link cannot be created.
"""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, NoReturn

if TYPE_CHECKING:
    from _typeshed import SupportsWrite

    from .server import ServerOptions

BUS_BAUDS = (4800, 9600, 38400, 57600, 115200)  # as server.options.BUS_BAUDS (imported late)

_stopping = False


def _early_stop(signum: int, frame: object) -> None:
    # A signal before the server is running (e.g. while the firmware imports numpy).
    global _stopping
    _stopping = True


class _RenewArgumentError(ValueError):
    """Arguments of the ``renew`` control command that cannot be served."""


class _RenewParser(argparse.ArgumentParser):
    """The command line's parser for ``renew``: errors raise instead of exiting the process."""

    def error(self, message: str) -> NoReturn:
        raise _RenewArgumentError(message)

    def exit(self, status: int = 0, message: str | None = None) -> NoReturn:
        raise _RenewArgumentError(message or "--help and --version are not renew options")

    def _print_message(self, message: str, file: SupportsWrite[str] | None = None) -> None:
        pass  # never on stdout: it carries the control channel's answers


def _build_parser(
    kind: type[argparse.ArgumentParser] = argparse.ArgumentParser,
) -> argparse.ArgumentParser:
    parser = kind(
        prog="mirobot-emulator",
        description="A virtual WLKATA Mirobot (firmware model) on a pseudo-terminal or a TCP "
        "socket. The first line of stdout is the device path (or socket://HOST:PORT); stdin "
        "takes fault-injection commands (drop-ok [N], corrupt-status [N], ignore-status [N], "
        "stall S, hard-limit [AXIS], reset, close, split-bytes [on|off], delay MS, "
        "time-scale X; stats, motion-ends and starvations for the server's counters; renew "
        "ARGS: become a new process started with ARGS), each answered 'ack <command>'.",
    )
    parser.add_argument(
        "--firmware",
        choices=("classic", "2021", "2024"),
        default="2021",
        help="firmware profile (default: 2021)",
    )
    parser.add_argument(
        "--time-scale",
        type=float,
        default=1.0,
        metavar="X",
        help="simulated seconds per wall second; 0 = motion completes at once (default: 1)",
    )
    parser.add_argument("--link", metavar="PATH", help="also create a symlink to the device here")
    parser.add_argument(
        "--listen",
        metavar="HOST:PORT",
        help="serve on a TCP socket instead of a pty (socket://HOST:PORT for pyserial); "
        "port 0 picks a free one; HOST defaults to 127.0.0.1; one client at a time "
        "(default where there are no ptys: 127.0.0.1:0)",
    )
    parser.add_argument(
        "--baud",
        type=int,
        metavar="N",
        help="pace input and output at N/10 bytes per second (default: full speed)",
    )
    parser.add_argument(
        "--reset-on-open",
        action="store_true",
        help="reset the firmware (banner reprinted) when a client opens the port, "
        "like an arm whose DTR line resets it",
    )
    parser.add_argument(
        "--usb-latency-ms",
        type=float,
        default=0.0,
        metavar="N",
        help="hold output until N ms old or 62 bytes, like an FTDI latency timer "
        "(default: 0 = off)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed for random faults (default: 0)")
    parser.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="SPEC",
        help="inject a fault (repeatable): drop-ok:N, corrupt-status:N, "
        "corrupt-status-rate:P, ignore-status:N, stall:AFTER_S:DURATION_S, "
        "hard-limit:AFTER_S[:AXIS], reset:AFTER_S, close:AFTER_S, split-bytes (one byte "
        "per write), delay:MS (hold every output line MS ms)",
    )
    parser.add_argument(
        "--homing-seconds",
        type=float,
        metavar="S",
        help="duration of the homing switch search (default: the firmware's)",
    )
    parser.add_argument(
        "--bus",
        type=int,
        default=0,
        metavar="N",
        help="serve an RS485 bus of N multi-function controllers (addresses 1..N), each with "
        "an arm of --firmware; lines are addressed @N... (default: one bare arm)",
    )
    parser.add_argument(
        "--bus-baud",
        type=int,
        choices=BUS_BAUDS,
        default=38400,
        metavar="{4800,9600,38400,57600,115200}",
        help="the bus's baud, which paces it (default: 38400; only with --bus)",
    )
    parser.add_argument(
        "--bus-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="how the controllers read a point the sources disagree on (repeatable), e.g. "
        "o103=number; see mirobot_emulator.bus.BusOptions (only with --bus)",
    )
    parser.add_argument(
        "--exit-on-stdin-eof",
        action="store_true",
        help="stop when stdin (the control channel) ends, after answering the commands read "
        "(a parent that dies leaves no emulator behind)",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    return parser


def _version() -> str:
    """The installed package's version (``mirobot-async`` ships the emulator too)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("mirobot-async")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree
        return "unknown (not installed)"


def _say(line: str) -> None:
    try:
        sys.stdout.write(line + "\n")
        sys.stdout.flush()
    except (BrokenPipeError, ValueError, OSError):  # nobody listens any more: keep serving
        pass


def _log(message: str) -> None:
    try:
        sys.stderr.write(f"mirobot-emulator: {message}\n")
        sys.stderr.flush()
    except (ValueError, OSError):
        pass


def _options(args: argparse.Namespace, parser: argparse.ArgumentParser) -> ServerOptions:
    from ._faults import FaultSpecError, parse_fault
    from .server import ServerOptions, parse_listen
    from .server.options import DEFAULT_LISTEN_HOST

    try:
        faults = tuple(parse_fault(spec) for spec in args.fault)
    except FaultSpecError as exc:
        parser.error(str(exc))
    if not args.time_scale >= 0 or args.time_scale == float("inf"):
        parser.error("--time-scale must be a finite number >= 0")
    if args.baud is not None and args.baud <= 0:
        parser.error("--baud must be positive")
    if not args.usb_latency_ms >= 0:
        parser.error("--usb-latency-ms must be >= 0")
    if args.homing_seconds is not None and not 0 <= args.homing_seconds < float("inf"):
        parser.error("--homing-seconds must be a finite number >= 0")
    _check_bus_arguments(args, parser)
    listen = None
    if args.listen is None and not args.link:
        from .server._pty_port import pty_available

        if not pty_available():  # e.g. Windows: TCP is the only port there is
            listen = parse_listen(f"{DEFAULT_LISTEN_HOST}:0")
    if args.listen is not None:
        if args.link:
            parser.error("--link makes a symlink to a pty: it cannot be used with --listen")
        try:
            listen = parse_listen(args.listen)
        except ValueError as exc:
            parser.error(f"--listen {exc}")
    return ServerOptions(
        firmware=args.firmware,
        time_scale=args.time_scale,
        link=args.link,
        baud=args.baud,
        reset_on_open=args.reset_on_open,
        usb_latency_ms=args.usb_latency_ms,
        seed=args.seed,
        faults=faults,
        homing_seconds=args.homing_seconds,
        listen=listen,
        bus=args.bus,
        bus_baud=args.bus_baud,
        bus_options=tuple(args.bus_option),
    )


def _check_bus_arguments(args: argparse.Namespace, parser: argparse.ArgumentParser) -> None:
    """``--bus`` and its companions: errors (exit status 2) before anything is opened."""
    if not 0 <= args.bus <= 99:
        parser.error("--bus must be 1..99 (the controllers' addresses)")
    if not args.bus:
        if args.bus_option or args.bus_baud != 38400:
            parser.error("--bus-baud and --bus-option need --bus N")
        return
    if args.baud is not None:
        parser.error("--baud cannot be used with --bus: the bus paces itself (see --bus-baud)")
    if args.reset_on_open:
        parser.error("--reset-on-open cannot be used with --bus (a reset power-cycles every node)")
    from .bus import BusOptions

    try:
        BusOptions.parse(args.bus_option)
    except ValueError as exc:
        parser.error(f"--bus-option: {exc}")


def _renew_options(argv: Sequence[str]) -> ServerOptions:
    """The options of ``renew ARGS``, parsed as the command line is; :class:`ValueError` for
    arguments that are wrong or name what only a new process can change."""
    parser = _build_parser(_RenewParser)
    args = parser.parse_args(list(argv))
    fixed = [
        name
        for name, given in (
            ("--listen", args.listen is not None),
            ("--link", bool(args.link)),
            ("--exit-on-stdin-eof", args.exit_on_stdin_eof),
        )
        if given
    ]
    if fixed:
        raise ValueError(f"{', '.join(fixed)} cannot be renewed: start a new process")
    return _options(args, parser)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``mirobot-emulator``; returns the exit status.

    SIGINT and SIGTERM never raise in here: until the port is ready they only set a flag, then
    they stop the server. Run as a program (``argv`` None), they are ignored from the moment the
    server has stopped: Python restores the default handlers during finalisation, and a signal
    arriving then (a second SIGTERM, or a SIGTERM racing a ``close`` fault) would turn exit
    status 0 into a kill.
    """
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _early_stop)
    parser = _build_parser()
    args = parser.parse_args(argv)
    options = _options(args, parser)

    from .server import EmulatorServer

    try:
        control_fd: int | None = sys.stdin.fileno() if sys.stdin is not None else None
    except (ValueError, OSError):
        control_fd = None
    server = EmulatorServer(
        options,
        on_reply=_say,
        control_fd=control_fd,
        log=_log,
        stop_on_control_eof=args.exit_on_stdin_eof,
        renew_parser=_renew_options,
    )
    try:
        try:
            path = server.open()  # the port, the firmware (numpy), the power-on banner, the link
        except OSError as exc:
            _log(f"cannot create the port: {exc}")
            return 1

        def stop(signum: int, frame: object) -> None:
            server.request_stop()

        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, stop)
        if _stopping:
            return 0
        _say(path)
        if server.serve() == "closed":
            _log("port closed (close fault); exiting")
        return 0
    finally:
        if argv is None:
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, signal.SIG_IGN)
        server.close()


if __name__ == "__main__":
    sys.exit(main())
