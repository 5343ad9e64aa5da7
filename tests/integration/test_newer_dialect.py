"""The client against the 2024 family (issue 33): its refusals, its family, homing with ``?``."""

from __future__ import annotations

import asyncio
import time

import pytest

from mirobot_async import Mirobot
from mirobot_async._core.replies import State
from mirobot_async.errors import MirobotCommandError, MotionRefusedError, RefusalReason
from mirobot_async.testing import start_emulator


@pytest.mark.parametrize("assumed", [None, "2021", "classic"])
async def test_an_info_e102_refusal_raises_at_once_whatever_the_profile_assumed(
    assumed: str | None,
) -> None:
    """``$3`` answered ``Info,E102,Invalid statement`` and no ``ok``: a command error naming
    E102 at once, not a lost reply after the liveness interval; the next line keeps its own."""
    async with (
        start_emulator(firmware="2024", time_scale=0, in_process=True) as url,
        Mirobot.connect(url, firmware=assumed) as arm,  # type: ignore[arg-type]
    ):
        started = time.monotonic()
        with pytest.raises(MirobotCommandError) as info:
            await arm.send("$3", validate=False)
        assert time.monotonic() - started < 0.5
        assert info.value.code == 102 and info.value.text == "Invalid statement"
        assert "E102" in str(info.value) and "'$3'" in str(info.value)
        assert await arm.send("$I") == ("[0.9j.20160303:]",)
        assert arm.stats.protocol_violations == 0


async def test_the_family_and_its_evidence() -> None:
    async with (
        start_emulator(firmware="2024", time_scale=0, in_process=True) as url,
        Mirobot.connect(url) as arm,
    ):
        banner = await arm.reset()  # the one-line banner is a reset, and names the family
        assert banner == ("WLKATA Robot started successfully.Firmware version:Mirobot,20240820",)
        assert arm.firmware == "2024"
        assert arm.firmware_version == "Mirobot,20240820"
        assert arm.firmware_evidence is not None
        assert "WLKATA Robot started successfully" in arm.firmware_evidence


async def test_the_family_from_the_settings_when_no_banner_was_seen() -> None:
    async with start_emulator(firmware="2024", time_scale=0, in_process=True) as url:
        async with Mirobot.connect(url) as arm:
            pass  # the banner is read by the first connection
        async with Mirobot.connect(url) as arm:
            assert arm.firmware is None
            assert await arm.detect_firmware() == "2024"
            assert (
                arm.firmware_evidence
                == "$$ lists $44, $45, $51, $52 (only the 2024 family has them)"
            )


async def test_a_refused_move_is_a_refusal_and_the_stream_stays_in_step() -> None:
    async with (
        start_emulator(firmware="2024", time_scale=0, in_process=True) as url,
        Mirobot.connect(url) as arm,
    ):
        await arm.clear_alarm()  # out of Alarm; the power-on lock stays
        with pytest.raises(MotionRefusedError) as info:
            await arm.move_joints(j1=10)
        assert info.value.reason is RefusalReason.LOCKED
        assert info.value.text == "Error,A106,Locked status of each axis"
        assert arm.alarm is None
        await arm.unlock()
        with pytest.raises(MotionRefusedError) as info:
            await arm.move_pose(500, 0, 100, 0, 0, 0)
        assert info.value.reason is RefusalReason.UNREACHABLE
        await arm.move_joints(j1=10)
        assert (await arm.status()).joints[0] == pytest.approx(10, abs=0.02)


async def test_status_during_homing_reports_home_with_the_joints() -> None:
    """The 2024 family answers ``?`` during the homing search: status() and statuses() report
    ``Home`` at once, with the joints (classic and 2021 stay silent: tests/realtime)."""
    async with (
        start_emulator(firmware="2024", time_scale=20, in_process=True) as url,
        Mirobot.connect(url) as arm,
    ):
        await arm.unlock()
        await arm.move_joints(j1=20)
        home = asyncio.create_task(arm.home())
        seen: list[State] = []
        async for report in arm.statuses(interval=0.02):
            seen.append(report.state)
            if report.state is State.HOME:
                assert report.joints[0] == pytest.approx(20, abs=0.02)
                break
        report = await arm.status(timeout=0.5)  # answered during the search
        assert report.state in (State.HOME, State.RUN, State.IDLE)
        await home
        assert State.HOME in seen
        assert (await arm.status()).joints[0] == pytest.approx(0, abs=0.02)
