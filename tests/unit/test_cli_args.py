"""The ``mirobot`` command line without a robot: arguments, KEY=VALUE targets, offline commands,
output formatting, exit statuses (no subprocess, no emulator)."""

from __future__ import annotations

import argparse
import asyncio
import io
from pathlib import Path

import pytest

from mirobot_async._cli import (
    EXIT_FAILED,
    EXIT_OK,
    EXIT_USAGE,
    JOINT_KEYS,
    POSE_KEYS,
    CliError,
    ProgressBar,
    RichProgressBar,
    build_parser,
    commands,
    exit_status_for,
    format_status_line,
    format_status_table,
    main,
    parse_assignments,
    read_program,
)
from mirobot_async._cli.arguments import DEFAULT_MONITOR_INTERVAL
from mirobot_async._cli.programs import ProgramLine
from mirobot_async._cli.rendering import describe_failures, describe_interrupted_run, line_ranges
from mirobot_async._cli.session import background_jobs
from mirobot_async._core.replies import State, StatusReport
from mirobot_async.errors import (
    MirobotAlarmError,
    MirobotCommandError,
    MirobotConnectionError,
    MirobotLinkLostError,
    MirobotTimeoutError,
    MirobotUsageError,
)

REPORT = StatusReport(
    State.IDLE,
    (1.5, -2.25, 3.0, 0.0, -0.0, 90.0),
    12.0,
    (198.67, 0.0, 230.72, 0.0, 0.0, 0.0),
    1000,
    40,
    1,
)


# --------------------------------------------------------------------------------------------
# KEY=VALUE targets


def test_assignments_parse_numbers_case_insensitively() -> None:
    assert parse_assignments(["j1=10", "J3=-5.5", "rail=100"], JOINT_KEYS, "joint") == {
        "j1": 10.0,
        "j3": -5.5,
        "rail": 100.0,
    }
    assert parse_assignments(["x=200", "Y=0", "z=1e2", "rz=-90"], POSE_KEYS, "axis") == {
        "x": 200.0,
        "y": 0.0,
        "z": 100.0,
        "rz": -90.0,
    }


def test_assignment_aliases() -> None:
    assert parse_assignments(["d=5"], JOINT_KEYS, "joint") == {"rail": 5.0}
    assert parse_assignments(["a=1", "b=2", "c=3"], POSE_KEYS, "axis") == {
        "rx": 1.0,
        "ry": 2.0,
        "rz": 3.0,
    }


@pytest.mark.parametrize(
    ("items", "keys", "message"),
    [
        (["j7=1"], JOINT_KEYS, "unknown joint 'j7' in 'j7=1'"),
        (["x=1"], JOINT_KEYS, "unknown joint 'x'"),
        (["j1=1"], POSE_KEYS, "unknown axis 'j1'"),
        (["x=abc"], POSE_KEYS, "x=abc: 'abc' is not a number"),
        (["x="], POSE_KEYS, "is not a number"),
        (["x=nan"], POSE_KEYS, "finite"),
        (["j2=inf"], JOINT_KEYS, "finite"),
        (["j1"], JOINT_KEYS, "'j1' is not KEY=VALUE"),
        (["=5"], JOINT_KEYS, "is not KEY=VALUE"),
        (["j1=1", "J1=2"], JOINT_KEYS, "j1 is given twice"),
        ([], JOINT_KEYS, "at least one joint target"),
    ],
)
def test_bad_assignments(items: list[str], keys: tuple[str, ...], message: str) -> None:
    with pytest.raises(CliError) as info:
        parse_assignments(items, keys, "joint" if keys is JOINT_KEYS else "axis")
    assert message in str(info.value)
    assert "\n" not in str(info.value)


# --------------------------------------------------------------------------------------------
# The parser


def parse(*argv: str) -> argparse.Namespace:
    return build_parser().parse_args(list(argv))


def test_robot_commands_default_to_the_embedded_emulator() -> None:
    args = parse("status")
    assert args.handler is commands.cmd_status
    assert args.port is None
    assert args.firmware is None  # 2021 for the embedded emulator; detected with --port
    assert args.time_scale is None
    assert args.verbose == 0


def test_common_options_after_the_subcommand() -> None:
    args = parse("status", "--port", "/dev/ttyUSB0", "--firmware", "classic", "-v")
    assert (args.port, args.firmware, args.verbose) == ("/dev/ttyUSB0", "classic", 1)
    assert parse("-v", "status").verbose == 1
    assert parse("status", "--time-scale", "0").time_scale == 0.0


