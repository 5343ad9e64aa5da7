"""The envelope follows what the firmware keeps and where its parser stands (issue 23 items 1-4
and the soft limits), over the real emulator on a pty.

Each case was reproducible before: a line the envelope let through ended outside it. Now the
line is refused before a byte of it is written (``refused by the safety envelope``), or it ends
where the envelope predicted (the emulator's status, up to whole motor steps).
"""

from __future__ import annotations

import pytest

from mirobot_async import Envelope, Mirobot, MirobotUsageError, MotionRefusedError, RefusalReason
from mirobot_async.kinematics import DH_2021, DH_CLASSIC, forward
from mirobot_async.testing import EmulatorProcess, WireSpy

pytestmark = [pytest.mark.timeout(60), pytest.mark.usefixtures("no_leftover_tasks")]
only_classic = pytest.mark.parametrize("profile", ["classic"])
only_2021 = pytest.mark.parametrize("profile", ["2021"])
STEP = 0.05  # deg: whole motor steps
J1_50 = Envelope(joints={1: (-50, 50)})


async def _refused(arm: Mirobot, spy: WireSpy, line: str, *fragments: str) -> str:
    """``line`` is refused by the envelope and not one byte of it is written."""
    mark = spy.mark()
    with pytest.raises(MirobotUsageError) as info:
        await arm.send(line, validate=False)
    message = str(info.value)
    assert message.startswith("refused by the safety envelope"), message
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    assert line.encode() + b"\n" not in spy.lines(mark), "a refused line was written"
    return message


async def _j1(arm: Mirobot) -> float:
    report = await arm.wait_idle(timeout=20)
    return report.joints[0]


async def _store(emu: EmulatorProcess, *lines: str) -> None:
    """Another program (no envelope) leaves ``lines`` in the firmware's memory."""
    async with Mirobot.connect(emu.url) as other:
        await other.unlock()
        for line in lines:
            await other.send(line, validate=False)


# ---- item 1: a move refused as locked moves the parser ---------------------------------------


async def test_locked_refusal_moves_the_parser(emu: EmulatorProcess) -> None:
    spy = WireSpy()
    async with Mirobot.connect(emu.url, envelope=J1_50, open_transport=spy.opener) as arm:
        if arm.firmware != "classic":
            await arm.send("$X")  # out of Alarm; the power-on lock stays (oracle)
        with pytest.raises(MotionRefusedError) as info:
            await arm.send("M21 G91 G0 G21 X40")
        assert info.value.reason is RefusalReason.LOCKED
        await arm.send("M50")
        # the firmware's parser stands at J1 = 40 (the refused target): X45 more is 85
        await _refused(arm, spy, "G91 X45", "J1 range")
        await arm.send("G91 X5")  # predicted from 40: ends at 45
        assert await _j1(arm) == pytest.approx(45, abs=STEP)


async def test_an_m21_line_resynchronises_the_parser(emu: EmulatorProcess) -> None:
    async with Mirobot.connect(emu.url, envelope=J1_50) as arm:
        if arm.firmware != "classic":
            await arm.send("$X")
        with pytest.raises(MotionRefusedError):
            await arm.send("M21 G91 G0 G21 X40")
        await arm.send("M50")
        await arm.send("M21 G91 X45")  # M21 re-reads the arm's position (0): ends at 45
        assert await _j1(arm) == pytest.approx(45, abs=STEP)


# ---- item 2: classic M20 G1 (and 2021 with $35=0) is a joint-space move ----------------------


async def _at_j1(arm: Mirobot, j1: float) -> str:
    """Move to J1 = ``j1`` (others 0); the M20 G1 line to the mirror pose (J1 = -j1)."""
    await arm.move_joints(j1=j1)
    assert await _j1(arm) == pytest.approx(j1, abs=STEP)
    dh = DH_CLASSIC if arm.firmware == "classic" else DH_2021
    x, y, z, a, b, c = forward((-j1, 0.0, 0.0, 0.0, 0.0, 0.0), dh)
    return f"M20 G90 G1 G21 X{x:.3f} Y{y:.3f} Z{z:.3f} A{a:.3f} B{b:.3f} C{c:.3f} F2000"


@only_classic
async def test_classic_m20_g1_is_checked_as_a_joint_move(emu: EmulatorProcess) -> None:
    # From J1 = -40 to J1 = 40 the straight line stays at x = 154.7 mm; the joint-space move
    # passes J1 = 0, x = 202 mm.
    spy = WireSpy()
    envelope = Envelope(x=(None, 170))
    async with Mirobot.connect(emu.url, envelope=envelope, open_transport=spy.opener) as arm:
        await arm.unlock()
        line = await _at_j1(arm, -40)
        await _refused(arm, spy, line, "joint-space path", "maximum x=170")
        with pytest.raises(MirobotUsageError, match="joint-space path"):
            dh = DH_CLASSIC
            x, y, z, *_ = forward((40.0, 0.0, 0.0, 0.0, 0.0, 0.0), dh)
            await arm.move_pose(x=x, y=y, z=z, rx=0, ry=0, rz=40, linear=True, speed=2000)


