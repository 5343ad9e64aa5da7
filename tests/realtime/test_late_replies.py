"""Lines the firmware answers late, at the arm's own speed (emulator ``--time-scale 1``, both
profiles): a ``G4`` runs only once the planner is empty and the arm reports ``Idle`` meanwhile;
a line waits for planner room behind long moves; a held arm answers nothing queued; the 2021
``$M`` is answered when its move is queued. None of them may be taken for a lost reply."""

from __future__ import annotations

import asyncio
import contextlib

import pytest

from mirobot_async import Mirobot, State


@pytest.fixture
async def ready(arm: Mirobot) -> Mirobot:
    await arm.unlock()
    return arm


async def test_a_long_dwell_behind_a_move_is_not_given_up(ready: Mirobot, profile: str) -> None:
    await ready.move_joints(j1=30, speed=1000, wait=False)  # ~2 s
    await ready.send("G4 P4")  # then 4 s of Idle before its ok
    await ready.move_joints(j1=0, speed=2000)
    assert ready.stats.replies_lost == 0


async def test_a_line_waits_for_planner_room_behind_slow_moves(
    ready: Mirobot, profile: str
) -> None:
    """20 short slow moves: the last ones wait seconds for room in the planner."""
    lines = [f"M21 G90 G1 X{(i % 2) * 3} F600" for i in range(20)]
    result = await ready.stream(lines, wait=True)
    assert result.ok, result
    assert ready.stats.replies_lost == 0


async def test_a_line_sent_to_a_held_arm_waits(ready: Mirobot, profile: str) -> None:
    await ready.move_joints(j1=60, speed=600, wait=False)  # 6 s
    queued = [asyncio.create_task(ready.move_joints(j1=0, speed=600, wait=False))]
    for i in range(16):  # fill the planner, so the next line waits for room (each line moves:
        # a line whose target rounds to the steps already planned makes no block, as on GRBL)
        target = 1 + i % 2
        queued.append(asyncio.create_task(ready.move_joints(j1=target, speed=600, wait=False)))
    try:
        async with contextlib.aclosing(ready.statuses(interval=0.05)) as reports:
            async for report in reports:
                if report.joints[0] > 5:  # well under way
                    break
        report = await ready.hold()
        assert report.state is State.HOLD
        await asyncio.sleep(3)  # three liveness intervals of a held arm, lines waiting
        assert (await ready.status(fresh=True)).state is State.HOLD
        assert not all(task.done() for task in queued)  # some still wait for planner room
        await ready.resume()
        async with asyncio.timeout(60):
            await asyncio.gather(*queued)
    finally:
        for task in queued:
            task.cancel()
        with contextlib.suppress(BaseException):
            await asyncio.gather(*queued, return_exceptions=True)
    assert ready.stats.replies_lost == 0


async def test_hold_returns_once_the_arm_stands(ready: Mirobot, profile: str) -> None:
    """``Hold`` is reported from the first moment of braking; hold() waits for the stop."""
    await ready.move_joints(j1=60, speed=2400, wait=False)  # 40 deg/s: braking takes a while
    async with contextlib.aclosing(ready.statuses(interval=0.05)) as reports:
        async for report in reports:
            if report.joints[0] > 10:  # at full speed
                break
    held = await ready.hold()
    assert held.state is State.HOLD
    after = await ready.status(fresh=True)
    assert after.state is State.HOLD
    assert after.joints == held.joints, (held.joints, after.joints)  # it had stopped
    await ready.resume()
    assert (await ready.wait_idle()).joints[0] == pytest.approx(60, abs=0.05)


@pytest.mark.parametrize("profile", ["2021"])
async def test_the_2021_zero_move_behind_a_long_move(ready: Mirobot, profile: str) -> None:
    await ready.move_joints(j1=40, j2=20, speed=1000, wait=False)
    await ready.send("$M")  # a "$" line: written once the move is answered, then queued
    report = await ready.wait_idle()
    assert all(abs(j) < 0.05 for j in report.joints), report
    assert ready.stats.replies_lost == 0
