"""The emulator's fast paths give exactly what the general code gives (the emulator is judged
byte for byte against the firmware, so a shortcut may save time, never change a bit)."""

from __future__ import annotations

import itertools
import math

from mirobot_emulator.firmware._geometry import Geometry
from mirobot_emulator.firmware._scanner import _read_float_digits, _scan, read_float, scan
from mirobot_emulator.motion import AxisLimits, joint_block
from mirobot_emulator.motion._axes import round_half_away, vec7
from mirobot_emulator.settings import default_settings


def test_read_float_agrees_with_grbls_digit_by_digit_reading() -> None:
    alphabet = "0123456789.-+X"
    texts = ["".join(p) for n in range(5) for p in itertools.product(alphabet, repeat=n)]
    texts += ["123456789", "0.000000001", "-12345.678901", "99999999.9", "1.2.3", "-.5", "+0"]
    for text in texts:
        for start in range(len(text) + 1):
            fast, slow = read_float(text, start), _read_float_digits(text, start)
            assert fast == slow, (text, start)
            if fast is not None and slow is not None:
                assert math.copysign(1.0, fast[0]) == math.copysign(1.0, slow[0]), (text, start)


def test_to_steps_is_the_rounding_of_every_axis_whatever_was_asked_before() -> None:
    limits = Geometry("classic", default_settings("classic")).limits()
    assert limits.steps is not None
    q = (10.0, -20.5, 0.00881, -0.00881, 359.99, -0.0, 1e-300)
    expected = tuple(round_half_away(x * s) for x, s in zip(q, limits.steps, strict=True))
    assert limits.to_steps(q) == expected
    other = (1.0,) * 7
    assert limits.to_steps(other) != expected
    assert limits.to_steps(q) == expected
    as_list = list(q)
    assert limits.to_steps(as_list) == expected
    as_list[0] = 0.0
    assert limits.to_steps(as_list)[0] == 0


def test_vec7_returns_floats_and_keeps_a_tuple_of_floats() -> None:
    q = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0)
    assert vec7(q) is q
    mixed = vec7((1, 2.0, 3, 4, 5, 6, 7))
    assert all(type(x) is float for x in mixed)
    assert mixed == q


def test_a_block_from_rest_shares_its_nominal_profile_but_not_for_negative_zero() -> None:
    limits = AxisLimits.from_settings(default_settings("2021"))
    block = joint_block((0.0,) * 7, (10.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), 2000.0, limits)
    assert block.profile_from(0.0) is block.profile
    fresh = block.profile_from(-0.0)
    assert fresh is not block.profile
    assert fresh.duration == block.profile.duration


def test_switch_steps_is_a_fresh_list_each_time() -> None:
    geometry = Geometry("classic", default_settings("classic"))
    first = geometry.switch_steps()
    first.clear()
    assert len(geometry.switch_steps()) == 3


def test_a_line_scanned_again_gives_the_same_words_in_a_block_of_its_own() -> None:
    first, status = scan("M21G90G01X5.5F2000", "classic")
    assert status == 0
    assert first == _scan("M21G90G01X5.5F2000", "classic")[0]
    first.words["X"] = 99.0  # a caller's change stays in its own block
    again, _ = scan("M21G90G01X5.5F2000", "classic")
    assert again is not first
    assert again.words == {"X": 5.5, "F": 2000.0}
    assert again.coord_mode == 21 and again.motion == 1 and again.distance == 90
    assert scan("G1X", "2021")[1] == _scan("G1X", "2021")[1] != 0


def test_a_blocks_nominal_profile_is_the_trapezoid_from_rest() -> None:
    from mirobot_emulator.motion._profile import trapezoid

    limits = AxisLimits.from_settings(default_settings("classic"))
    end = (10.0, 5.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    first = joint_block((0.0,) * 7, end, 2000.0, limits)
    fresh = trapezoid(0.0, first.length, 0.0, 0.0, first.speed, first.accel)
    assert first.profile.phases() == fresh.phases()
    assert (first.profile.s_end, first.profile.v_end) == (fresh.s_end, fresh.v_end)
