"""One function per ``mirobot`` subcommand: ``cmd_*(args) -> exit status`` (async when it talks
to an arm). Arguments are checked before a robot is opened; commands that move the arm run the
pre-flight check and stop safely when interrupted (:mod:`mirobot_async._cli.session`)."""

from __future__ import annotations

import argparse
import contextlib
import datetime
import importlib
import os
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, Final

from mirobot_async._cli.exits import EXIT_FAILED, EXIT_OK, CliError, RobotNotReadyError, note
from mirobot_async._cli.plotting import TraceError, TraceWriter
from mirobot_async._cli.programs import (
    ProgramLine,
    open_trace,
    program_name,
    program_of,
    program_problems,
    read_lines,
    read_program,
)
from mirobot_async._cli.rendering import (
    LiveView,
    describe_failures,
    describe_interrupted_run,
    format_status_table,
    progress_bar,
)
from mirobot_async._cli.session import (
    HOMING_INTERRUPT,
    background_jobs,
    envelope_of,
    firmware_of,
    open_robot,
    preflight,
    prepare,
    refuse_if_locked,
    sampling,
    start_modes,
    stop_safely,
    time_scale_of,
)
from mirobot_async._cli.targets import JOINT_KEYS, POSE_KEYS, parse_assignments
from mirobot_async._cli.watching import watched
from mirobot_async._core import gcode
from mirobot_async._core.replies import State
from mirobot_async.errors import (
    MirobotAlarmError,
    MirobotCommandError,
    MirobotError,
    MirobotTimeoutError,
)

if TYPE_CHECKING:
    from mirobot_async._client.client import Mirobot, StreamResult
    from mirobot_async._safety.envelope import Envelope

__all__ = [
    "JOINT_KEYS",
    "POSE_KEYS",
    "cmd_check",
    "cmd_emulator",
    "cmd_gripper",
    "cmd_home",
    "cmd_mcp",
    "cmd_monitor",
    "cmd_move_joints",
    "cmd_move_pose",
    "cmd_plot",
    "cmd_ports",
    "cmd_pump",
    "cmd_reset",
    "cmd_run",
    "cmd_status",
    "cmd_unlock",
    "cmd_urdf",
    "cmd_view",
    "emulator_main",
    "joint_targets",
    "pose_targets",
    "trace_interval",
]

TRACE_ROBOT_INTERVAL: Final = 0.05
"""``run --trace`` samples the status about every 50 ms of the robot's time."""
MIN_TRACE_INTERVAL: Final = 0.004
"""... but not more often than this in wall time (a fast virtual arm is sampled back-to-back)."""

_PUMP_PWM: Final = {"on": gcode.PUMP_SUCK, "blow": gcode.PUMP_BLOW, "off": gcode.PUMP_OFF}


def trace_interval(time_scale: float | None) -> float:
    """Wall seconds between trace samples: :data:`TRACE_ROBOT_INTERVAL` of robot time."""
    if not time_scale:
        return TRACE_ROBOT_INTERVAL
    return max(MIN_TRACE_INTERVAL, TRACE_ROBOT_INTERVAL / time_scale)


async def _show_final_status(arm: Mirobot) -> None:
    print(format_status_table(await arm.status()), flush=True)


async def cmd_status(args: argparse.Namespace) -> int:
    """``mirobot status``: one status report as a table."""
    async with open_robot(args) as arm:
        report = await arm.status()
    print(format_status_table(report), flush=True)
    if report.state is State.ALARM and args.port is not None:
        note("the arm is in Alarm (locked): 'mirobot home' or 'mirobot unlock' releases it")
    return EXIT_OK


