"""Hold to jog's motion (``mirobot view``'s :class:`HoldJog`, without the page) against a
virtual arm at its own speed (the real-time lane: each jog takes what it takes on an arm): the
jog moves while keep-alives come and stands still once they stop, along its one axis; a joint's
range, the arm's reach and the envelope end it at the edge with the reason, and the next jog
moves from where the arm stands (no desync). The latency from a real page's release is measured
by ``tests/browser/test_view_holdjog.py``.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator

import pytest

from mirobot_async import Envelope, Mirobot, State
from mirobot_async._view import holdjog
from mirobot_async._view.holdjog import HoldJog
from mirobot_async._view.jogplan import JogAxis
from mirobot_async.testing import EmulatorProcess

pytestmark = [
    pytest.mark.timeout(60),
    pytest.mark.usefixtures("no_leftover_tasks"),
    pytest.mark.parametrize("profile", ["2021"]),
]

HOME_X = 198.67
"""The tool's x with every joint at 0 (2021)."""


@contextlib.asynccontextmanager
async def _held(jog: HoldJog, axis: JogAxis) -> AsyncIterator[asyncio.Task[str]]:
    """The button of ``axis`` held while the block runs (keep-alives as the page sends them),
    let go at its end: the jog's task (its outcome once the arm stands)."""
    assert jog.press(axis)
    task = asyncio.create_task(jog.run(axis))

    async def keep_alive() -> None:
        while True:
            await asyncio.sleep(1 / holdjog.KEEPALIVE_HZ)  # the page's keep-alive cadence
            jog.press(axis)

    alive = asyncio.create_task(keep_alive())
    try:
        yield task
    finally:
        alive.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await alive
        jog.release()


async def _jog(jog: HoldJog, axis: JogAxis, seconds: float) -> str:
    """Hold ``axis``'s button ``seconds`` and let go: the jog's outcome."""
    async with _held(jog, axis) as task:
        await asyncio.sleep(seconds)  # the button held this long (the jog's length)
    return await task


@pytest.fixture
async def ready_arm(arm: Mirobot) -> Mirobot:
    """The real-time arm, unlocked (it powers on locked)."""
    await arm.unlock()
    return arm


@pytest.fixture
async def jog(ready_arm: Mirobot) -> HoldJog:
    return HoldJog(ready_arm, lambda _: None, "2021")


async def test_a_held_joint_jog_moves_and_stands_still_after_the_release(
    ready_arm: Mirobot, jog: HoldJog
) -> None:
    said = await _jog(jog, JogAxis("joint", 1, 1), 0.6)
    assert "J2 + (hold): stopped at" in said and "after the release" in said, said
    report = await ready_arm.status(fresh=True)
    assert report.state is State.IDLE
    assert 0.6 < report.joints[1] < 1.6, report.joints  # about 2 deg/s
    assert report.joints[0] == report.joints[2] == 0.0
    said = await _jog(jog, JogAxis("joint", 1, -1), 0.3)
    assert (await ready_arm.status(fresh=True)).joints[1] < report.joints[1] - 0.2


@pytest.mark.parametrize("axis", range(6))
async def test_a_held_cartesian_jog_moves_along_its_axis_only(
    ready_arm: Mirobot, jog: HoldJog, axis: int
) -> None:
    before = (await ready_arm.status(fresh=True)).pose
    sign = 1 if axis % 2 == 0 else -1
    turn = axis >= 3  # the wrist moves a coarse motor step at a time: under 1 deg/s
    said = await _jog(jog, JogAxis("pose", axis, sign), 1.0 if turn else 0.6)
    assert "stopped at" in said and "after the release" in said, said
    after = (await ready_arm.status(fresh=True)).pose
    moved = [a - b for a, b in zip(after, before, strict=True)]
    assert moved[axis] * sign > (0.2 if turn else 0.3), (moved, said)  # about 1-2 mm/s here
    for other in range(6):
        if other != axis:
            assert abs(moved[other]) < 0.1, moved


