"""A move slower than the default move timeout is waited for, at the arm's own speed."""

from __future__ import annotations

import time

import pytest

from mirobot_async import Mirobot
from mirobot_async._client import motion_commands, path_commands
from mirobot_async._client.motion_commands import motion_timeout
from mirobot_async.testing import InProcessArm

pytestmark = pytest.mark.realtime


def test_the_default_timeout_covers_the_slowest_move() -> None:
    # J1 over 260 degrees at F100 takes 156 s of motion: more than the fixed default.
    assert motion_timeout(None, (None,) * 6, None, None, False, joints=True) == 120.0
    assert motion_timeout(None, (260.0,) + (None,) * 5, None, 100.0, True, joints=True) >= 312
    # a short slow move keeps the fixed default
    assert motion_timeout(None, (5.0,) + (None,) * 5, None, 100.0, True, joints=True) == 120.0


async def test_a_move_longer_than_the_default_is_waited_for(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """At real time: with the fixed default lowered to 2 s, a 6 s move at F100 still ends."""
    monkeypatch.setattr(motion_commands, "MOVE_TIMEOUT", 2.0)
    with InProcessArm("classic", time_scale=1) as model:
        async with Mirobot.connect(model.url) as arm:
            await arm.send("M50")
            started = time.monotonic()
            report = await arm.move_joints(j1=10, speed=100, timeout=2.0)
            assert report is not None
            assert report.joints[0] == pytest.approx(10, abs=0.05)
            assert time.monotonic() - started >= 5.0  # 10 deg at 100 deg/min: 6 s of motion


async def test_a_path_longer_than_the_default_is_waited_for(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """At real time: with the fixed default lowered to 2 s, a 6 s joint path still ends."""
    monkeypatch.setattr(motion_commands, "MOVE_TIMEOUT", 2.0)
    monkeypatch.setattr(path_commands, "MOVE_TIMEOUT", 2.0)
    with InProcessArm("classic", time_scale=1) as model:
        async with Mirobot.connect(model.url) as arm:
            await arm.send("M50")
            await arm.status()
            points = [(5.0, 0, 0, 0, 0, 0), (10.0, 0, 0, 0, 0, 0)]
            report = await arm.move_joint_path(points, speed=100, timeout=2.0)
            assert report.joints[0] == pytest.approx(10, abs=0.05)
