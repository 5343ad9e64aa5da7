"""The arm service behind ``mirobot mcp`` (no MCP SDK in the way), on two emulators of the
pool: the arm and the dry run's virtual twin. Each emulator is read through its own control
channel (``stats``), which the service does not use."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator

import pytest

from mirobot_async import Mirobot
from mirobot_async._core.replies import State
from mirobot_async._mcp_server.service import ArmService, default_envelope, program_lines
from mirobot_async.errors import MirobotUsageError
from mirobot_async.testing import EmulatorPool, EmulatorProcess

pytestmark = pytest.mark.timeout(60)


async def lines_received(emulator: EmulatorProcess) -> int:
    words = (await emulator.control("stats")).split()
    counts = {name: value for name, _, value in (w.partition("=") for w in words if "=" in w)}
    return int(counts["lines_in"])


@pytest.fixture
async def arm_and_twin(
    mirobot_emulator_pool: EmulatorPool,
) -> AsyncIterator[tuple[ArmService, EmulatorProcess, EmulatorProcess]]:
    async with (
        mirobot_emulator_pool.lend_async("2021", 0.0) as arm_emulator,
        mirobot_emulator_pool.lend_async("2021", 0.0) as twin_emulator,
        Mirobot.connect(
            arm_emulator.url, firmware="2021", envelope=default_envelope("2021")
        ) as arm,
        Mirobot.connect(twin_emulator.url, firmware="2021") as twin,
    ):
        yield ArmService(arm, twin), arm_emulator, twin_emulator


async def test_every_motion_runs_on_the_twin_first(
    arm_and_twin: tuple[ArmService, EmulatorProcess, EmulatorProcess],
) -> None:
    service, _, twin_emulator = arm_and_twin
    await service.home()
    twin_lines = await lines_received(twin_emulator)
    moved = await service.move_joints((25, None, None, None, None, None), None, None, False)
    assert await lines_received(twin_emulator) > twin_lines
    assert moved["dry_run"].startswith("ran first on the virtual twin: ok, it ended <Idle,")
    assert moved["status"]["joints"]["j1"] == pytest.approx(25, abs=0.05)
    twin = await service.twin.status()  # type: ignore[union-attr]
    assert twin.joints[0] == pytest.approx(25, abs=0.05)  # the twin went there too
    unlocked = await service.unlock()  # not a motion: no dry run
    assert "dry_run" not in unlocked


async def test_a_failure_on_the_twin_sends_nothing_to_the_arm(
    arm_and_twin: tuple[ArmService, EmulatorProcess, EmulatorProcess],
) -> None:
    service, arm_emulator, twin_emulator = arm_and_twin
    await service.home()
    program = "M21 G90 G21\nG0 X20\n"
    checked = await service.check_program(program)  # reads the settings ($$) once
    assert checked["envelope"] == "every line is inside the safety envelope"
    await twin_emulator.control("hard-limit")  # the twin is stuck: only a reset frees it
    before = await service.status()
    sent = await lines_received(arm_emulator)
    with pytest.raises(MirobotUsageError) as refused:
        await service.run_program(program)
    assert str(refused.value).startswith(
        "refused by the dry run on the virtual twin, nothing was sent to the arm: "
    )
    assert await lines_received(arm_emulator) == sent
    assert (await service.status())["firmware_line"] == before["firmware_line"]
    assert service.running is None  # the next command may run


def test_program_lines_keep_the_numbers_of_the_text() -> None:
    text = "; header\n\nG0 X1 ; go\n(only a comment)\nG1 Y2 F100\n"
    assert program_lines(text) == [(3, "G0 X1"), (5, "G1 Y2 F100")]


async def test_hold_while_homing_is_refused_with_the_way_out(
    mirobot_emulator_pool: EmulatorPool,
) -> None:
    """The firmware ignores feed hold while it homes: hold says so (and that reset stops it)."""
    async with (
        mirobot_emulator_pool.lend_async("2021", 10.0) as emulator,
        Mirobot.connect(emulator.url, firmware="2021", envelope=default_envelope("2021")) as arm,
    ):
        service = ArmService(arm)
        homing = asyncio.ensure_future(service.home())
        try:
            deadline = asyncio.get_running_loop().time() + 10
            while (await arm.status()).state is not State.HOME:
                assert asyncio.get_running_loop().time() < deadline, "never homing"
            with pytest.raises(MirobotUsageError, match="reset \\(%\\) is the only thing"):
                await service.hold()
            homed = await homing
        finally:
            homing.cancel()
            with contextlib.suppress(BaseException):
                await homing
    assert homed["status"]["state"] == "Idle"  # homing went on, untouched


async def test_check_program_reports_problems_and_run_program_refuses_them(
    arm_and_twin: tuple[ArmService, EmulatorProcess, EmulatorProcess],
) -> None:
    service, arm_emulator, _ = arm_and_twin
    await service.home()
    program = "; Q is a letter the firmware does not know\nM21 G90 G21\nG0 X10 Q5\n"
    checked = await service.check_program(program)
    assert [problem["line"] for problem in checked["problems"]] == [3]
    assert checked["commands"] == 2 and checked["firmware"] == "2021"
    sent = await lines_received(arm_emulator)
    with pytest.raises(
        MirobotUsageError, match=r"refused, nothing was sent: 1 problem\(s\): line 3: "
    ):
        await service.run_program(program)
    assert await lines_received(arm_emulator) == sent


async def test_reset_says_the_arm_is_locked_only_when_it_is(
    arm_and_twin: tuple[ArmService, EmulatorProcess, EmulatorProcess],
) -> None:
    service, _, _ = arm_and_twin
    await service.home()
    at_rest = await service.reset()
    assert at_rest["status"]["state"] != "Alarm", at_rest
    assert "Alarm" not in at_rest["outcome"]
    assert at_rest["outcome"].endswith(f"the arm is {at_rest['status']['state']}")


def test_reset_help_does_not_promise_a_lock() -> None:
    from mirobot_async._cli.arguments import build_parser

    parser = build_parser()
    text = next(
        action.choices["reset"].format_help()  # type: ignore[index]
        for action in parser._actions
        if getattr(action, "choices", None) and "reset" in action.choices  # type: ignore[operator]
    )
    assert "locked afterwards" not in text
    assert "one at rest does not lock it" in " ".join(text.split())
