"""A remembered alarm is cleared by the robot's ``ok`` to a line that clears it, whichever call
sent the line: ``send()``, a stream, or a ``$H...`` variant the firmware homes for.

The fact is decided once, from the line's one parse (``ParsedLine.clears_alarm``), when its reply
comes; the client then sends motion again and the robot runs it.
"""

from __future__ import annotations

import pytest

from mirobot_async import Mirobot, State
from mirobot_async._core.line import parse_line

pytestmark = pytest.mark.mirobot_emulator(time_scale=50)  # the reset lands in a 1.8 s move


async def _remembered_alarm(arm: Mirobot) -> None:
    """Reset the robot during a long move: ``ALARM: Abort during cycle``, remembered."""
    await arm.move_joints(j1=150, speed=100, wait=False)  # 90 s of motion at time scale 1
    await arm.reset()
    assert arm.alarm == "Abort during cycle"
    assert (await arm.status()).state is State.ALARM


async def _moves_again(arm: Mirobot) -> None:
    assert arm.alarm is None
    report = await arm.move_joints(j1=5, speed=2000, wait=True)
    assert report is not None and report.state is State.IDLE


async def test_a_streamed_unlock_clears_the_remembered_alarm(ready_arm: Mirobot) -> None:
    arm = ready_arm
    await _remembered_alarm(arm)
    result = await arm.stream(["$X"])
    assert not result.errors
    assert (await arm.status()).state is not State.ALARM
    await _moves_again(arm)


async def test_a_streamed_m50_clears_the_remembered_alarm(ready_arm: Mirobot) -> None:
    arm = ready_arm
    await _remembered_alarm(arm)
    await arm.stream(["$X", "M50"])
    await _moves_again(arm)


async def test_an_undocumented_homing_variant_that_homes_clears_the_alarm(
    ready_arm: Mirobot,
) -> None:
    arm = ready_arm
    await _remembered_alarm(arm)
    await arm.send("$H8", validate=False)  # the firmware homes for it (oracle), answers ok
    await _moves_again(arm)


def test_which_lines_clear_an_alarm_is_read_from_the_one_parse() -> None:
    clearing = ["$X", "$x", "$H", "$HH", "$H0", "$H7", "$HE", "$H8", "$h 1", "M50", "m050"]
    for line in clearing:
        assert parse_line(line).clears_alarm, line
    for line in ["$$", "$M", "M5", "M3 S50", "G0 X50", "(M50)", "$50=1", "M50 X", "$10=99"]:
        assert not parse_line(line).clears_alarm, line
