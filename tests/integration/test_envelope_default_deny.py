"""The envelope cannot be bypassed (issue 13 items 1-6, issue 17 item 1), over the real emulator.

Each test drives the real client against an emulator process on a pty. A refused line raises
``MirobotUsageError`` ("refused by the safety envelope ...") and writes no byte of the line
(the :class:`~mirobot_async.testing.WireSpy` on the transport shows it); a line the envelope
predicts ends where it said (the emulator's status, up to whole motor steps).
"""

from __future__ import annotations

import time

import pytest

from mirobot_async import Envelope, Mirobot, MirobotUsageError
from mirobot_async.kinematics import DH_2021, forward
from mirobot_async.testing import EmulatorProcess, WireSpy

pytestmark = [pytest.mark.timeout(60), pytest.mark.usefixtures("no_leftover_tasks")]
only_2021 = pytest.mark.parametrize("profile", ["2021"])
STEP = 0.05  # deg: whole motor steps


async def _connect(emu: EmulatorProcess, spy: WireSpy, envelope: Envelope) -> Mirobot:
    arm = await Mirobot.connect(emu.url, envelope=envelope, open_transport=spy.opener)
    await arm.unlock()
    return arm


async def _refused(arm: Mirobot, spy: WireSpy, line: str, *fragments: str) -> str:
    """``line`` is refused and not one byte of it is written."""
    mark = spy.mark()
    with pytest.raises(MirobotUsageError) as info:
        await arm.send(line, validate=False)  # the envelope alone (validation refuses more)
    message = str(info.value)
    assert message.startswith("refused by the safety envelope"), message
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    assert spy.lines(mark) == [], "bytes of a refused line were written"
    return message


async def _at(arm: Mirobot) -> tuple[float, ...]:
    report = await arm.wait_idle(timeout=20)
    return report.joints


# ---- item 1: the 2021 base offset ---------------------------------------------------------


@only_2021
async def test_base_offset_is_part_of_the_prediction(emu: EmulatorProcess) -> None:
    spy = WireSpy()
    arm = await _connect(emu, spy, Envelope(x=(None, 230)))
    try:
        line = "M20 G90 G0 G21 X200 Y0 Z200 A0 B0 C0"
        await arm.settings()  # the guard learns $41..$43 from the listing
        await arm.send("$41=40")  # passes: it does not move, but X200 now means x = 240
        await _refused(arm, spy, line, "maximum x=230")
        await arm.send("$41=0")
        await arm.send(line)
        x = forward(await _at(arm), DH_2021)[0]
        assert x == pytest.approx(200, abs=0.2)
    finally:
        await arm.close()


@only_2021
async def test_no_absolute_cartesian_line_before_the_base_offset_is_known(
    emu: EmulatorProcess,
) -> None:
    """Refused while ``$41..$43`` are unknown, or written only after a ``$$`` listing."""
    spy = WireSpy()
    arm = await _connect(emu, spy, Envelope(x=(None, 230)))
    try:
        line = "M20 G90 G0 G21 X200 Y0 Z200"
        mark = spy.mark()
        try:
            await arm.send(line)
        except MirobotUsageError as err:
            assert "base offset" in str(err)
            assert spy.lines(mark) == []
        else:
            written = spy.lines()  # the listing may have come earlier (e.g. with unlock())
            assert written.index(b"$$\n") < written.index(line.encode() + b"\n")
    finally:
        await arm.close()


# ---- item 2: every $H variant homes ---------------------------------------------------------


async def test_homing_variants_forget_the_position(emu: EmulatorProcess) -> None:
    spy = WireSpy()
    arm = await _connect(emu, spy, Envelope(joints={1: (-50, 50)}))
    try:
        await arm.send("M21 G90 G0 G21 X30")
        assert (await _at(arm))[0] == pytest.approx(30, abs=STEP)
        await arm.send("$H8", validate=False)  # homes the arm: the predicted J1=30 is gone
        assert (await _at(arm))[0] == pytest.approx(0, abs=STEP)
        # relative from the true position (0): 45 is inside; from the stale 30 it would not be
        await arm.send("M21 G91 G0 G21 X45")
        assert (await _at(arm))[0] == pytest.approx(45, abs=STEP)
    finally:
        await arm.close()


# ---- item 3: units --------------------------------------------------------------------------


async def test_units_unknown_at_connect_must_be_stated(emu: EmulatorProcess) -> None:
    spy = WireSpy()
    arm = await _connect(emu, spy, Envelope(joints={1: (-50, 50)}))
    try:
        # an earlier session left inches
        await arm.send("G20", check_envelope=False, validate=False)
        await arm.close()
        arm = await _connect(emu, spy, Envelope(joints={1: (-50, 50)}))
        await _refused(arm, spy, "M21 G90 G0 X2", "units")
        report = await arm.move_joints(j1=2)  # states G21 itself
        assert report is not None and report.joints[0] == pytest.approx(2, abs=STEP)
        await arm.send("G20", validate=False)
        await _refused(arm, spy, "M21 G90 G0 X2", "J1 range")  # 2 inches = 50.8 deg
    finally:
        await arm.close()


# ---- items 4 and 5: numbers and command numbers as the firmware reads them -------------------


@pytest.mark.parametrize(
    ("line", "fragment"),
    [
        ("M21 G90 G0 G21 X0000000030", "reads it as 0"),
        ("M20.001 G90 G0 G21 X200 Y0 Z200", "M20"),
        ("M16404 G90 G0 G21 X200 Y0 Z200", "M20"),
    ],
)
async def test_odd_number_forms_are_refused(emu: EmulatorProcess, line: str, fragment: str) -> None:
    spy = WireSpy()
    arm = await _connect(emu, spy, Envelope(z=(150, None)))
    try:
        await _refused(arm, spy, line, fragment)
    finally:
        await arm.close()


# ---- item 6: the wrist snap before a Cartesian path ------------------------------------------


@only_2021
async def test_wrist_snap_below_the_floor_is_refused(emu: EmulatorProcess) -> None:
    tool = (0.0, 60.0, 0.0)
    flipped = (20.0, 5.0, 20.0, 60.0, -160.0, -45.0)
    floor = forward(flipped, DH_2021, tool)[2] - 20.0
    spy = WireSpy()
    arm = await _connect(emu, spy, Envelope(z=(floor, None), tool=tool))
    try:
        await arm.send("$47=60", check_envelope=False)  # the arm's tool offset = the envelope's
        await arm.send("M21 G90 G0 G21 X20 Y5 Z20 A60 B-160 C-45")
        await _at(arm)
        await _refused(arm, spy, "M20 G91 G1 G21 X1 F500", "wrist snap", "minimum z")
    finally:
        await arm.close()


# ---- issue 17 item 1: bounded checks ----------------------------------------------------------


@pytest.mark.parametrize(
    "line", ["M20 G90 G1 G21 A300000 F100", "M20 G90 G1 G21 A99999999999 F100"]
)
async def test_absurd_rotations_are_refused_without_blocking(
    emu: EmulatorProcess, line: str
) -> None:
    spy = WireSpy()
    arm = await _connect(emu, spy, Envelope(z=(0, None)))
    try:
        await _at(arm)
        mark = spy.mark()
        t0 = time.process_time()  # CPU time: other processes on a loaded machine do not count
        with pytest.raises(MirobotUsageError):
            await arm.send(line, timeout=1)
        assert time.process_time() - t0 < 0.2  # the loop is never blocked for long
        assert spy.lines(mark) == []
    finally:
        await arm.close()