async def cmd_monitor(args: argparse.Namespace) -> int:
    """``mirobot monitor``: status samples until Ctrl-C (or ``--samples N``).

    An arm that does not answer for a while (the firmware answers no ``?`` while it searches its
    homing switches, 8-30 s) is waited for and shown as silent, probably homing (also when it
    is homing as the monitor opens the port); its first report after the search shows ``Home``.
    A lost link ends the command.
    """
    with open_trace(args.csv, append=True, time_scale=time_scale_of(args)) as trace:
        try:
            with LiveView(sys.stdout) as view:
                async with (
                    open_robot(args, watch_silent=True) as arm,
                    watched(arm, args, wait_for_page=False),
                ):
                    while args.samples is None or view.samples < args.samples:
                        try:
                            async with sampling(arm, args.interval) as statuses:
                                async for report in statuses:
                                    when = datetime.datetime.now().astimezone()
                                    view.show(report, when)
                                    if trace is not None:
                                        trace.write(report, when)
                                    if args.samples is not None and view.samples >= args.samples:
                                        break
                        except MirobotTimeoutError as err:
                            note(f"{err}; still waiting (is the arm homing?)")
                            view.show_silence(datetime.datetime.now().astimezone())
        finally:
            if trace is not None and trace.rows:
                note(f"{trace.rows} samples written to {trace.path}")
    return EXIT_OK


async def cmd_home(args: argparse.Namespace) -> int:
    """``mirobot home [--sequential]``."""
    async with open_robot(args) as arm:
        async with stop_safely(arm, HOMING_INTERRUPT):
            await arm.home(sequential=args.sequential)
        await _show_final_status(arm)
    return EXIT_OK


async def cmd_unlock(args: argparse.Namespace) -> int:
    """``mirobot unlock``."""
    async with open_robot(args) as arm:
        await arm.unlock()
        await _show_final_status(arm)
    return EXIT_OK


async def cmd_reset(args: argparse.Namespace) -> int:
    """``mirobot reset``: soft reset (``%``); the firmware reprints its banner."""
    async with open_robot(args) as arm:
        await arm.reset()
        await _show_final_status(arm)
    return EXIT_OK


def _values(targets: dict[str, float], keys: Sequence[str]) -> list[float | None]:
    """The targets in ``keys`` order, ``None`` for the ones not given (they stay)."""
    return [targets.get(key) for key in keys]


def joint_targets(args: argparse.Namespace) -> dict[str, float]:
    """The ``move joints`` targets, checked (values and ranges) before anything is started:
    :class:`CliError` / :class:`MirobotUsageError`, exit status 2."""
    targets = parse_assignments(args.targets, JOINT_KEYS, "joint")
    gcode.move_joints(
        *_values(targets, JOINT_KEYS),
        speed=args.speed,
        relative=args.relative,
        firmware=firmware_of(args),
    )
    return targets


def pose_targets(args: argparse.Namespace) -> dict[str, float]:
    """The ``move pose`` targets, checked before anything is started (``--linear`` without
    ``--speed`` gets 2000 mm/min, set in ``args``)."""
    targets = parse_assignments(args.targets, POSE_KEYS, "axis")
    if args.linear and args.speed is None:
        args.speed = 2000.0
    gcode.move_pose(
        *_values(targets, POSE_KEYS), speed=args.speed, linear=args.linear, relative=args.relative
    )
    return targets


async def cmd_move_joints(args: argparse.Namespace) -> int:
    """``mirobot move joints j1=.. [--relative] [--speed]``."""
    targets = joint_targets(args)
    async with open_robot(args) as arm:
        await prepare(arm, args)
        await preflight(arm)
        async with stop_safely(arm, args.on_interrupt):
            await arm.move_joints(
                *_values(targets, JOINT_KEYS), speed=args.speed, relative=args.relative
            )
        await _show_final_status(arm)
    return EXIT_OK


async def cmd_move_pose(args: argparse.Namespace) -> int:
    """``mirobot move pose x=.. [--linear] [--relative] [--speed]``."""
    targets = pose_targets(args)
    async with open_robot(args) as arm:
        await prepare(arm, args)
        await preflight(arm)
        async with stop_safely(arm, args.on_interrupt):
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
    async with open_robot(args) as arm:
        await prepare(arm, args)
        await arm.set_pump(_PUMP_PWM[args.action])
        await _show_final_status(arm)
    return EXIT_OK


