"""The status report mask ``$10``: what the client cannot read is refused before it is written,
what only adds fields (``Buf``, ``RX``, ``Lim``) is read, and a robot whose reports cannot be read
(set so by another program) is asked a few times a second, never in a tight loop."""

from __future__ import annotations

import pytest

from mirobot_async import Mirobot, MirobotTimeoutError, MirobotUsageError, State


@pytest.mark.parametrize("mask", [103, 127, 99 | 16, 33])
async def test_a_mask_that_adds_fields_is_accepted_and_read(ready_arm: Mirobot, mask: int) -> None:
    arm = ready_arm
    await arm.set_setting(10, mask)
    report = await arm.status()
    assert report.state is State.IDLE and report.joints == (0.0,) * 6
    await arm.move_joints(j1=5, wait=True)
    assert (await arm.status()).joints[0] == pytest.approx(5.0, abs=0.05)
    assert arm.stats.status_corrupted == 0


@pytest.mark.parametrize("mask", [0, 3, 98, 64 | 32 | 4, 255 - 32])
async def test_a_mask_without_angles_or_pwm_is_refused_before_sending(
    ready_arm: Mirobot, mask: int
) -> None:
    arm = ready_arm
    sent = arm.stats.bytes_sent
    with pytest.raises(MirobotUsageError, match=r"\$10.*angles \(1\) or the PWM values \(32\)"):
        await arm.set_setting(10, mask)
    with pytest.raises(MirobotUsageError, match="status report mask"):
        await arm.send(f"$10={mask}")
    result = await arm.stream([f"$10={mask}"])
    assert len(result.errors) == 1
    assert arm.stats.bytes_sent == sent
    assert (await arm.status()).state is State.IDLE


async def test_unreadable_reports_are_asked_for_a_few_times_a_second(ready_arm: Mirobot) -> None:
    arm = ready_arm
    await arm.send("$10=3", validate=False)  # as another program may have left it
    asked = arm.stats.status_requests
    with pytest.raises(MirobotTimeoutError):
        await arm.status(timeout=0.5)
    # each unreadable report used to call for the next "?" 2 ms later (about 200 in 0.5 s); now
    # each waits 4 times longer than the one before, up to 0.25 s: 5 in 0.5 s (a loaded
    # machine asks fewer, never more)
    assert arm.stats.status_corrupted >= 1
    assert arm.stats.status_requests - asked <= 7
