"""The workspace safety envelope wired into the client (issue 7, section 2).

Every move is checked before it is written: structured moves, relative moves (against the
predicted position), raw ``send()`` lines and ``stream()`` lines. A violating move raises
``MirobotUsageError`` naming the bound and writes nothing: a spy on the transport's ``write``
(:class:`WireSpy`) proves that not one byte went out, and the emulator's status shows the arm
where it was. Moves inside are written byte for byte as the G-code builders make them.

The last test is a hypothesis property over random joint targets and linear paths, run against a
minimal fake robot on a TCP socket (``socket://``) so that many examples are cheap.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
from collections.abc import Awaitable, Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from waiting import wait_until

from mirobot_async import (
    Envelope,
    LineResult,
    Mirobot,
    MirobotAlarmError,
    MirobotUsageError,
    MotionRefusedError,
    State,
    StatusReport,
)
from mirobot_async._core import gcode
from mirobot_async.kinematics import (
    DH_2021,
    DH_CLASSIC,
    JOINT_LIMITS,
    forward,
    forward_many,
    inverse,
)
from mirobot_async.testing import EmulatorProcess, WireSpy

pytestmark = [pytest.mark.timeout(60)]
emulated = pytest.mark.usefixtures("no_leftover_tasks")


class EnvelopeSpy(WireSpy):
    """The wire spy, with the lines written since a mark (status requests left out)."""

    def lines_since(self, mark: int) -> list[bytes]:
        """The lines written since ``mark`` (status requests left out)."""
        return [w for w in self.writes[mark:] if w != b"?"]


@pytest.fixture
def spy() -> EnvelopeSpy:
    return EnvelopeSpy()


@contextlib.asynccontextmanager
async def connected(
    emu: EmulatorProcess,
    envelope: Envelope,
    *,
    unlock: bool = True,
    spy: EnvelopeSpy | None = None,
) -> Any:
    opener = (spy or EnvelopeSpy()).opener
    async with Mirobot.connect(emu.url, envelope=envelope, open_transport=opener) as arm:
        if unlock:
            await arm.unlock()
            await arm.send("G21")  # units are unknown at connect (an earlier G20 survives)
            await arm.settings()  # the 2021 base offset $41..$43, for absolute M20 lines
        yield arm


def stated(line: bytes, *, mode: bool = True) -> bytes:
    """A builder's line as the client writes it: stating its units (``G21``), and its
    ``M20``/``M21`` only when the mode changes (``mode``; the firmware restarts a line that
    carries one from where the arm is)."""
    words = line.rstrip(b"\n").split()
    if not mode and words[0] in (b"M20", b"M21"):
        words = words[1:]
    return b" ".join(words) + b" G21\n"


async def assert_refused(
    arm: Mirobot,
    spy: EnvelopeSpy,
    call: Callable[[], Awaitable[object]],
    *fragments: str,
    reads_position: bool = False,
) -> MirobotUsageError:
    """``call()`` raises MirobotUsageError naming ``fragments`` and writes nothing at all.

    ``reads_position``: the client did not know where the arm is, so it asked for a status
    (``?``, never a line) before judging the move.
    """
    lines, refusals = arm.stats.lines_sent, arm.stats.envelope_refusals
    before = await arm.status()
    mark = spy.mark()
    with pytest.raises(MirobotUsageError) as info:
        await call()
    message = str(info.value)
    assert message.startswith("refused by the safety envelope: "), message
    assert message.endswith("; nothing was sent"), message
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    if reads_position:
        assert spy.since(mark) and set(spy.since(mark)) == {b"?"}
    else:
        assert spy.since(mark) == [], "bytes were written for a refused move"
    assert arm.stats.lines_sent == lines
    assert arm.stats.envelope_refusals == refusals + 1
    assert arm.pending_count == 0
    after = await arm.status()
    if before.state is State.IDLE:  # (an accepted move still running moves the arm meanwhile)
        assert after.joints == before.joints and after.rail == before.rail
    return info.value


def assert_joints(report: StatusReport | None, expected: tuple[float, ...]) -> None:
    assert report is not None
    assert report.joints == pytest.approx(expected, abs=0.05), report.joints  # whole steps


# ---- moves inside are untouched -----------------------------------------------------------------


@emulated
async def test_moves_inside_the_envelope_arrive_byte_for_byte(
    emu: EmulatorProcess, spy: EnvelopeSpy
) -> None:
    envelope = Envelope(x=(100, 260), y=(-160, 160), z=(100, 300), joints={1: (-60, 60)})
    async with connected(emu, envelope, spy=spy) as arm:
        mark = spy.mark()
        assert_joints(await arm.move_joints(j1=30, j2=10), (30, 10, 0, 0, 0, 0))
        assert spy.lines_since(mark) == [stated(gcode.move_joints(30, 10), mode=False)]

        mark = spy.mark()
        report = await arm.move_pose(x=200, y=50, z=200)
        assert report is not None
        assert report.pose[:3] == pytest.approx((200, 50, 200), abs=0.1)
        assert spy.lines_since(mark) == [stated(gcode.move_pose(200, 50, 200))]

        mark = spy.mark()
        report = await arm.move_pose(y=-50, linear=True, speed=2000)
        assert report is not None
        assert report.pose[:3] == pytest.approx((200, -50, 200), abs=0.1)
        assert spy.lines_since(mark) == [
            stated(gcode.move_pose(y=-50, linear=True, speed=2000), mode=False)
        ]

        mark = spy.mark()
        start = report.joints
        report = await arm.move_joints(j1=-5, relative=True)
        assert_joints(report, (start[0] - 5, *start[1:]))
        assert spy.lines_since(mark) == [stated(gcode.move_joints(-5, relative=True))]
        assert arm.stats.envelope_refusals == 0


# ---- moves outside are refused, nothing written -------------------------------------------------


@emulated
async def test_targets_outside_the_envelope_are_refused_with_nothing_written(
    emu: EmulatorProcess, spy: EnvelopeSpy
) -> None:
    envelope = Envelope(x=(100, 260), z=(100, None), joints={1: (-60, 60)})
    async with connected(emu, envelope, spy=spy) as arm:
        await assert_refused(
            arm, spy, lambda: arm.move_joints(j1=75), "j1=75.000", "J1 range -60..60 deg"
        )
        await assert_refused(
            arm, spy, lambda: arm.move_pose(z=50), "z=50.000 mm", "minimum z=100 mm", "move_pose"
        )
        await assert_refused(
            arm,
            spy,
            lambda: arm.move_pose(x=300, linear=True, speed=1000),
            "maximum x=260 mm",
        )
        await assert_refused(
            arm, spy, lambda: arm.move_joints(j1=75, wait=False), "J1 range -60..60 deg"
        )
        # the arm still works, inside
        assert_joints(await arm.move_joints(j1=55), (55, 0, 0, 0, 0, 0))


@emulated
async def test_a_joint_space_path_that_leaves_the_box_is_refused(
    emu: EmulatorProcess, spy: EnvelopeSpy
) -> None:
    # J1 swings the tool point around the base: from -25 to +25 deg it passes x = 198.67 (2021)
    # or 202 (classic) at J1 = 0, above the box, although both ends are inside it.
    envelope = Envelope(x=(None, 190))
    async with connected(emu, envelope, spy=spy) as arm:
        # Home is outside the box: a move back inside that never goes farther out is allowed.
        assert_joints(await arm.move_joints(j1=-25), (-25, 0, 0, 0, 0, 0))
        error = await assert_refused(
            arm, spy, lambda: arm.move_joints(j1=25), "joint-space path", "maximum x=190 mm"
        )
        assert "move_joints 'G90 G0 X25 G21'" in str(error)  # M21 is in effect
        assert_joints(await arm.move_joints(j1=-30), (-30, 0, 0, 0, 0, 0))


@emulated
async def test_a_linear_path_that_needs_joints_outside_the_envelope_is_refused(
    emu: EmulatorProcess, spy: EnvelopeSpy
) -> None:
    # Along y at x=200, z=200 the elbow (J3) is highest in the middle: with J3 <= -10 both ends
    # (y = -/+150) are allowed on both geometries, the middle of the straight line is not.
    envelope = Envelope(joints={3: (None, -10)})
    async with connected(emu, envelope, spy=spy) as arm:
        report = await arm.move_pose(x=200, y=-150, z=200)
        assert report is not None and report.pose[:3] == pytest.approx((200, -150, 200), abs=0.1)
        if arm.firmware == "classic":
            # the classic firmware runs M20 G1 in joint space (oracle): J3 stays <= -10
            report = await arm.move_pose(y=150, linear=True, speed=2000)
            assert report is not None and report.pose[1] == pytest.approx(150, abs=0.1)
            return
        await assert_refused(
            arm,
            spy,
            lambda: arm.move_pose(y=150, linear=True, speed=2000),
            "the straight line passes",
            "J3 range -170..-10 deg",
        )
        # point to point (G0) the same target is a joint-space move: allowed
        report = await arm.move_pose(y=150)
        assert report is not None and report.pose[:3] == pytest.approx((200, 150, 200), abs=0.1)


# ---- relative moves and the predicted position --------------------------------------------------


@emulated
async def test_relative_moves_are_checked_against_the_last_position(
    emu: EmulatorProcess, spy: EnvelopeSpy
) -> None:
    envelope = Envelope(z=(100, None), joints={1: (-60, 60)})
    async with connected(emu, envelope, spy=spy) as arm:
        assert_joints(await arm.move_joints(j1=40), (40, 0, 0, 0, 0, 0))
        assert_joints(await arm.move_joints(j1=15, relative=True), (55, 0, 0, 0, 0, 0))
        await assert_refused(
            arm, spy, lambda: arm.move_joints(j1=10, relative=True), "j1=65.000", "J1 range"
        )
        await assert_refused(
            arm,
            spy,
            lambda: arm.move_pose(z=-200, relative=True, linear=True, speed=1000),
            "minimum z=100 mm",
        )
        # Pipelined moves chain: the second starts where the first ends (-30), not where the
        # last status showed the arm (55).
        await arm.move_joints(j1=-30, wait=False)
        await assert_refused(
            arm,
            spy,
            lambda: arm.move_joints(j1=-40, relative=True, wait=False),
            "j1=-70.000",
        )
        await arm.wait_idle()
        assert_joints(await arm.move_joints(j1=-20, relative=True), (-50, 0, 0, 0, 0, 0))


@emulated
async def test_concurrent_moves_are_checked_in_the_order_they_are_written(
    emu: EmulatorProcess, spy: EnvelopeSpy
) -> None:
    envelope = Envelope(joints={1: (-60, 60)})
    async with connected(emu, envelope, spy=spy) as arm:
        mark = spy.mark()
        first = asyncio.ensure_future(arm.move_joints(j1=50, wait=False))
        second = asyncio.ensure_future(arm.move_joints(j1=15, relative=True, wait=False))
        await first
        with pytest.raises(MirobotUsageError, match=r"j1=65\.000"):
            await second  # checked after the first line was written: 50 + 15
        assert spy.lines_since(mark) == [stated(gcode.move_joints(50), mode=False)]
        assert_joints(await arm.wait_idle(), (50, 0, 0, 0, 0, 0))


@emulated
async def test_after_homing_the_position_is_read_before_the_next_move(
    emu: EmulatorProcess, spy: EnvelopeSpy
) -> None:
    envelope = Envelope(joints={1: (-60, 60)})
    async with connected(emu, envelope, spy=spy) as arm:
        assert_joints(await arm.move_joints(j1=40), (40, 0, 0, 0, 0, 0))
        await arm.home()
        mark = spy.mark()
        assert_joints(await arm.move_joints(j1=45, relative=True), (45, 0, 0, 0, 0, 0))
        written = spy.since(mark)
        line = stated(gcode.move_joints(45, relative=True), mode=False)
        assert b"?" in written[: written.index(line)]  # a fresh status, then the line


@emulated
async def test_a_failed_move_does_not_shift_the_predicted_position(
    emu: EmulatorProcess, spy: EnvelopeSpy, profile: str
) -> None:
    envelope = Envelope(joints={1: (-60, 60)})
    async with connected(emu, envelope, unlock=False, spy=spy) as arm:
        # Every profile powers on locked: 2021/2024 answer "Alarm lock", classic "ok" but dropped.
        with pytest.raises(MotionRefusedError if profile == "classic" else MirobotAlarmError):
            await arm.move_joints(j1=40)
        await arm.unlock()
        # From 0 (where the arm is), not from 40 (where the refused line would have taken it).
        assert_joints(await arm.move_joints(j1=50, relative=True), (50, 0, 0, 0, 0, 0))


@emulated
async def test_the_position_is_read_again_after_an_unchecked_move(
    emu: EmulatorProcess, spy: EnvelopeSpy, caplog: pytest.LogCaptureFixture
) -> None:
    envelope = Envelope(joints={1: (-60, 60)})
    async with connected(emu, envelope, spy=spy) as arm:
        with caplog.at_level(logging.WARNING, logger="mirobot_async"):
            await arm.send("M21 G90 G0 X75", check_envelope=False)
        await arm.wait_idle()
        # The client could not follow that line: it reads the arm's position (75) again.
        await assert_refused(
            arm,
            spy,
            lambda: arm.move_joints(j1=-5, relative=True),
            "j1=",  # 70 up to the whole motor steps of the read position
            "J1 range",
            reads_position=True,
        )
        assert_joints(await arm.move_joints(j1=-20, relative=True), (55, 0, 0, 0, 0, 0))


# ---- raw lines ----------------------------------------------------------------------------------


@emulated
async def test_raw_lines_that_move_the_arm_are_parsed_and_checked(
    emu: EmulatorProcess, spy: EnvelopeSpy
) -> None:
    envelope = Envelope(z=(100, None), joints={1: (-60, 60)})
    async with connected(emu, envelope, spy=spy) as arm:
        # The distance mode is unknown after connecting: a line must state it.
        await assert_refused(
            arm, spy, lambda: arm.send("G0 X10"), "distance mode (G90/G91)", "unknown"
        )
        await arm.send("M21 G90 G0 X10")
        await assert_refused(arm, spy, lambda: arm.send("G0 X70"), "j1=70.000", "send('G0 X70')")
        assert await arm.send("G91") == ()  # modes are tracked over every line
        assert await arm.send("G0 X45") == ()  # 10 + 45
        await assert_refused(arm, spy, lambda: arm.send("G0 X10"), "j1=65.000")
        await arm.wait_idle()  # at rest: the M20 below restarts from where the moves end
        await assert_refused(arm, spy, lambda: arm.send("M20 G90 G0 Z50"), "minimum z=100 mm")
        await assert_refused(arm, spy, lambda: arm.send("$J=G91 X1 F100", validate=False), "jog")
        assert await arm.send("M3 S500") == ()  # lines that do not move pass
        report = await arm.wait_idle()
        assert_joints(report, (55, 0, 0, 0, 0, 0))
        assert report.pump_pwm == 500


# ---- streams ------------------------------------------------------------------------------------


@emulated
@pytest.mark.parametrize("continue_on_error", [False, True])
async def test_a_stream_stops_before_the_line_that_leaves_the_envelope(
    emu: EmulatorProcess, spy: EnvelopeSpy, continue_on_error: bool
) -> None:
    envelope = Envelope(joints={1: (-60, 60)})
    lines = ["M21 G91 G0 X20", "G0 X20", "G0 X30", "G0 X-10"]  # 20, 40, 70 (refused), 60
    async with connected(emu, envelope, spy=spy) as arm:
        mark, sent = spy.mark(), arm.stats.lines_sent
        result = await arm.stream(lines, continue_on_error=continue_on_error)
        assert result.sent == 2 and result.acknowledged == 2
        assert result.stopped and not result.ok
        [failed] = result.errors
        assert failed.number == 3 and failed.line == "G0 X30"
        assert isinstance(failed.error, MirobotUsageError)
        assert "stream line 3 'G0 X30'" in str(failed.error)
        assert "j1=70.000" in str(failed.error)
        with pytest.raises(MirobotUsageError):
            result.raise_for_errors()
        assert arm.stats.lines_sent == sent + 2
        assert spy.lines_since(mark) == [b"M21 G91 G0 X20\n", b"G0 X20\n"]
        assert_joints(await arm.wait_idle(), (40, 0, 0, 0, 0, 0))


@emulated
async def test_a_stream_iterated_reports_the_refused_line(emu: EmulatorProcess) -> None:
    envelope = Envelope(joints={1: (-60, 60)})
    async with connected(emu, envelope) as arm:
        seen: list[LineResult] = []
        async for line_result in arm.stream(["M21 G90 G0 X50", "G0 X61", "G0 X0"]):
            seen.append(line_result)
        assert [r.number for r in seen] == [1, 2]
        assert seen[0].ok and isinstance(seen[1].error, MirobotUsageError)
        assert_joints(await arm.wait_idle(), (50, 0, 0, 0, 0, 0))


# ---- the opt-out --------------------------------------------------------------------------------


@emulated
async def test_opting_out_is_loud_and_sends(
    emu: EmulatorProcess, spy: EnvelopeSpy, caplog: pytest.LogCaptureFixture
) -> None:
    envelope = Envelope(joints={1: (-60, 60)})
    async with connected(emu, envelope, spy=spy) as arm:
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="mirobot_async"):
            mark = spy.mark()
            await arm.send("M21 G90 G0 X70", check_envelope=False)
            assert spy.lines_since(mark) == [b"M21 G90 G0 X70\n"]
        [record] = [r for r in caplog.records if r.levelno == logging.WARNING]
        message = record.getMessage()
        assert "send('M21 G90 G0 X70')" in message
        assert "WITHOUT the safety envelope check" in message
        assert "would have refused it" in message and "J1 range" in message
        assert_joints(await arm.wait_idle(), (70, 0, 0, 0, 0, 0))

        caplog.clear()  # every unchecked call warns, even for a line inside
        with caplog.at_level(logging.WARNING, logger="mirobot_async"):
            await arm.send("M21 G90 G0 X30", check_envelope=False)
        [record] = [r for r in caplog.records if r.levelno == logging.WARNING]
        assert "send('M21 G90 G0 X30') was sent WITHOUT" in record.getMessage()

        await arm.move_joints(j1=30)  # checked: the client knows the position again
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="mirobot_async"):
            result = await arm.stream(["M21 G90 G0 X10", "G0 X80", "G0 X20"], check_envelope=False)
        assert result.ok and result.sent == 3
        warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
        assert len(warnings) == 2
        assert "stream(check_envelope=False)" in warnings[0]
        assert "stream line 2 'G0 X80'" in warnings[1] and "would have refused" in warnings[1]
        assert_joints(await arm.wait_idle(), (20, 0, 0, 0, 0, 0))


# ---- the firmware's geometry --------------------------------------------------------------------


@emulated
async def test_a_classic_arm_gets_the_classic_geometry(
    emu: EmulatorProcess, spy: EnvelopeSpy, profile: str
) -> None:
    # The tool point at home: z = 230.72 mm (2021), 181 mm (classic).
    envelope = Envelope(z=(None, 200))
    async with connected(emu, envelope, spy=spy) as arm:
        assert arm.firmware == profile  # detected at connect ($$) because of the envelope
        assert arm.envelope is not None
        if profile == "classic":
            assert arm.envelope.dh == DH_CLASSIC
            assert_joints(await arm.move_joints(j1=10), (10, 0, 0, 0, 0, 0))
        else:
            assert arm.envelope is envelope and envelope.dh == DH_2021
            await assert_refused(arm, spy, lambda: arm.move_joints(j1=10), "maximum z=200 mm")


# ---- hypothesis: random targets and paths against a fake robot ----------------------------------

FAKE_STATUS = (
    b"<Idle,Angle(ABCDXYZ):0.000,0.000,0.000,0.000,0.000,0.000,0.000,"
    b"Cartesian coordinate(XYZ RxRyRz):198.670,0.000,230.720,0.000,0.000,0.000,"
    b"Pump PWM:0,Valve PWM:0,Motion_MODE:0>\r\n"
)
START_JOINTS = (0.0,) * 6
START_POSE = (198.67, 0.0, 230.72, 0.0, 0.0, 0.0)
BOX = {"x": (120.0, 260.0), "y": (-150.0, 150.0), "z": (120.0, 300.0)}
NARROW = {1: (-70.0, 70.0), 2: (-20.0, 60.0), 3: (-90.0, 40.0), 5: (-120.0, 30.0)}
PROPERTY_ENVELOPE = Envelope(x=BOX["x"], y=BOX["y"], z=BOX["z"], joints=NARROW)
LIMITS = PROPERTY_ENVELOPE.joint_limits


# What the envelope reads before the first move: the settings (base offset, $35, soft limits
# off), the stored startup lines (none) and the work offsets (zero).
_ZERO_ROW = b"0.000,0.000,0.000,0.000,0.000,0.000,0.000]\r\n"
FAKE_ANSWERS = {
    b"$$": b"".join(
        b"$%d=%s\r\n" % (n, v)
        for n, v in [(20, b"0"), (35, b"1"), (41, b"0.000"), (42, b"0.000"), (43, b"0.000")]
        + [(n, b"100.000") for n in (*range(130, 137), *range(140, 147))]
    ),
    b"$N": b"$N0=\r\n$N1=\r\n",
    b"$#": b"".join(b"[G%d:" % n + _ZERO_ROW for n in (54, 55, 56, 57, 58, 59, 28, 30, 92)),
    b"$G": b"[G0 G54 G17 G21 G90 G94 M0 M5 M9 T0 F200. S0.]\r\n",
}


class FakeRobot:
    """Answers ``?`` with an Idle status at home and every line with ``ok``; records lines."""

    def __init__(self) -> None:
        self.received = bytearray()
        self.server: asyncio.Server | None = None

    async def __aenter__(self) -> str:
        self.server = await asyncio.start_server(self._serve, "127.0.0.1", 0)
        port = self.server.sockets[0].getsockname()[1]
        return f"socket://127.0.0.1:{port}"

    async def __aexit__(self, *exc_info: object) -> None:
        assert self.server is not None
        self.server.close()
        await self.server.wait_closed()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        line = bytearray()
        with contextlib.suppress(ConnectionError):
            while data := await reader.read(4096):
                self.received += data
                for byte in data:
                    if byte == ord("?"):
                        writer.write(FAKE_STATUS)
                    elif byte == ord("\n"):
                        writer.write(FAKE_ANSWERS.get(bytes(line), b""))
                        writer.write(b"ok\r\n")
                        line.clear()
                    else:
                        line.append(byte)
        writer.close()


def box_excess(points: np.ndarray) -> float:
    """How far (mm) the farthest of ``points`` (N, 3) lies outside the box (<= 0: inside)."""
    lo = np.array([BOX[a][0] for a in "xyz"])
    hi = np.array([BOX[a][1] for a in "xyz"])
    return float(np.max(np.maximum(lo - points, points - hi)))


def limit_excess(q: tuple[float, ...] | np.ndarray) -> float:
    """How far (deg) the joint farthest out of the envelope's ranges is out (<= 0: inside)."""
    return float(max(max(lo - v, v - hi) for v, (lo, hi) in zip(q, LIMITS, strict=True)))