async def cmd_gripper(args: argparse.Namespace) -> int:
    """``mirobot gripper open|close [--legacy]``."""
    async with open_robot(args) as arm:
        await prepare(arm, args)
        async with stop_safely(arm, args.on_interrupt):
            if args.action == "close":
                await arm.gripper_close(legacy=args.legacy)
            else:
                await arm.gripper_open(legacy=args.legacy)
        await _show_final_status(arm)
    return EXIT_OK


async def _record(arm: Mirobot, trace: TraceWriter, interval: float) -> None:
    """Append status samples to ``trace`` until cancelled."""
    async with sampling(arm, interval) as statuses:
        async for report in statuses:
            trace.write(report)


def _failure_words(err: MirobotError) -> str:
    """What the firmware said (its own words) or, for other errors, the error message."""
    if isinstance(err, MirobotCommandError) and err.text:
        return err.text
    return str(err)


async def cmd_run(args: argparse.Namespace) -> int:
    """``mirobot run FILE`` (``-``: standard input): pre-flight, then stream the program with a
    progress bar; final status at the end; Ctrl-C holds the arm."""
    name = program_name(args.file)
    program = read_program(args.file)
    if not program:
        raise CliError(f"{name}: no commands in the {'input' if args.file == '-' else 'file'}")
    scale = time_scale_of(args)
    with open_trace(args.trace, append=False, time_scale=scale) as trace:
        async with open_robot(args) as arm, watched(arm, args, wait_for_page=True):
            if not args.no_check:
                await _check_before_running(arm, args, name, program)
            else:
                await _warn_unchecked(arm, args, name, program)
            await prepare(arm, args)
            before = await preflight(arm, probe_lock=False)
            # the envelope is no part of check: with --no-check too, a program it refuses is
            # refused whole before its first byte (never half run)
            await check_envelope_before_running(arm, name, program)
            await refuse_if_locked(arm)  # writes its probe: after the read-only checks
            if trace is not None:
                trace.write(before)  # the start of the path, before the first move
            result = await _stream_program(arm, args, name, program, trace, scale)
            for failed in result.errors:
                line = program[failed.number - 1]
                words = "failed" if failed.error is None else _failure_words(failed.error)
                print(f"{name}:{line.number}: {line.text}: {words}", file=sys.stderr)
            final = await arm.status()
            if trace is not None:
                trace.write(final)
            print(format_status_table(final), flush=True)
    if trace is not None:
        note(f"{trace.rows} status samples written to {trace.path}")
    if result.errors:
        describe_failures(
            program,
            result.sent,
            result.acknowledged,
            result.errors[0].number,
            len(result.errors),
            continue_on_error=args.continue_on_error,
        )
        return EXIT_FAILED
    return EXIT_OK


async def _warn_unchecked(
    arm: Mirobot, args: argparse.Namespace, name: str, program: list[ProgramLine]
) -> None:
    """``--no-check``: the lines ``check`` flags are said on stderr and sent all the same (the
    stream does not validate them either: the run never stops half-way at one)."""
    firmware = args.firmware or arm.firmware or "2021"
    for line, message in program_problems(program, firmware, start_modes(args)):
        note(f"warning: {name}:{line.number}: {line.text}: {message} (sent anyway: --no-check)")


