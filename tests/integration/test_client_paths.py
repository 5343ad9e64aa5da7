"""Moves, paths and raw-line validation of the client over the real emulator.

* ``move_pose(wait=True)`` completes when the 2021 base offset ``$41..$43`` is not zero;
* ``send()``/``stream()`` refuse what :func:`mirobot_async._core.validation.check_line` flags,
before
  writing a byte (issue 15 item 3);
* ``move_path``/``move_joint_path`` (issue 12 item 2);
* structured moves state millimetres, whatever unit an earlier line chose (``G20``).
"""

from __future__ import annotations

import asyncio
import logging

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mirobot_async import (
    Envelope,
    InvalidLineError,
    Mirobot,
    MirobotUsageError,
    MotionRefusedError,
    PathError,
)
from mirobot_async._core.validation import ModalState, check_line
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


# ---- one validation: what check_line flags, send() refuses (issue 15 item 3) ------------------

_ALPHABET = "GMXYZABCDFPSERNQHJKgmxyz$=0123456789.-+ ()\t;?!%/"
_WORD = st.tuples(
    st.sampled_from("GMXYZABCDFPSERNQ"),
    st.one_of(
        st.integers(-400, 99999).map(str),
        st.floats(-1e5, 1e5, allow_nan=False).map(lambda v: f"{v:.3f}"),
        st.sampled_from(["0000000030", "20.001", "16404", "1e3", ".", "-", "2000", "1001"]),
    ),
).map("".join)
_LINES = st.one_of(
    st.lists(_WORD, min_size=1, max_size=8).map(" ".join),
    st.text(_ALPHABET, min_size=1, max_size=100),
    st.from_regex(r"\$[0-9A-Z]{1,4}(=[0-9.\-]{1,12})?", fullmatch=True),
)


def _flagged_lines(firmware: str, count: int) -> list[str]:
    """Lines ``check_line`` flags from the modes a fresh connection knows (none: unknown)."""
    found: list[str] = []

    @settings(max_examples=count, derandomize=True, database=None, deadline=None)
    @given(_LINES)
    def collect(line: str) -> None:
        if check_line(line, firmware=firmware, state=ModalState.unknown()):
            found.append(line)

    collect()
    return found


async def test_every_line_check_flags_is_refused_with_no_byte_written(
    emu: EmulatorProcess, profile: str
) -> None:
    lines = _flagged_lines(profile, 400)
    assert len(lines) > 100  # the strategy finds plenty of bad lines
    spy = WireSpy()
    async with Mirobot.connect(emu.url, open_transport=spy.opener) as arm:
        await arm.detect_firmware()  # (unknown, a line only one profile refuses asks for $$)
        for line in lines:
            mark = spy.mark()
            with pytest.raises(MirobotUsageError):
                await arm.send(line)
            assert spy.since(mark) == [], f"bytes of {line!r} were written"
        # the same lines in a stream: each refused before it is written
        mark = spy.mark()
        result = await arm.stream(lines[:50], continue_on_error=True)
        assert result.sent == 0 and len(result.errors) == 50
        assert spy.since(mark) == []


async def test_validation_follows_the_modes_and_has_a_loud_opt_out(
    ready_arm: Mirobot, wire_spy: WireSpy, caplog: pytest.LogCaptureFixture
) -> None:
    arm = ready_arm
    await arm.send("M3 S0")  # valid: sent
    await arm.send("M21 G90")  # the modes are now known: joint ranges apply without M21
    mark = wire_spy.mark()
    with pytest.raises(InvalidLineError, match="J1=170 is outside"):
        await arm.send("G0 X170")
    with pytest.raises(InvalidLineError, match="PWM"):
        await arm.send("M3 S2000")
    assert wire_spy.lines(mark) == []
    with caplog.at_level(logging.WARNING, logger="mirobot_async"):
        await arm.send("M3 S1000", validate=False)
    assert "WITHOUT validation" in caplog.text
    assert wire_spy.lines(mark) == [b"M3 S1000\n"]


# ---- paths (issue 12 item 2) ----------------------------------------------------------------

_SQUARE = [(200, 0, 200), (200, 20, 200), (180, 20, 200), (180, 0, 200), (200, 0, 200)]