async def test_the_reach_ends_a_cartesian_jog_and_the_next_starts_where_the_arm_is(
    ready_arm: Mirobot, jog: HoldJog
) -> None:
    """Toward the base along x the firmware's solution leaves J2's range near x 142.3 (J2 at
    -30): the jog ends just before, nothing refused, and X + then moves from there."""
    await ready_arm.move_pose(x=144.0, linear=True, speed=3000)
    async with _held(jog, JogAxis("pose", 0, -1)) as task:
        said = await asyncio.wait_for(task, 10)
    assert "X - (hold): stopped (at the edge of the arm's reach) at" in said, said
    report = await ready_arm.status(fresh=True)
    edge = report.pose[0]
    assert 142.0 < edge < 143.0 and report.joints[1] > -30.01, report  # (whole motor steps)
    await _jog(jog, JogAxis("pose", 0, 1), 0.5)
    back = (await ready_arm.status(fresh=True)).pose[0]
    assert edge + 0.3 < back < edge + 2.0, (edge, back)


@pytest.mark.parametrize("envelope", [Envelope(x=(None, HOME_X + 1.5))])
async def test_the_envelope_ends_a_cartesian_jog_at_its_edge(
    emu: EmulatorProcess, envelope: Envelope
) -> None:
    async with Mirobot.connect(emu.url, envelope=envelope) as arm:
        await arm.unlock()
        jog = HoldJog(arm, lambda _: None, "2021")
        async with _held(jog, JogAxis("pose", 0, 1)) as task:
            said = await asyncio.wait_for(task, 10)
        assert "X + (hold): stopped (refused at the edge: refused by the safety envelope" in said
        edge = (await arm.status(fresh=True)).pose[0]
        assert HOME_X + 1.3 < edge <= HOME_X + 1.5, edge
        await _jog(jog, JogAxis("pose", 0, -1), 0.4)
        assert (await arm.status(fresh=True)).pose[0] < edge - 0.2


async def test_a_joint_jog_ends_at_the_end_of_the_joints_range(
    ready_arm: Mirobot, jog: HoldJog
) -> None:
    await ready_arm.move_joints(j2=69.5, speed=3000)
    async with _held(jog, JogAxis("joint", 1, 1)) as task:
        said = await asyncio.wait_for(task, 10)
    assert "J2 + (hold): stopped (at the end of the joint's range) at 70.0" in said, said


async def test_a_cartesian_jog_refuses_an_arm_the_firmware_would_swing_over(
    ready_arm: Mirobot, jog: HoldJog
) -> None:
    await ready_arm.move_joints(0, 20, 10, 0, -120, 0, speed=3000)
    before = await ready_arm.status(fresh=True)
    said = await _jog(jog, JogAxis("pose", 2, 1), 0.3)
    assert "Z + (hold): refused: the arm stands in another configuration" in said, said
    assert (await ready_arm.status(fresh=True)).joints == before.joints


async def test_no_keep_alive_ends_the_jog(ready_arm: Mirobot) -> None:
    """The page stalls or its link goes silently (no release, no more keep-alives): the
    watchdog ends the jog and the arm stands still."""
    said: list[str] = []
    jog = HoldJog(ready_arm, said.append, "2021")
    axis = JogAxis("joint", 0, 1)
    assert jog.press(axis)
    outcome = await asyncio.wait_for(jog.run(axis), 10)
    assert "after the watchdog" in outcome, outcome
    assert said == ["**J1 + (hold): no keep-alive from the page**"]
    first = (await ready_arm.status(fresh=True)).joints[0]
    assert 1.0 < first < 3.0, first  # 2 deg/s for the watchdog's second
    await asyncio.sleep(0.3)  # the measurement window: the arm must not move during it
    assert (await ready_arm.status(fresh=True)).joints[0] == first