async def _check_before_running(
    arm: Mirobot, args: argparse.Namespace, name: str, program: list[ProgramLine]
) -> None:
    """The whole program through the validation ``check`` uses
    (:mod:`mirobot_async._core.validation`, the arm's firmware profile, from the modes the
    program will start from: after ``--home`` the feed rate is 0) before anything is sent:
    problems as ``FILE:LINE: message`` on stderr and :class:`RobotNotReadyError` (exit 1), so a
    program never stops half-way through at a line the check would have refused. The firmware
    profile is asked (``$$``, read-only) only when it is unknown and the profiles disagree about
    the program."""
    firmware = args.firmware or arm.firmware
    start = start_modes(args)  # after --home the feed rate is 0: a G1 needs its F
    if firmware is None:  # a port whose profile is not known yet: ask ($$) only if it matters
        if not any(program_problems(program, p, start) for p in gcode.FIRMWARE_PROFILES):
            return
        firmware = await arm.detect_firmware()
    problems = program_problems(program, firmware, start)
    if not problems:
        return
    for line, message in problems:
        print(f"{name}:{line.number}: {line.text}: {message}", file=sys.stderr)
    count = len(problems)
    raise RobotNotReadyError(
        f"{count} problem{'s' if count != 1 else ''} in {name} (firmware {firmware}): nothing "
        "was sent (--no-check sends it anyway)"
    )


# --- the envelope's check of a whole program (--envelope) ---------------------------------------


async def check_envelope_before_running(
    arm: Mirobot, name: str, program: list[ProgramLine]
) -> None:
    """With a safety envelope (``--envelope``), the whole program is predicted from where the
    arm stands before anything is sent: a line the envelope refuses is ``FILE:LINE: text:
    why`` on stderr and :class:`RobotNotReadyError` (exit 1), so that the program does not stop
    half-way at that line. Without an envelope, nothing to do."""
    from mirobot_async._client.guard import PathRefused

    if arm.envelope is None:
        return
    try:
        await arm.preview_lines([line.text for line in program])
    except PathRefused as err:
        line = program[err.index]
        print(f"{name}:{line.number}: {line.text}: {err}", file=sys.stderr)
        raise RobotNotReadyError(
            f"{name} leaves the safety envelope at line {line.number}: nothing was sent"
        ) from None


def envelope_refusals(
    program: list[ProgramLine], envelope: Envelope, firmware: str
) -> list[tuple[ProgramLine, str]]:
    """The lines of ``program`` the envelope refuses, offline (``check --envelope``): predicted
    as ``mirobot view`` draws the program, from the arm at rest after homing (every joint 0,
    power-on modes; ``run`` predicts from where the arm stands), with the reasons ``run``'s
    check gives."""
    from mirobot_async._view.preview import preview_program

    preview = preview_program([line.text for line in program], firmware=firmware, envelope=envelope)
    return [(program[flag.number - 1], flag.message) for flag in preview.flagged]


# --- end of the envelope's check --------------------------------------------------------------


async def _stream_program(
    arm: Mirobot,
    args: argparse.Namespace,
    name: str,
    program: list[ProgramLine],
    trace: TraceWriter | None,
    scale: float | None,
) -> StreamResult:
    """Stream ``program`` with the progress bar, the trace recorder and the safe stop."""
    progress = progress_bar(len(program), sys.stderr)
    recorder = None if trace is None else _record(arm, trace, trace_interval(scale))
    stream = arm.stream(
        [line.text for line in program],
        on_progress=lambda line: progress.update(line.number),
        continue_on_error=args.continue_on_error,
        validate=not args.no_check,  # --no-check sends what check flags (said before)
    )

    def queued() -> list[str]:
        progress.finish("interrupted")
        return describe_interrupted_run(
            name, program, stream.result.sent, stream.result.acknowledged
        )

    async with background_jobs(progress_bar=progress.tick(), status_recording=recorder):
        try:
            async with stop_safely(arm, args.on_interrupt, queued):
                result = await stream.run()
                with contextlib.suppress(MirobotAlarmError):  # the status shows the alarm
                    await arm.wait_idle()
        except BaseException:
            progress.finish("stopped")
            raise
        if not result.errors:
            progress.finish("done")
        else:
            progress.finish("done, with errors" if args.continue_on_error else "stopped")
    return result


