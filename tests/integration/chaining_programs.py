"""Random programs of joint and Cartesian moves for the chaining property tests (emulator and
firmware oracle): absolute and relative, ``G0`` and ``G1``, with or without the mode word
(``M20``/``M21``) repeated on every line, and the helpers that run one streamed or stepped.

A program starts from the zero pose with its modes stated in its first line. Targets stay small
(a few degrees, a few mm) so that every line is reachable and the runs are short.
"""

from __future__ import annotations

from collections.abc import Sequence

from hypothesis import strategies as st

from mirobot_async import Mirobot, MotionChainError, StatusReport
from mirobot_async.kinematics import DH_2021, DH_CLASSIC, forward

ZERO_LINE = "M21 G90 G0 X0 Y0 Z0 A0 B0 C0"
"""Back to the zero pose (at rest, so its M21 restarts from where the arm is)."""

_ANGLE = st.integers(-8, 8)
_STEP = st.sampled_from((-4, -3, -2, -1, 1, 2, 3, 4))


def _number(value: float) -> str:
    text = f"{value:.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


@st.composite
def _joint_line(draw: st.DrawFn) -> tuple[bool, str]:
    relative = draw(st.booleans())
    axes = draw(st.lists(st.sampled_from("XYZ"), min_size=1, max_size=3, unique=True))
    values = [draw(_STEP if relative else _ANGLE) for _ in axes]
    words = " ".join(f"{a}{v}" for a, v in zip(sorted(axes), values, strict=True))
    motion = draw(st.sampled_from(("G0", "G1 F2000")))
    return False, f"{'G91' if relative else 'G90'} {motion} {words}"


@st.composite
def _pose_line(draw: st.DrawFn, profile: str) -> tuple[bool, str]:
    relative = draw(st.booleans())
    if relative:
        axes = draw(st.lists(st.sampled_from("XYZ"), min_size=1, max_size=3, unique=True))
        words = " ".join(f"{a}{draw(_STEP) * 2}" for a in sorted(axes))
    else:  # a whole pose: the forward kinematics of small joint angles
        joints = [draw(_ANGLE) for _ in range(3)]
        pose = forward((*joints, 0.0, 0.0, 0.0), DH_2021 if profile == "2021" else DH_CLASSIC)
        words = " ".join(f"{a}{_number(v)}" for a, v in zip("XYZABC", pose, strict=True))
    motion = draw(st.sampled_from(("G0", "G1 F2000")))
    return True, f"{'G91' if relative else 'G90'} {motion} {words}"


@st.composite
def programs(draw: st.DrawFn, profile: str) -> list[str]:
    """2..5 moves, each maybe preceded by ``G4 P0``; mode words on every line (``repeat``) or
    only where the mode changes."""
    repeat = draw(st.booleans())
    count = draw(st.integers(2, 5))
    lines: list[str] = []
    mode: bool | None = None
    for _ in range(count):
        if lines and draw(st.integers(0, 5)) == 0:
            lines.append("G4 P0")
        cartesian, body = draw(st.one_of(_joint_line(), _pose_line(profile)))
        stated = repeat or mode is not cartesian
        lines.append(f"{'M20' if cartesian else 'M21'} {body}" if stated else body)
        mode = cartesian
    return lines


def joints_of(report: StatusReport) -> tuple[float, ...]:
    return (*report.joints, report.rail or 0.0)


async def to_zero(arm: Mirobot) -> None:
    """Stop, then go back to the zero pose with the modes restated at rest."""
    await arm.wait_idle()
    await arm.send(ZERO_LINE)
    await arm.wait_idle()


async def stepped(arm: Mirobot, program: Sequence[str]) -> StatusReport:
    """Each line after the arm stopped (``wait_idle``); where the arm ends."""
    await to_zero(arm)
    for line in program:
        await arm.send(line, validate=False)
        await arm.wait_idle()
    return await arm.wait_idle()


async def streamed(arm: Mirobot, program: Sequence[str]) -> StatusReport | MotionChainError:
    """``stream(program, wait=True)``: where the arm ends, or the refusal (nothing written)."""
    await to_zero(arm)
    sent_before, firmware_before = arm.stats.lines_sent, arm.firmware
    result = await arm.stream(list(program), wait=True)
    if result.errors and isinstance(result.errors[0].error, MotionChainError):
        # (a list only one profile refuses makes the client learn the profile first: "$$")
        learnt = firmware_before is None and arm.firmware is not None
        assert result.sent == 0, "refused after a byte"
        assert arm.stats.lines_sent == sent_before + learnt, "refused after a byte"
        return result.errors[0].error
    assert result.ok, result.errors
    return await arm.wait_idle()
