"""The envelope knows what the firmware rejects: a line the firmware refuses moves nothing, so
predicting it as a move lets the lines behind it run from a position nobody predicted.

Each test is one way the client used to predict a refused line as run (the firmware's verdict:
:mod:`mirobot_async._core.acceptance`; proven line by line against the firmware model in
``tests/unit/test_acceptance_vs_firmware.py``)."""

from __future__ import annotations

import pytest

from mirobot_async import Envelope, Mirobot, MirobotCommandError, MirobotUsageError
from mirobot_async._core.validation import check_program
from mirobot_async._mcp_server.service import ArmService, default_envelope
from mirobot_async.testing import EmulatorPool, EmulatorProcess, WireSpy

pytestmark = [pytest.mark.timeout(60), pytest.mark.usefixtures("no_leftover_tasks")]


def _lines(spy: WireSpy, mark: int) -> list[bytes]:
    return [w for w in spy.writes[mark:] if w != b"?"]


async def test_a_feed_move_without_a_feed_rate_after_homing_is_refused(
    emu: EmulatorProcess,
) -> None:
    """After homing the feed rate is 0: ``G1`` without ``F`` is 'Undefined feed rate'. Predicted
    as a move (J1 -> 20), the relative line behind it (J1 - 40 -> -20, inside -20..60) ran from
    J1 = 0 and ended at -40."""
    spy = WireSpy()
    envelope = Envelope(joints={1: (-20, 60)})
    async with Mirobot.connect(emu.url, envelope=envelope, open_transport=spy.opener) as arm:
        await arm.home()
        mark = len(spy.writes)
        with pytest.raises(MirobotUsageError, match="Undefined feed rate"):
            await arm.send("M21 G91 G21 G1 X20")
        result = await arm.stream(["M21 G91 G21 G1 X20", "G0 X-40"])
        assert result.sent == 0 and result.stopped
        assert "Undefined feed rate" in str(result.errors[0].error)
        assert _lines(spy, mark) == []  # refused before a byte
        await arm.send("M21 G91 G21 G1 X20 F2000")  # with a feed rate it runs
        await arm.send("G1 X-30")  # and the feed rate stays
        await arm.wait_idle()
        assert (await arm.status()).joints[0] == pytest.approx(-10, abs=0.05)


async def test_a_mode_word_after_a_g_word_is_refused_by_check_send_and_the_envelope(
    emu: EmulatorProcess, profile: str
) -> None:
    """``G91 M21 ...`` is a 'Modal group violation' on the firmware (M20/M21/M3/M4/M5/M50 take
    the modal group of the word before them): ``mirobot check`` flags it, ``send()`` refuses it,
    and the envelope does not predict it (sent unvalidated, it would have been J1 -30 and the
    next line's start)."""
    for line in ("G90 M21 G0 X10", "G0 M20 X200", "G91 M3 S100", "G90 M50"):
        assert check_program([line], firmware=profile), line
    spy = WireSpy()
    envelope = Envelope(joints={1: (-20, 60)})
    async with Mirobot.connect(emu.url, envelope=envelope, open_transport=spy.opener) as arm:
        await arm.home()
        mark = len(spy.writes)
        with pytest.raises(MirobotUsageError, match="Modal group violation"):
            await arm.send("G91 M21 G0 X-30")
        with pytest.raises(MirobotUsageError, match="Modal group violation"):
            await arm.send("G91 M21 G0 X-30", validate=False)
        assert _lines(spy, mark) == []


async def test_a_refused_classic_line_still_switches_the_mode(
    mirobot_emulator_pool: EmulatorPool,
) -> None:
    """On classic a refused line's M20 still switches to Cartesian mode: the client follows it,
    so a relative joint move states M21 again (it moved the tool 30 mm down instead), and the
    envelope predicts the next raw line in Cartesian mode (it ended at z = 151 under z >= 160)."""
    async with (
        mirobot_emulator_pool.lend_async("classic", 0.0) as emu,
        Mirobot.connect(emu.url) as arm,
    ):
        await arm.home()
        await arm.move_joints(j3=-10)
        with pytest.raises(MirobotCommandError):  # the firmware refuses it (Q is no word of it)
            await arm.send("M20 G0 Q1", validate=False)
        assert (await arm.status()).motion_mode == 1  # and yet: Cartesian mode
        await arm.move_joints(j3=-30, relative=True)
        assert (await arm.status()).joints[2] == pytest.approx(-40, abs=0.05)
    async with (
        mirobot_emulator_pool.lend_async("classic", 0.0) as emu,
        Mirobot.connect(emu.url, envelope=Envelope(z=(160, None))) as arm,
    ):
        await arm.home()
        await arm.send("M21 G90 G21 G0 X0")
        await arm.wait_idle()
        with pytest.raises(MirobotCommandError):
            await arm.send("M20 G0 Q1", validate=False, check_envelope=False)
        with pytest.raises(MirobotUsageError, match="z=160"):
            await arm.send("G91 G0 Z-30")  # a Cartesian move to z = 151
        await arm.wait_idle()
        assert (await arm.status()).pose[2] == pytest.approx(181, abs=0.05)


async def test_run_program_under_the_default_envelope_refuses_a_line_without_feed(
    mirobot_emulator_pool: EmulatorPool,
) -> None:
    """Through MCP: after homing, ``G1`` without ``F`` is refused; predicted as J1 -60 it let
    ``G0 X100`` through, which ran from J1 = 0 to 100 (x = -34.5 mm under x >= 50)."""
    async with (
        mirobot_emulator_pool.lend_async("2021", 0.0) as emulator,
        Mirobot.connect(emulator.url, firmware="2021", envelope=default_envelope("2021")) as arm,
    ):
        service = ArmService(arm)
        await service.home()
        with pytest.raises(MirobotUsageError, match="feed rate"):
            await service.run_program("M21 G91 G21\nG1 X-60\nG0 X100\n")
        assert (await arm.status()).joints[0] == pytest.approx(0, abs=0.05)