def cmd_check(args: argparse.Namespace) -> int:
    """``mirobot check FILE``: offline validation, problems as ``FILE:LINE: message``; with
    ``--envelope FILE`` also the lines the envelope refuses, as ``run`` says them."""
    name = program_name(args.file)
    lines = read_lines(args.file)
    program = program_of(lines)
    envelope = envelope_of(args)  # a bad file: a usage error before anything is judged
    problems = program_problems(program, args.firmware)
    for line, message in problems:
        print(f"{name}:{line.number}: {message}")
    refused: list[tuple[ProgramLine, str]] = []
    if envelope is not None:
        flagged = {line.number for line, _ in problems}
        refused = [
            (line, why)
            for line, why in envelope_refusals(program, envelope, args.firmware)
            if line.number not in flagged
        ]
    for line, why in refused:
        print(f"{name}:{line.number}: {line.text}: {why}")
    if refused:
        note(f"{name} leaves the safety envelope at line {refused[0][0].number}")
    if problems or refused:
        count = len(problems) + len(refused)
        note(f"{count} problem{'s' if count != 1 else ''} in {name}")
        return EXIT_FAILED
    print(f"OK: {len(lines)} lines ({len(program)} commands, firmware {args.firmware})")
    return EXIT_OK


def cmd_plot(args: argparse.Namespace) -> int:
    """``mirobot plot TRACE.csv -o FILE.png``."""
    from mirobot_async._cli.plotting import PLOT_SIZE_PX, plot_trace, read_trace

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


def cmd_ports(args: argparse.Namespace) -> int:
    """``mirobot ports [DEVICE ...]``: serial ports with VID:PID, description and a probe's
    verdict. Exit status 0 when a Mirobot answered (or with ``--no-probe``), else 1."""
    from mirobot_async._cli.ports import describe_ports

    found = describe_ports(list(args.devices), probe=not args.no_probe, timeout=args.timeout)
    if not found:
        note("no serial ports found (is the arm plugged in? name a device to probe it)")
        return EXIT_FAILED
    rows = [("DEVICE", "VID:PID", "DESCRIPTION", "VERDICT")]
    rows += [(p.device, p.vid_pid, p.description, p.verdict) for p in found]
    widths = [max(len(row[column]) for row in rows) for column in range(3)]
    for row in rows:
        cells = [text.ljust(width) for text, width in zip(row[:3], widths, strict=True)]
        print("  ".join([*cells, row[3]]))
    if args.no_probe or any(p.is_mirobot for p in found):
        return EXIT_OK
    return EXIT_FAILED


# --- mirobot view / mirobot urdf ----------------------------------------------------------


async def cmd_view(args: argparse.Namespace) -> int:
    """``mirobot view [PROGRAM]``: serve the 3D view and teach pendant until Ctrl-C (the view
    extra is imported here, so the other commands never need it)."""
    from mirobot_async._view.command import serve_view

    return await serve_view(args)


def cmd_urdf(args: argparse.Namespace) -> int:
    """``mirobot urdf [--firmware]``: the URDF on standard output (no viser needed)."""
    from mirobot_async._urdf import build_urdf

    sys.stdout.write(build_urdf(args.firmware))
    sys.stdout.flush()
    return EXIT_OK


# --- end of mirobot view / mirobot urdf ---------------------------------------------------


# --- mcp -----------------------------------------------------------------------------------


async def cmd_mcp(args: argparse.Namespace) -> int:
    """``mirobot mcp``: a Model Context Protocol server over stdio (needs the ``mcp`` extra)."""
    from mirobot_async._mcp_server import serve

    return await serve(args)


# --- end of mcp ----------------------------------------------------------------------------


def cmd_emulator(args: argparse.Namespace) -> int:
    """``mirobot emulator ...``: the ``mirobot-emulator`` command (normally dispatched by
    :func:`~mirobot_async._cli.main` before argparse sees the arguments)."""
    return emulator_main(args.arguments)


def emulator_main(argv: Sequence[str]) -> int:
    """Run ``mirobot-emulator ARGV`` in this process; returns its exit status."""
    # Imported by name: the emulator is a separate top-level package.
    emulator = importlib.import_module("mirobot_emulator.__main__")
    status: int = emulator.main(list(argv))
    return status