def test_monitor_options() -> None:
    args = parse("monitor", "--interval", "0.2", "--csv", "out.csv", "--samples", "3")
    assert (args.interval, args.csv, args.samples) == (0.2, "out.csv", 3)
    assert parse("monitor").interval == DEFAULT_MONITOR_INTERVAL


def test_move_subcommands() -> None:
    args = parse("move", "joints", "j1=10", "j2=-5", "--relative", "--speed", "1000")
    assert args.handler is commands.cmd_move_joints
    assert args.targets == ["j1=10", "j2=-5"]
    assert args.relative and args.speed == 1000.0
    assert args.prepare is None
    args = parse("move", "pose", "x=200", "--linear", "--home")
    assert args.handler is commands.cmd_move_pose
    assert args.linear and args.prepare == "home"
    assert parse("move", "pose", "x=1", "--no-home").prepare == "none"
    assert parse("move", "joints", "j1=1", "--unlock").prepare == "unlock"


def test_negative_values_are_targets_not_options() -> None:
    assert parse("move", "joints", "j1=-10").targets == ["j1=-10"]


def test_run_check_plot_pump_gripper_home() -> None:
    args = parse("run", "prog.gcode", "--trace", "t.csv", "--continue-on-error", "--unlock")
    assert (args.file, args.trace, args.continue_on_error, args.prepare) == (
        "prog.gcode",
        "t.csv",
        True,
        "unlock",
    )
    assert parse("check", "p.gcode", "--firmware", "classic").firmware == "classic"
    args = parse("plot", "t.csv", "-o", "t.png")
    assert (args.trace, args.output) == ("t.csv", "t.png")
    assert parse("pump", "blow").action == "blow"
    assert parse("gripper", "close", "--legacy").legacy
    assert parse("home", "--sequential").sequential
    assert not parse("home").sequential


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        ([], "required: COMMAND"),
        (["fly"], "invalid choice: 'fly'"),
        (["pump", "maybe"], "invalid choice: 'maybe'"),
        (["gripper"], "required: action"),
        (["move"], "required: KIND"),
        (["status", "--firmware", "2030"], "invalid choice: '2030'"),
        (["status", "--time-scale", "-1"], "must be a number >= 0"),
        (["status", "--time-scale", "fast"], "'fast' is not a number"),
        (["monitor", "--interval", "0"], "must be a number > 0"),
        (["monitor", "--samples", "x"], "is not a whole number"),
        (["move", "joints", "j1=1", "--speed", "-3"], "must be a number > 0"),
        (["move", "joints", "j1=1", "--home", "--unlock"], "not allowed with argument"),
        (["run"], "required: FILE"),
        (["status", "--bogus"], "unrecognized arguments: --bogus"),
    ],
)
def test_usage_errors_are_one_line_and_exit_2(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == EXIT_USAGE
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("mirobot: error: ")
    assert message in lines[0]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["move", "joints", "j7=1"], "unknown joint 'j7'"),
        (["move", "joints", "j1=500"], "j1=500 is outside the joint range -100..160 deg"),
        (["move", "joints", "j1=abc"], "'abc' is not a number"),
        (["move", "joints"], "at least one joint target"),
        (["move", "joints", "rail=600"], "rail=600 is outside the rail range"),
        (["move", "pose", "x=abc"], "x=abc: 'abc' is not a number"),
        (["move", "pose", "q=1"], "unknown axis 'q'"),
        (["move", "pose", "j1=3"], "unknown axis 'j1'"),
    ],
)
def test_bad_targets_exit_2_before_any_robot_is_started(
    argv: list[str],
    message: str,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def no_emulator(*args: object, **kwargs: object) -> None:
        raise AssertionError("a robot was opened for a bad argument")

    import mirobot_async.testing

    monkeypatch.setattr(mirobot_async.testing, "start_emulator", no_emulator)
    assert main(argv) == EXIT_USAGE
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("mirobot: error: ")
    assert message in lines[0]


def test_relative_joint_moves_are_not_range_checked() -> None:
    args = parse("move", "joints", "j1=300", "--relative")
    assert commands.joint_targets(args) == {"j1": 300.0}


def test_linear_pose_moves_get_a_default_speed() -> None:
    args = parse("move", "pose", "x=200", "--linear")
    commands.pose_targets(args)
    assert args.speed == 2000.0


def test_emulator_is_delegated(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[list[str]] = []

    def fake_main(argv: list[str]) -> int:
        seen.append(argv)
        return 7

    import mirobot_emulator.__main__ as emulator_main

    monkeypatch.setattr(emulator_main, "main", fake_main)
    assert main(["emulator", "--firmware", "classic", "--help"]) == 7
    assert main(["-v", "emulator"]) == 7
    assert seen == [["--firmware", "classic", "--help"], []]


def test_help_lists_every_subcommand(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for name in (
        "status",
        "monitor",
        "home",
        "unlock",
        "reset",
        "move",
        "pump",
        "gripper",
        "run",
        "check",
        "plot",
        "emulator",
    ):
        assert name in out


# --------------------------------------------------------------------------------------------
# Exit statuses


@pytest.mark.parametrize(
    ("exc", "status"),
    [
        (CliError("x"), EXIT_USAGE),
        (MirobotUsageError("x"), EXIT_USAGE),
        (MirobotConnectionError("could not open"), EXIT_USAGE),
        (MirobotLinkLostError("gone"), EXIT_FAILED),
        (MirobotCommandError("G0 X1", "Alarm lock"), EXIT_FAILED),
        (MirobotAlarmError("G0 X1", "Hard limit"), EXIT_FAILED),
        (MirobotTimeoutError("status"), EXIT_FAILED),
        (RuntimeError("boom"), EXIT_FAILED),
    ],
)
def test_exception_to_exit_status(exc: Exception, status: int) -> None:
    code, message = exit_status_for(exc, 0)
    assert code == status
    assert message is not None and "\n" not in message


# --------------------------------------------------------------------------------------------
# Offline commands through main()


def test_check_ok(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    program = tmp_path / "ok.gcode"
    program.write_text("; comment\nM21 G90\nG0 X10 Y10\n\nM3 S1000\n")
    assert main(["check", str(program)]) == EXIT_OK
    out = capsys.readouterr().out
    assert out.startswith("OK: 5 lines")


def test_check_problems(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    program = tmp_path / "bad.gcode"
    program.write_text("M21 G90\nG0 X500\nG7\nM3 S2000\n")
    assert main(["check", str(program)]) == EXIT_FAILED
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"{program}:2: J1=500 is outside -100..160"
    assert out[1].startswith(f"{program}:3: G7")
    assert out[2].startswith(f"{program}:4: S2000")


def test_check_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(tmp_path / "nope.gcode")]) == EXIT_USAGE
    assert capsys.readouterr().err == f"mirobot: error: {tmp_path / 'nope.gcode'}: no such file\n"
    assert main(["check", str(tmp_path)]) == EXIT_USAGE
    assert "is a directory" in capsys.readouterr().err


def test_check_examples_are_valid(capsys: pytest.CaptureFixture[str]) -> None:
    examples = Path(__file__).resolve().parents[2] / "examples"
    programs = sorted(examples.glob("*.gcode"))
    assert len(programs) >= 3
    for program in programs:
        for firmware in ("2021", "classic"):
            assert main(["check", str(program), "--firmware", firmware]) == EXIT_OK, program


def test_run_missing_file_exits_2(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["run", str(tmp_path / "nope.gcode")]) == EXIT_USAGE
    assert capsys.readouterr().err.endswith("nope.gcode: no such file\n")


def test_run_empty_program_exits_2(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    program = tmp_path / "empty.gcode"
    program.write_text("; nothing\n\n(nothing either)\n")
    assert main(["run", str(program)]) == EXIT_USAGE
    assert "no commands" in capsys.readouterr().err


def test_plot_bad_traces(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plot", str(tmp_path / "nope.csv")]) == EXIT_USAGE
    assert "cannot read" in capsys.readouterr().err
    bad = tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    assert main(["plot", str(bad)]) == EXIT_USAGE
    assert "missing column(s)" in capsys.readouterr().err
    garbled = tmp_path / "garbled.csv"
    garbled.write_text("timestamp,j1,j2,j3,j4,j5,j6,x,y,z\n2025-01-01T00:00:00,1,2,3,4,5,x,7,8,9\n")
    assert main(["plot", str(garbled)]) == EXIT_USAGE
    assert f"{garbled}:2: bad sample" in capsys.readouterr().err


# --------------------------------------------------------------------------------------------
# Programs and output


def test_read_program_drops_comments_and_keeps_line_numbers(tmp_path: Path) -> None:
    program = tmp_path / "p.gcode"
    program.write_text("; header\nM20  G90 ; mode\n\n(only a comment)\nG0 (inline) X1   Y2\n")
    assert [(line.number, line.text) for line in read_program(str(program))] == [
        (2, "M20 G90"),
        (5, "G0 X1 Y2"),
    ]


def test_status_table() -> None:
    table = format_status_table(REPORT).splitlines()
    assert table[0] == "state   Idle"
    assert table[1].split() == ["J1", "J2", "J3", "J4", "J5", "J6", "rail"]
    assert table[2].split() == [
        "joints",
        "1.500",
        "-2.250",
        "3.000",
        "0.000",
        "0.000",
        "90.000",
        "12.000",
    ]
    assert table[4].split()[1:4] == ["198.670", "0.000", "230.720"]
    assert "pump 1000, valve 40" in table[5]
    assert "Cartesian (M20)" in table[6]


def test_status_line() -> None:
    line = format_status_line(REPORT)
    assert "Idle" in line and "rail 12.000" in line and "pump 1000 valve 40" in line
    assert "\n" not in line


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


async def test_progress_bar_on_a_terminal_is_drawn_by_rich_in_place() -> None:
    from mirobot_async._cli.rendering import progress_bar

    out = FakeTerminal()
    bar = progress_bar(40, out)
    assert isinstance(bar, RichProgressBar)
    bar.update(10)
    assert "10/40" in out.getvalue()
    assert "\r" in out.getvalue() or "\x1b[" in out.getvalue()  # redrawn in place
    bar.update(40)
    assert "all sent, the arm is finishing its moves" in out.getvalue()
    bar.finish("done")
    bar.finish("again")  # idempotent
    text = out.getvalue()
    assert "40/40" in text and "done\n" in text
    assert "again" not in text
    assert isinstance(progress_bar(3, io.StringIO()), ProgressBar)  # not a terminal: plain


def test_progress_bar_without_a_terminal_prints_occasional_lines() -> None:
    clock = FakeClock()
    out = io.StringIO()
    bar = ProgressBar(100, out, clock=clock, width=10)
    for done in range(1, 101):
        clock.now += 0.5
        bar.update(done)
    bar.finish("stopped")
    text = out.getvalue()
    lines = text.splitlines()
    assert "\r" not in text
    assert 10 <= len(lines) <= 12  # about one per tenth, plus the first and the last
    assert lines[0].startswith("[----------]   1/100 lines   1%")
    assert lines[-1] == "[##########] 100/100 lines 100%  elapsed 50.0s  stopped"
    assert all("elapsed" in line for line in lines)


def test_progress_bar_without_a_terminal_stays_quiet_when_fast() -> None:
    clock = FakeClock()
    out = io.StringIO()
    bar = ProgressBar(1000, out, clock=clock)
    for done in range(1, 1001):
        clock.now += 0.001
        bar.update(done)
    bar.finish()
    assert 2 <= len(out.getvalue().splitlines()) <= 3  # first, maybe 1 s later, final


def test_progress_bar_eta_unknown_before_the_first_line() -> None:
    bar = ProgressBar(5, io.StringIO(), clock=FakeClock())
    assert "ETA ?" in bar.render()


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "examples/square.gcode", "--trace", "{missing}/t.csv"],
        ["monitor", "--csv", "{missing}/m.csv"],
        ["status", "--port", "{missing}/ttyUSB0"],
    ],
)
def test_unusable_files_and_ports_exit_2_before_any_robot_is_started(
    argv: list[str],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def no_emulator(*args: object, **kwargs: object) -> None:
        raise AssertionError("an emulator was started")

    import mirobot_async.testing

    monkeypatch.setattr(mirobot_async.testing, "start_emulator", no_emulator)
    monkeypatch.chdir(Path(__file__).resolve().parents[2])
    missing = tmp_path / "no-such-dir"
    assert main([arg.format(missing=missing) for arg in argv]) == EXIT_USAGE
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("mirobot: error: ")
    assert str(missing) in lines[0]


# --------------------------------------------------------------------------------------------
# run: summary of a stopped run, background jobs


def test_stopped_run_says_how_many_lines_had_already_been_sent(
    capsys: pytest.CaptureFixture[str],
) -> None:
    program = [ProgramLine(n, f"G0 X{n}") for n in (2, 3, 5, 6, 7)]
    describe_failures(program, 4, 1, 2, 1, continue_on_error=False)
    err = capsys.readouterr().err
    assert "1 line was refused; 1 of 5 acknowledged" in err
    assert (
        "stopped at line 3, but the 2 line(s) after it had already been sent (pipelined) "
        "before the refusal arrived"
    ) in err
    # Nothing in flight after the refused line: nothing to say about it.
    describe_failures(program, 2, 1, 2, 1, continue_on_error=False)
    assert "stopped at" not in capsys.readouterr().err


def test_interrupted_run_says_what_was_still_queued() -> None:
    program = [ProgramLine(n, f"G0 X{n}") for n in (2, 3, 5, 6, 7, 9, 10)]
    assert describe_interrupted_run("p.gcode", program, 5, 2) == [
        "3 line(s) sent but not executed (queued in the arm): p.gcode line 5-7",
        "2 line(s) accepted by the arm (up to line 3); the last moves among them may not "
        "have finished",
        "2 line(s) not sent: p.gcode line 9-10",
    ]
    assert describe_interrupted_run("p.gcode", program, 0, 0) == [
        "7 line(s) not sent: p.gcode line 2-3, 5-7, 9-10"
    ]
    assert line_ranges([1, 3, 5, 7, 9, 11]) == "1, 3, 5, ..., 11"


async def _fail_soon(failing: asyncio.Event) -> None:
    await asyncio.sleep(0)  # a job that fails after it has started
    failing.set()
    raise OSError("disk full")  # in the same step: the waiter on ``failing`` runs after this


async def test_background_job_failure_is_a_warning_not_the_result(
    capsys: pytest.CaptureFixture[str],
) -> None:
    failing = asyncio.Event()
    async with background_jobs(status_recording=_fail_soon(failing), nothing=None):
        await failing.wait()
    assert "warning: status recording failed: OSError: disk full" in capsys.readouterr().err


async def test_background_job_failure_does_not_replace_the_blocks_error(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(MirobotLinkLostError):
        failing = asyncio.Event()
        async with background_jobs(status_recording=_fail_soon(failing)):
            await failing.wait()
            raise MirobotLinkLostError("link lost")
    assert "warning" not in capsys.readouterr().err  # most likely the same cause: debug only


async def test_cancelling_the_caller_during_background_clean_up_propagates() -> None:
    slow_clean_up = asyncio.Event()
    job_done = False

    async def stubborn() -> None:
        nonlocal job_done
        try:
            await asyncio.sleep(10)  # a job that runs until it is cancelled
        except asyncio.CancelledError:
            slow_clean_up.set()
            await asyncio.sleep(10)  # a slow clean-up, cut short by the second cancellation
        finally:
            job_done = True

    async def body() -> str:
        async with background_jobs(job=stubborn()):
            await asyncio.sleep(0)  # a block of one loop turn: the job is still running
        return "finished"

    task = asyncio.create_task(body())
    await slow_clean_up.wait()
    task.cancel()  # e.g. a second Ctrl-C while the background jobs wind down
    with pytest.raises(asyncio.CancelledError):
        await task
    assert job_done


def test_live_view_draws_a_table_on_a_terminal_and_lines_otherwise() -> None:
    import datetime

    from mirobot_async._cli.rendering import LiveView

    when = datetime.datetime(2025, 1, 1, 12, 0, 0)
    terminal = FakeTerminal()
    with LiveView(terminal) as view:
        view.show(REPORT, when)
        view.show(REPORT, when)
    text = terminal.getvalue()
    assert "sample 2 at 12:00:00.000" in text and "rail" in text and "198.670" in text
    assert "\x1b[" in text  # drawn in place
    plain = io.StringIO()
    with LiveView(plain) as view:
        view.show(REPORT, when)
    assert plain.getvalue() == format_status_line(REPORT, when) + "\n"


def test_version_and_offline_commands_show_no_robot_flags(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from mirobot_async import __version__

    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"mirobot {__version__}"

    def help_of(*argv: str) -> str:
        with pytest.raises(SystemExit):
            main([*argv, "--help"])
        return capsys.readouterr().out

    for command in ("check", "plot", "ports"):
        text = help_of(command)
        assert "usage: mirobot " + command in text
        for flag in ("--port", "--time-scale", "--verbose", "--on-interrupt", "--home"):
            assert flag not in text, (command, flag)
    for argv in (["run"], ["move", "joints"], ["move", "pose"], ["gripper"]):
        text = help_of(*argv)
        assert "--port" in text and "--on-interrupt {hold,reset}" in text, argv
    assert "--on-interrupt" not in help_of("status")  # it does not move the arm
    home = help_of("home")  # feed hold does not stop a homing cycle: always a soft reset
    assert "--on-interrupt" not in home and "soft reset" in " ".join(home.split())
