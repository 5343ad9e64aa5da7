"""Streaming keeps a program's meaning: what is streamed ends where the same lines sent one at a
time (each after the arm stopped) end, or is refused before its first byte
(:class:`~mirobot_async.MotionChainError`). The firmware restarts a line that carries
``M20``/``M21`` from where the arm is (see :class:`~mirobot_async._core.modal.Chaining`); the
emulator models it. The vendor's firmware showed the same property (the firmware tapes of
``test_diff_chaining``)."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import TypeVar

import pytest
from chaining_programs import joints_of, programs, stepped, streamed, to_zero
from conftest import Cli, EmulatorLender
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from mirobot_async import Mirobot, MotionChainError, MotionRefusedError, StatusReport
from mirobot_async._cli.exits import EXIT_FAILED
from mirobot_async.testing import EmulatorProcess

_T = TypeVar("_T")

TIME_SCALE = 4.0
"""Fast enough for many examples, slow enough that lines are parsed while the arm moves."""
IN_PROCESS_TIME_SCALE = 100.0
"""In-process, a line reaches the firmware the instant it is written: the arm still moves while
the lines after it are parsed at this speed too (a move of a few degrees lasts milliseconds;
with the client's restart checks disabled the properties fail at 200 already)."""
STATUS_TIMEOUT = 10.0
"""Generous (the client's default is 2 s): these tests judge where the arm ends, not how fast its
replies come on a loaded host."""
STEP = 0.06
"""Two whole motor steps of the coarsest joint, in degrees (J3: 64 steps/degree)."""


async def _run(url: str, run: Callable[[Mirobot], Awaitable[_T]]) -> _T:
    async with Mirobot.connect(url, status_timeout=STATUS_TIMEOUT) as arm:
        await arm.unlock()
        return await run(arm)


@pytest.mark.parametrize("firmware", ["2021", "classic", "2024"])
def test_streamed_programs_end_where_stepped_ones_do(
    lend_emulator: EmulatorLender, firmware: str
) -> None:
    @settings(
        max_examples=25,
        deadline=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    )
    @given(program=programs(firmware))
    def check(program: list[str]) -> None:
        with lend_emulator(
            firmware, TIME_SCALE, in_process_time_scale=IN_PROCESS_TIME_SCALE
        ) as url:
            through_stream = asyncio.run(_run(url, lambda arm: streamed(arm, program)))
        # The reference: each line from rest, so the arm's speed plays no part in it.
        with lend_emulator(firmware, 0) as url:
            one_at_a_time = asyncio.run(_run(url, lambda arm: stepped(arm, program)))
        if isinstance(through_stream, MotionChainError):
            event("refused before the first byte")
            assert "G4 P0" in str(through_stream) and "once at the top" in str(through_stream)
            return
        event("streamed")
        assert not isinstance(one_at_a_time, MotionChainError)
        assert isinstance(through_stream, StatusReport), through_stream
        assert isinstance(one_at_a_time, StatusReport), one_at_a_time
        assert joints_of(through_stream) == pytest.approx(joints_of(one_at_a_time), abs=STEP)

    check()


_MOVES = st.lists(
    st.tuples(
        st.booleans(),  # Cartesian
        st.booleans(),  # relative
        st.lists(st.integers(-5, 5), min_size=3, max_size=3),
    ),
    min_size=2,
    max_size=5,
)


async def _client_moves(
    url: str, moves: list[tuple[bool, bool, list[int]]], wait: bool
) -> tuple[float, ...]:
    async with Mirobot.connect(url, status_timeout=STATUS_TIMEOUT) as arm:
        await arm.unlock()
        await to_zero(arm)
        start = await arm.status()
        for cartesian, relative, values in moves:
            if cartesian:
                x, y, z = (float(v) for v in values)
                if relative:
                    await arm.move_pose(x, y, z, relative=True, wait=wait)
                else:
                    sx, sy, sz = start.pose[:3]
                    await arm.move_pose(sx + x, sy + y, sz + z, wait=wait)
            else:
                await arm.move_joints(*values, relative=relative, wait=wait)
        return joints_of(await arm.wait_idle())


@pytest.mark.parametrize("firmware", ["2021", "classic", "2024"])
def test_the_clients_own_moves_chain_without_waiting(
    lend_emulator: EmulatorLender, firmware: str
) -> None:
    """``move_joints``/``move_pose`` with ``wait=False`` end where the same calls with
    ``wait=True`` do: the client states M20/M21 only when the mode changes (and makes the arm
    stop first when the line would read a joint still moving)."""

    @settings(
        max_examples=20,
        deadline=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    )
    @given(moves=_MOVES)
    def check(moves: list[tuple[bool, bool, list[int]]]) -> None:
        with lend_emulator(
            firmware, TIME_SCALE, in_process_time_scale=IN_PROCESS_TIME_SCALE
        ) as url:
            queued = asyncio.run(_client_moves(url, moves, wait=False))
        # The reference: each move from rest, so the arm's speed plays no part in it.
        with lend_emulator(firmware, 0) as url:
            waited = asyncio.run(_client_moves(url, moves, wait=True))
        assert queued == pytest.approx(waited, abs=STEP)

    check()


@pytest.mark.mirobot_emulator(time_scale=TIME_SCALE)
async def test_relative_move_after_a_queued_one_adds_to_its_end(ready_arm: Mirobot) -> None:
    """The issue's case, in smaller moves: ``move_joints(j1=-10, wait=False)`` then
    ``move_joints(j1=15, relative=True, wait=False)`` ends at J1 = 5 (with M21 on the second
    line the firmware would measure it from where the arm is: 15, as the issue's -40 then +60
    ended at 60, not 20)."""
    arm = ready_arm
    await arm.move_joints(j1=-10, wait=False)
    await arm.move_joints(j1=15, relative=True, wait=False)
    report = await arm.wait_idle()
    assert report.joints[0] == pytest.approx(5, abs=STEP)


@pytest.mark.mirobot_emulator(time_scale=TIME_SCALE)
async def test_a_list_with_repeated_mode_words_is_refused_before_its_first_byte(
    ready_arm: Mirobot,
) -> None:
    arm = ready_arm
    sent = arm.stats.lines_sent
    result = await arm.stream(["M21 G91 G0 X1 F2000"] * 8)
    assert result.sent == 0 and arm.stats.lines_sent == sent
    assert result.stopped and not result.ok
    error = result.errors[0].error
    assert isinstance(error, MotionChainError)
    assert result.errors[0].number == 2
    assert error.line == "M21 G91 G0 X1 F2000"
    assert "State M21 once at the top" in str(error)
    # stated once, the same moves chain: 8 degrees
    result = await arm.stream(["M21 G91 G0 X1 F2000", *["G0 X1"] * 7], wait=True)
    assert result.ok
    assert (await arm.wait_idle()).joints[0] == pytest.approx(8, abs=STEP)


@pytest.mark.mirobot_emulator(time_scale=TIME_SCALE)
async def test_a_generator_is_refused_at_the_line(ready_arm: Mirobot) -> None:
    """A lazy input cannot be judged whole: the line is refused as the stream reaches it
    (nothing of it written; the stream stops there)."""
    arm = ready_arm
    result = await arm.stream(line for line in ["M21 G91 G0 X1 F2000"] * 3)
    assert result.sent == 1 and result.stopped
    assert isinstance(result.errors[0].error, MotionChainError)
    assert result.errors[0].number == 2


@pytest.mark.mirobot_emulator(time_scale=TIME_SCALE)
async def test_send_refuses_a_mode_word_while_the_arm_may_move(ready_arm: Mirobot) -> None:
    arm = ready_arm
    await arm.send("M21 G91 G0 X5 F2000")
    with pytest.raises(MotionChainError, match="J1 may still be moving"):
        await arm.send("M21 G91 G0 X5 F2000")
    await arm.send("G0 X5")  # chains without the mode word
    await arm.wait_idle()
    await arm.send("M21 G91 G0 X5")  # at rest: the restart is where the arm is
    assert (await arm.wait_idle()).joints[0] == pytest.approx(15, abs=STEP)


@pytest.mark.mirobot_emulator(firmware="classic", time_scale=0)
async def test_a_line_reading_where_a_refused_line_left_the_parser_is_refused(
    emu: EmulatorProcess,
) -> None:
    """A refused motion line moves the firmware's parser, not the arm (oracle: locked
    ``M21 G91 X10``, ``M50``, ``G91 X1`` ends at J1 10.999): a line that reads the parser
    there is refused before its first byte; restating the mode restarts from the arm."""
    async with Mirobot.connect(emu.url) as arm:  # locked: power-on
        with pytest.raises(MotionRefusedError, match="locked"):
            await arm.send("M21 G91 X10")
        await arm.send("M50")
        sent = arm.stats.lines_sent
        with pytest.raises(MotionChainError, match="refused line 'M21 G91 X10'"):
            await arm.send("G91 X1")
        assert arm.stats.lines_sent == sent
        await arm.send("M21 G91 X1")
        assert (await arm.wait_idle()).joints[0] == pytest.approx(1, abs=STEP)


def test_check_reports_the_line_and_the_fix(cli: Cli, tmp_path: Path) -> None:
    program = tmp_path / "steps.gcode"
    program.write_text("M21 G91 G0 X1 F2000\n" * 3)
    proc = cli("check", str(program), "--firmware", "classic")
    assert proc.returncode == EXIT_FAILED
    assert f"{program}:2: M21 makes the firmware restart this line" in proc.stdout
    assert "State M21 once at the top" in proc.stdout
    assert f"{program}:3:" in proc.stdout
    program.write_text("M21 G91 G0 X1 F2000\n" + "G0 X1\n" * 2)
    assert cli("check", str(program), "--firmware", "classic").returncode == 0


@pytest.mark.mirobot_emulator(time_scale=TIME_SCALE)
def test_run_refuses_the_program_before_its_first_byte(
    cli: Cli, tmp_path: Path, emu: EmulatorProcess
) -> None:
    program = tmp_path / "steps.gcode"
    program.write_text("M21 G91 G0 X1 F2000\n" * 3)
    proc = cli("run", str(program), "--port", emu.url)
    assert proc.returncode != 0
    assert f"{program}:2: M21 G91 G0 X1 F2000: M21 makes the firmware restart" in proc.stderr
    assert "nothing was sent" in proc.stderr


@pytest.mark.mirobot_emulator(time_scale=TIME_SCALE)
async def test_the_envelope_never_predicts_a_restarted_line(emu: EmulatorProcess) -> None:
    """The envelope's prediction assumes each line continues where the one before ends: a line
    the firmware would restart from the moving arm is refused even with ``validate=False``;
    sent unchecked, the prediction is dropped and the position read again."""
    from mirobot_async._safety.envelope import Envelope

    async with Mirobot.connect(emu.url, envelope=Envelope(joints={1: (-60, 60)})) as arm:
        await arm.unlock()
        await arm.send("G21")
        await arm.send("M21 G91 G0 X5 F2000")
        with pytest.raises(MotionChainError, match="refused by the safety envelope"):
            await arm.send("M21 G91 G0 X5", validate=False)
        await arm.send("M21 G91 G0 X5", validate=False, check_envelope=False)
        report = await arm.wait_idle()
        # the client follows the arm, not its own stepped arithmetic (5 + 5 = 10)
        moved = await arm.move_joints(j1=1, relative=True)
        assert moved is not None
        assert moved.joints[0] == pytest.approx(report.joints[0] + 1, abs=STEP)


PROFILE_DEPENDENT = [
    "M20 G90 G0 X198.67 Y0 Z230.72 A0 B0 C0",
    "M20 G90 G1 F2000 X198.67 Y0 Z230.72 A0 B0 C0",
    "M20 G90 G1 F2000 X198.67 Y0 Z230.72 A0 B0 C0",
]
"""Restarted on the 2021 firmware (its M20 G1 path starts from the parser's pose), not on classic
(a whole pose: the same end either way)."""


@pytest.mark.mirobot_emulator(time_scale=TIME_SCALE)
async def test_a_list_judged_differently_per_profile_learns_the_profile_first(
    ready_arm: Mirobot, profile: str
) -> None:
    """The client does not know the firmware yet: a list that only one profile would refuse is
    judged once the profile is learnt, so it is refused before its first byte (2021) or sent
    whole (classic), never cut after a byte."""
    result = await ready_arm.stream(PROFILE_DEPENDENT)
    if profile != "classic":
        assert result.sent == 0 and result.stopped, result
        assert isinstance(result.errors[0].error, MotionChainError)
    else:
        assert result.ok and result.sent == 3, result
