"""Moves, paths and raw-line validation of the client over the real emulator.

* ``move_pose(wait=True)`` completes when the 2021 base offset ``$41..$43`` is not zero;
* ``send()``/``stream()`` refuse what :func:`mirobot_async.validation.check_line` flags, before
  writing a byte (issue 15 item 3);
* ``move_path``/``move_joint_path`` (issue 12 item 2).
"""

from __future__ import annotations

import pytest

from mirobot_async import Mirobot
from mirobot_async.testing import EmulatorProcess, WireSpy

pytestmark = [pytest.mark.timeout(60), pytest.mark.usefixtures("no_leftover_tasks")]
only_2021 = pytest.mark.parametrize("profile", ["2021"])


# ---- the base offset in move_pose's completion target ----------------------------------------


@only_2021
async def test_move_pose_wait_completes_with_a_base_offset(ready_arm: Mirobot) -> None:
    """The firmware adds ``$41`` to absolute ``M20`` targets; completion must not wait for a
    pose the arm never reports (it hung until the timeout)."""
    await ready_arm.send("$41=40")
    try:
        report = await ready_arm.move_pose(200, 0, 200, 0, 0, 0, timeout=10)
        assert report is not None
        assert report.pose[0] == pytest.approx(240, abs=0.2)
        await ready_arm.settings()  # the offset is now known exactly: X/Y/Z checked too
        report = await ready_arm.move_pose(190, 10, 210, 0, 0, 0, timeout=10)
        assert report is not None
        assert report.pose[:3] == pytest.approx((230, 10, 210), abs=0.2)
    finally:
        await ready_arm.send("$41=0")
