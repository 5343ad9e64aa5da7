"""Moves, paths and raw-line validation of the client over the real emulator.

* ``move_pose(wait=True)`` completes when the 2021 base offset ``$41..$43`` is not zero;
* ``send()``/``stream()`` refuse what :func:`mirobot_async.validation.check_line` flags, before
  writing a byte (issue 15 item 3);
* ``move_path``/``move_joint_path`` (issue 12 item 2).
"""

from __future__ import annotations

import logging

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mirobot_async import InvalidLineError, Mirobot, MirobotUsageError
from mirobot_async.testing import EmulatorProcess, WireSpy
from mirobot_async.validation import ModalState, check_line

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
