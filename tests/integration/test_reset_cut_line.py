"""A reset that catches lines on their way: the first line answered after it has an unknown fate.

A spontaneous reset wipes what the robot had received; the bytes still on the wire arrive after
it, and the first of them may be the tail of a line whose head was wiped, read by the firmware as
a line of its own. Its reply cannot be told from a reply to the whole line, so the client reports
that line as :class:`MirobotOutcomeUnknownError` (quoting the reply), the lines before it as not
run (:class:`MirobotResetError`) and the lines after it with their own replies; nothing is resent.
"""

from __future__ import annotations

import asyncio

import pytest

# 9600 baud: a 9-byte line spends ~9 ms on the wire, so a dozen lines are in transit at once
from waiting import poll_until, wait_until

from mirobot_async import (
    Mirobot,
    MirobotAlarmError,
    MirobotOutcomeUnknownError,
    MirobotResetError,
)
from mirobot_async.testing import EmulatorProcess

SLOW_WIRE = ("--baud", "9600")
LINES = [f"M3 S{100 + i}" for i in range(60)]


@pytest.mark.mirobot_emulator(time_scale=0, extra_args=SLOW_WIRE)
async def test_the_first_line_answered_after_a_reset_has_an_unknown_outcome(
    emu: EmulatorProcess, ready_arm: Mirobot
) -> None:
    arm = ready_arm
    arm.liveness_interval = 0.1  # settle the lines the reset wiped soon after the banner
    stream = asyncio.ensure_future(arm.stream(LINES))
    try:
        await wait_until(
            lambda: arm.stats.lines_acknowledged >= 5 and arm.pending_count >= 6,
            10,
            "5 lines acknowledged and 6 pending",
        )
        await emu.control("reset")
        result = await asyncio.wait_for(stream, 15)
    finally:
        stream.cancel()
    assert result.stopped and result.errors
    kinds = [type(r.error) for r in result.errors]
    assert kinds.count(MirobotOutcomeUnknownError) == 1, result.errors
    cut = kinds.index(MirobotOutcomeUnknownError)
    unknown = result.errors[cut].error
    assert isinstance(unknown, MirobotOutcomeUnknownError)
    assert unknown.command == result.errors[cut].line
    assert "unknown" in str(unknown) and unknown.reply in str(unknown)
    # before it: wiped by the reset (not run); after it: their own replies (2021: Alarm lock),
    # then the lines the stream had not written yet (not sent)
    assert all(k is MirobotResetError for k in kinds[:cut]), result.errors
    after = result.errors[cut + 1 :]
    unsent = [isinstance(r.error, MirobotResetError) and "not sent" in str(r.error) for r in after]
    assert unsent == sorted(unsent), result.errors  # the unsent ones come last
    answered = [r.error for r, was_unsent in zip(after, unsent, strict=True) if not was_unsent]
    assert not any(isinstance(e, MirobotResetError) for e in answered), result.errors
    if arm.firmware == "2021":
        assert all(isinstance(e, MirobotAlarmError) for e in answered), result.errors
    # every line accounted for once: acknowledged before the reset, or one of the errors
    assert result.acknowledged + len(result.errors) >= result.sent
    await wait_until(lambda: arm.pending_count == 0, 10, "no call pending")

    async def all_received() -> dict[str, str] | None:
        words = (await emu.control("stats")).split()
        stats = dict(word.split("=") for word in words[2:])
        return stats if int(stats["bytes_in"]) == arm.stats.bytes_sent else None

    # nothing resent: the robot received each written line once
    stats = await poll_until(all_received, 10, "every byte written received", every=0.01)
    assert int(stats["lines_in"]) == arm.stats.lines_sent
