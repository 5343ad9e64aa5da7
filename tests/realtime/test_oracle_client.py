"""The client against the vendor's firmware itself (the oracle at ``-s 1``: real time), for the
timing rules that only real time shows: homing answers no ``?`` for ~8 s (``$HH`` ~29 s), the
pump line behind a move is answered when the move ends, a ``G4`` runs in ``Idle`` after the
planner empties."""

from __future__ import annotations

import asyncio
import time

import pytest
from waiting import wait_until

from mirobot_async import Mirobot, MirobotTimeoutError, State

pytestmark = pytest.mark.timeout(120)


async def test_home_on_the_real_firmware(oracle: str) -> None:
    async with Mirobot.connect(oracle) as arm:
        homing = asyncio.create_task(arm.home())
        try:
            await wait_until(lambda: arm.homing is not None, 30, "the homing line written")
            with pytest.raises(MirobotTimeoutError, match="homing"):
                await arm.status()  # the firmware answers no "?" during the search
            report = await homing
        finally:
            homing.cancel()
        assert report.state is State.IDLE and all(abs(j) < 0.05 for j in report.joints)
        await arm.move_joints(j1=10, speed=2000)
        assert abs((await arm.status()).joints[0] - 10) < 0.05


@pytest.mark.timeout(150)
async def test_sequential_home_on_the_real_firmware(oracle: str) -> None:
    async with Mirobot.connect(oracle) as arm:
        started = time.monotonic()
        report = await arm.home(sequential=True)
        assert time.monotonic() - started >= 29.0  # the oracle's $HH search
        assert report.state is State.IDLE and all(abs(j) < 0.05 for j in report.joints)


async def test_send_home_and_a_statuses_consumer_on_the_real_firmware(oracle: str) -> None:
    async with Mirobot.connect(oracle) as arm:
        states: list[State] = []

        async def consume() -> None:
            async for report in arm.statuses(interval=0.2):
                states.append(report.state)

        consumer = asyncio.create_task(consume())
        try:
            output = await arm.send("$H")
            assert output is not None
            report = await arm.wait_idle()
            assert all(abs(j) < 0.05 for j in report.joints), report
            after = len(states)  # the consumer is still alive after homing: it reports on
            await wait_until(
                lambda: len(states) >= after + 2 or consumer.done(), 10, "reports after homing"
            )
            assert not consumer.done(), consumer
        finally:
            consumer.cancel()
            await asyncio.gather(consumer, return_exceptions=True)
        assert State.HOME in states and State.IDLE in states, states


async def test_pump_line_right_behind_a_long_move_is_answered_when_it_ends(oracle: str) -> None:
    async with Mirobot.connect(oracle) as arm:
        await arm.unlock()
        await arm.move_joints(j1=60, speed=1000, wait=False)  # ~4 s at F1000
        started = time.monotonic()
        await arm.set_pump(1000)  # the firmware holds it until the planner is empty
        late = time.monotonic() - started
        report = await arm.status(fresh=True)
        assert report.state is State.IDLE and abs(report.joints[0] - 60) < 0.05, report
        assert report.pump_pwm == 1000
        assert late > 2.0  # really answered late: liveness checks ran meanwhile, and held
        assert arm.stats.replies_lost == 0


async def test_dwell_behind_a_move_runs_in_idle_and_is_not_given_up(oracle: str) -> None:
    async with Mirobot.connect(oracle) as arm:
        await arm.unlock()
        await arm.move_joints(j1=40, speed=1000, wait=False)
        await arm.send("G4 P3")  # 3 s of Idle after the move before its ok
        await arm.set_pump(0)
        assert arm.stats.replies_lost == 0
        report = await arm.status(fresh=True)
        assert abs(report.joints[0] - 40) < 0.05, report


@pytest.mark.timeout(150)
async def test_pump_line_behind_more_than_30_seconds_of_motion(oracle: str) -> None:
    """The old default (30 s) would have given up the pump line: it waits for the motion."""
    async with Mirobot.connect(oracle) as arm:
        await arm.unlock()
        for j1 in (150, -90, 150):  # 9 + 14 + 14 s at F1000
            await arm.move_joints(j1=j1, speed=1000, wait=False)
        await arm.set_pump(500)
        report = await arm.status(fresh=True)
        assert report.state is State.IDLE and abs(report.joints[0] - 150) < 0.05, report
        assert report.pump_pwm == 500