def joint_move_verdict(target: tuple[float, ...]) -> bool | None:
    """True: must be refused; False: must be sent; None: too close to a bound to say.

    Independent of the envelope's own sampling: the joint-space path from home is sampled so
    densely that the tool point moves at most 0.2 mm between samples.
    """
    q0, q1 = np.array(START_JOINTS), np.array(target)
    # 450 mm bounds the tool point's distance from any joint axis: 0.2 mm per step at most.
    n = max(2, math.ceil(float(np.abs(q1 - q0).sum()) * math.pi / 180 * 450 / 0.2))
    t = np.linspace(0.0, 1.0, n + 1)[:, None]
    path = forward_many(q0[None, :] + t * (q1 - q0)[None, :], DH_2021)[:, :3]
    target_point = np.array([forward(target, DH_2021)[:3]])
    target_out = max(limit_excess(target), box_excess(target_point))
    path_out = box_excess(path)
    if target_out > 1e-3 or path_out > PROPERTY_ENVELOPE.path_step_mm:
        return True  # outside (a path dip deeper than the sampling limit is always caught)
    if target_out < -0.01 and path_out < -0.5:
        return False
    return None


def linear_move_verdict(target: tuple[float, float, float]) -> bool | None:
    """As :func:`joint_move_verdict` for a straight line from home to ``target`` (x, y, z)."""
    end = np.array(target)
    if box_excess(end[None, :]) > 1e-3:
        return True
    try:
        q_end = inverse((*target, 0.0, 0.0, 0.0), DH_2021, "firmware")
    except MirobotUsageError:
        return True  # an unreachable target
    if limit_excess(q_end) > 1e-3:
        return True  # the target needs joints outside the envelope's ranges
    # Inside for sure when every point of the line, sampled every 0.25 mm, is reachable with
    # joints well inside the ranges (a shallower excursion between the envelope's own samples,
    # path_step_mm apart, may pass: documented).
    start = np.array(START_POSE[:3])
    n = max(2, math.ceil(float(np.linalg.norm(end - start)) / 0.25))
    for t in np.linspace(0.0, 1.0, n + 1)[1:]:
        point = (start + t * (end - start)).tolist()
        try:
            q = inverse((*point, 0.0, 0.0, 0.0), DH_2021, "firmware")
        except MirobotUsageError:
            return None
        if limit_excess(q) > -0.5:
            return None
    return False if box_excess(end[None, :]) < -0.5 else None