async def test_move_path_streams_bare_lines_and_ends_idle_at_the_last_point(
    ready_arm: Mirobot, wire_spy: WireSpy
) -> None:
    arm = ready_arm
    await arm.move_pose(200, 0, 200, 0, 0, 0)
    mark = wire_spy.mark()
    report = await arm.move_path(_SQUARE[1:], speed=2000)
    assert report.pose[:3] == pytest.approx((200, 0, 200), abs=0.2)
    sent = wire_spy.lines(mark)
    # M20 is in effect after move_pose: not stated again (the firmware restarts a line that
    # carries M20/M21 from where the arm is), and no later line carries it
    assert sent[0] == b"G90 G1 G21 F2000\n"
    assert sent[1:5] == [
        b"G1 X200 Y20 Z200\n",
        b"G1 X180 Y20 Z200\n",
        b"G1 X180 Y0 Z200\n",
        b"G1 X200 Y0 Z200\n",
    ]


async def test_move_joint_path_ends_at_the_last_point(ready_arm: Mirobot) -> None:
    points = [(10, 0, 0, 0, 0, 0), (20, 5, 0, 0, 0, 0), (None, 10, -5)]
    report = await ready_arm.move_joint_path(points, speed=2000)
    assert report.joints[:3] == pytest.approx((20, 10, -5), abs=0.05)


async def test_a_bad_point_is_refused_before_the_first_byte(
    ready_arm: Mirobot, wire_spy: WireSpy
) -> None:
    mark = wire_spy.mark()
    refused = r"path point 2 \(200, 0, 300, 0\): j1=200 is outside"
    with pytest.raises(MirobotUsageError, match=refused):
        await ready_arm.move_joint_path([(10,), (20,), (200, 0, 300, 0)], speed=1000)
    with pytest.raises(MirobotUsageError, match="speed is required"):
        await ready_arm.move_path(_SQUARE)
    assert wire_spy.lines(mark) == []


async def test_the_envelope_checks_the_whole_path_first(emu: EmulatorProcess) -> None:
    spy = WireSpy()
    async with Mirobot.connect(
        emu.url, envelope=Envelope(x=(None, 215)), open_transport=spy.opener
    ) as arm:
        await arm.unlock()
        if arm.firmware == "2021":
            await arm.settings()  # the base offset (absolute M20 targets)
        await arm.move_pose(200, 0, 200, 0, 0, 0)
        mark = spy.mark()
        path = [(205, 0, 200), (210, 0, 200), (220, 0, 200), (205, 0, 200)]
        with pytest.raises(MirobotUsageError, match=r"path point 2 \(220, 0, 200\).*x=215"):
            await arm.move_path(path, speed=2000)
        assert spy.lines(mark) == []
        report = await arm.move_path(path[:2], speed=2000)
        assert report.pose[0] == pytest.approx(210, abs=0.2)


async def test_a_point_the_robot_refuses_is_named(ready_arm: Mirobot) -> None:
    with pytest.raises(PathError) as info:
        await ready_arm.move_path([(200, 0, 200), (900, 0, 200), (200, 0, 200)], speed=2000)
    assert info.value.index == 1 and info.value.point == (900, 0, 200)
    assert isinstance(info.value.error, MotionRefusedError)


async def test_structured_moves_state_millimetres(ready_arm: Mirobot) -> None:
    """13.3: G20 (inches) left by an earlier session changed what move_pose() meant."""
    arm = ready_arm
    await arm.send("G20", validate=False)
    report = await arm.move_pose(200, 0, 200)
    assert report is not None
    assert report.pose[:3] == pytest.approx((200, 0, 200), abs=0.1)
    report = await arm.move_joints(j1=10)
    assert report is not None and abs(report.joints[0] - 10) < 0.05


@pytest.mark.parametrize("firmware", ["2021", "classic", "2024"])
async def test_a_relative_move_from_a_stepped_position_ends_at_its_target(firmware: str) -> None:
    """The firmware adds a relative move to its parser's exact position (36.4), not to the whole
    motor steps a status shows (36.364): the arm ends a step away from status + move, and a
    wait that never saw it moving (motion over at once) must still see it arrive."""
    from mirobot_async.testing import start_emulator

    async with (
        start_emulator(firmware=firmware, time_scale=0, in_process=True) as url,
        Mirobot.connect(url, firmware=firmware) as arm,  # type: ignore[arg-type]
    ):
        await arm.home()
        at = await arm.move_joints(j6=36.4)
        assert at is not None
        async with asyncio.timeout(10):
            report = await arm.move_joints(j6=-3.3, relative=True, speed=3000)
        assert report is not None
        assert abs(report.joints[5] - (at.joints[5] - 3.3)) <= 0.1