@only_2021
async def test_2021_m20_g1_follows_setting_35(emu: EmulatorProcess) -> None:
    spy = WireSpy()
    envelope = Envelope(x=(None, 170))
    async with Mirobot.connect(emu.url, envelope=envelope, open_transport=spy.opener) as arm:
        await arm.unlock()
        line = await _at_j1(arm, -40)
        await arm.send("$35=0")  # M20 G1 becomes a joint-space move: followed
        await _refused(arm, spy, line, "joint-space path", "maximum x=170")
        await arm.send("$35=1")  # a straight line again: x stays at 152.2 mm
        await arm.send(line)
        assert await _j1(arm) == pytest.approx(40, abs=0.1)


# ---- item 3: stored startup lines ------------------------------------------------------------


@only_classic
async def test_startup_lines_are_read_and_predicted_after_a_reset(emu: EmulatorProcess) -> None:
    await _store(emu, "$N0=G91")
    spy = WireSpy()
    async with Mirobot.connect(emu.url, envelope=J1_50, open_transport=spy.opener) as arm:
        await arm.unlock()
        await arm.move_joints(j1=30)  # the envelope reads $N before this first move
        assert await _j1(arm) == pytest.approx(30, abs=STEP)
        await arm.reset()  # the firmware runs G91 after the banner
        await _refused(arm, spy, "M21 G0 G21 X40", "J1 range")  # 30 + 40 = 70
        assert b"$N\n" in spy.lines()
        await arm.send("M21 G0 G21 X10")
        assert await _j1(arm) == pytest.approx(40, abs=STEP)


@only_classic
@pytest.mark.mirobot_emulator(extra_args=("--reset-on-open",), fresh=True)
async def test_startup_lines_after_a_reset_on_open(emu: EmulatorProcess) -> None:
    async with Mirobot.connect(emu.url) as other:
        await other.unlock()
        await other.move_joints(j1=30)
        await other.send("$N0=G91")
    spy = WireSpy()
    async with Mirobot.connect(emu.url, envelope=J1_50, open_transport=spy.opener) as arm:
        # the open reset the arm and ran G91; the client has not read $N yet: unknown
        await arm.send("M50")
        await _refused(arm, spy, "M21 G0 G21 X40", "distance mode")
        await arm.send("M21 G90 G0 G21 X40")
        assert await _j1(arm) == pytest.approx(40, abs=STEP)


async def test_a_startup_line_stored_meanwhile_makes_its_modes_unknown(
    emu: EmulatorProcess,
) -> None:
    spy = WireSpy()
    async with Mirobot.connect(emu.url, envelope=J1_50, open_transport=spy.opener) as arm:
        await arm.unlock()
        await arm.move_joints(j1=30)
        await arm.send("$N0=G91", check_envelope=False)
        await arm.reset()
        if arm.firmware != "classic":
            await arm.unlock()
        # classic ran G91, 2021 may not have: unknown, so the line must state it
        await _refused(arm, spy, "M21 G0 G21 X40", "distance mode")
        await arm.send("M21 G90 G0 G21 X40")
        assert await _j1(arm) == pytest.approx(40, abs=STEP)


# ---- item 4: work offsets in EEPROM ----------------------------------------------------------


async def test_stored_work_offsets_are_read_and_added(emu: EmulatorProcess) -> None:
    await _store(emu, "G10 L2 P1 X40")
    spy = WireSpy()
    async with Mirobot.connect(emu.url, envelope=J1_50, open_transport=spy.opener) as arm:
        await arm.unlock()
        await _refused(arm, spy, "M21 G90 G0 G21 X30", "J1 range")  # 30 + 40 = 70
        assert b"$#\n" in spy.lines()
        await arm.send("M21 G90 G0 G21 X-30")  # -30 + 40 = 10
        assert await _j1(arm) == pytest.approx(10, abs=STEP)


async def test_a_work_offset_set_meanwhile_is_read_again(emu: EmulatorProcess) -> None:
    spy = WireSpy()
    async with Mirobot.connect(emu.url, envelope=J1_50, open_transport=spy.opener) as arm:
        await arm.unlock()
        await arm.send("M21 G90 G0 G21 X30")
        assert await _j1(arm) == pytest.approx(30, abs=STEP)
        await arm.send("G10 L2 P1 X40", check_envelope=False, validate=False)
        await _refused(arm, spy, "M21 G90 G0 G21 X30", "J1 range")


# ---- soft limits $20, $130..$146 -------------------------------------------------------------


async def test_soft_limits_narrow_the_envelope(emu: EmulatorProcess) -> None:
    spy = WireSpy()
    async with Mirobot.connect(emu.url, envelope=J1_50, open_transport=spy.opener) as arm:
        await arm.unlock()
        await arm.send("$144=20")  # J1 >= -20: the firmware would drop X-45
        await _refused(arm, spy, "M21 G90 G0 G21 X-45", "J1 range -20..50")
        await arm.send("M21 G90 G0 G21 X-15")
        assert await _j1(arm) == pytest.approx(-15, abs=STEP)
        await arm.send("$20=0")  # soft limits off: the envelope's own range again
        await arm.send("M21 G90 G0 G21 X-45")
        assert await _j1(arm) == pytest.approx(-45, abs=STEP)


async def test_stored_soft_limits_are_read(emu: EmulatorProcess) -> None:
    await _store(emu, "$144=20")
    spy = WireSpy()
    async with Mirobot.connect(emu.url, envelope=J1_50, open_transport=spy.opener) as arm:
        await arm.unlock()
        await _refused(arm, spy, "M21 G90 G0 G21 X-45", "J1 range -20..50")