def rounded(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False).map(lambda v: round(v, 3))


# Half anywhere in the firmware's ranges (mostly outside the envelope), half near home (mostly
# inside), so that both outcomes are exercised.
joint_targets = st.one_of(
    st.tuples(*(rounded(max(lo, -120.0), min(hi, 120.0)) for lo, hi in JOINT_LIMITS)),
    st.tuples(*(rounded(-30.0, 30.0) for _ in JOINT_LIMITS)),
)
linear_targets = st.one_of(
    st.tuples(rounded(60.0, 320.0), rounded(-220.0, 220.0), rounded(60.0, 360.0)),
    st.tuples(rounded(140.0, 250.0), rounded(-120.0, 120.0), rounded(140.0, 280.0)),
)


async def attempt(call: Callable[[Mirobot], Awaitable[object]]) -> tuple[bool, bytes, int]:
    """Connect to a fresh fake robot, run ``call``: (refused, line bytes written, refusals)."""
    robot = FakeRobot()
    async with (
        robot as url,
        Mirobot.connect(url, envelope=PROPERTY_ENVELOPE, firmware="2021") as arm,
    ):
        await arm.detect_firmware()  # the envelope reads $$, $N and $# before the first move
        before = len(robot.received)
        refused = False
        try:
            await call(arm)
        except MirobotUsageError as err:
            assert str(err).startswith("refused by the safety envelope")
            refused = True
        await wait_until(
            lambda: arm.stats.bytes_sent == len(robot.received), 5, "every byte written read"
        )
        written = bytes(robot.received[before:])
        return refused, written, arm.stats.envelope_refusals


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(target=joint_targets, relative=st.booleans())
def test_property_joint_targets_outside_are_refused_inside_sent_unchanged(
    target: tuple[float, ...], relative: bool
) -> None:
    # From home (all zero) a relative target is the same numbers as an absolute one.
    def call(arm: Mirobot) -> Awaitable[object]:
        return arm.move_joints(*target, relative=relative, wait=False)

    refused, written, refusals = asyncio.run(attempt(call))
    expected = joint_move_verdict(target)
    event(f"refused={refused}, oracle={expected}")
    if refused:
        assert written == b"", "a refused move wrote bytes"
        assert refusals == 1
        assert expected is not False, f"an inside move was refused: {target}"
    else:
        assert written == stated(gcode.move_joints(*target, relative=relative), mode=False)
        assert expected is not True, f"an outside move was sent: {target}"


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(target=linear_targets, relative=st.booleans())
def test_property_linear_paths_outside_are_refused_inside_sent_unchanged(
    target: tuple[float, float, float], relative: bool
) -> None:
    words = (
        tuple(round(v - s, 3) for v, s in zip(target, START_POSE, strict=False))
        if relative
        else target
    )
    goal = tuple(s + w for s, w in zip(START_POSE, words, strict=False)) if relative else target

    def call(arm: Mirobot) -> Awaitable[object]:
        return arm.move_pose(*words, linear=True, speed=3000, relative=relative, wait=False)

    refused, written, _ = asyncio.run(attempt(call))
    expected = linear_move_verdict((goal[0], goal[1], goal[2]))
    event(f"refused={refused}, oracle={expected}")
    if refused:
        assert written == b""
        assert expected is not False, f"an inside path was refused: {goal}"
    else:
        assert written == stated(
            gcode.move_pose(*words, linear=True, speed=3000, relative=relative)
        )
        assert expected is not True, f"an outside path was sent: {goal}"
