"""The emulator's shortcuts for joint moves in whole steps give what the general code gives: a
block built from whole steps is the block built from its ends, and a
block shared by a move made again runs as often as it is queued, and the soft-limit check
without its loop names the axis the loop names."""

from __future__ import annotations

import math
import random

from mirobot_emulator import motion
from mirobot_emulator.firmware._geometry import Geometry
from mirobot_emulator.motion import AxisLimits, Block, joint_block, joint_block_in_steps
from mirobot_emulator.settings import default_settings


def _limits(profile: str) -> AxisLimits:
    return Geometry(profile, default_settings(profile)).limits()


def _vec7(values: list[float]) -> tuple[float, float, float, float, float, float, float]:
    return (values[0], values[1], values[2], values[3], values[4], values[5], values[6])


def _block_fields(block: Block) -> tuple[object, ...]:
    names = ("kind", "start", "end", "length", "speed", "accel", "direction_in", "direction_out",
             "junction_deviation", "start_steps", "delta_steps", "timed", "duration")  # fmt: skip
    return tuple(getattr(block, name) for name in names)


def test_a_joint_block_from_whole_steps_is_the_block_from_its_ends() -> None:
    rng = random.Random(11)
    for profile in ("classic", "2021"):
        limits = _limits(profile)
        for _ in range(300):
            a = _vec7([rng.uniform(-120.0, 120.0) for _ in range(7)])
            b = _vec7([x + rng.choice((0.0, rng.uniform(-30.0, 30.0))) for x in a])
            feed = rng.choice((None, 2000.0, 1e-9, 5e5))
            general = joint_block(a, b, feed, limits)
            fast = joint_block_in_steps(limits.to_steps(a), limits.to_steps(b), feed, limits)
            assert _block_fields(fast) == _block_fields(general)
            for s in (0.0, general.length / 3, general.length):
                assert fast.position_at(s) == general.position_at(s)


def test_a_move_made_again_shares_its_block_and_runs_as_often_as_queued() -> None:
    limits = _limits("classic")
    there, back = (10.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), motion.ZERO
    first = joint_block(back, there, 2000.0, limits)
    again = joint_block(back, there, 2000.0, limits)
    assert again is first  # shared: a block never changes once built
    other_limits = _limits("classic")  # other limits (settings changed): built anew
    assert joint_block(back, there, 2000.0, other_limits) is not first
    planner = motion.Planner(motion.ZERO)
    for _ in range(3):
        planner.push(joint_block(planner.planned_position, there, 2000.0, limits))
        planner.push(joint_block(planner.planned_position, back, 2000.0, limits))
    assert len(planner.blocks) == 6
    planner.advance(math.inf)
    assert not planner.busy
    assert planner.position == limits.quantise(back)
    assert planner.finished == 6


def _soft_violation_by_loop(settings: dict[int, float], q: tuple[float, ...]) -> str | None:
    if settings[20] == 0:
        return None
    for k, letter in enumerate("ABCDXYZ"):  # firmware axes a..g = J4, J5, J6, D, J1, J2, J3
        value = q[(3, 4, 5, 6, 0, 1, 2)[k]]
        if value > settings[130 + k] or value < -settings[140 + k]:
            return letter
    return None


def test_the_soft_limit_check_names_the_first_axis_out_of_range_in_firmware_order() -> None:
    rng = random.Random(5)
    for profile in ("classic", "2021"):
        settings = dict(default_settings(profile))
        settings[20] = 1.0
        geometry = Geometry(profile, settings)
        for _ in range(2000):
            q = tuple(rng.choice((rng.uniform(-200.0, 200.0), 0.0, math.nan)) for _ in range(7))
            assert geometry.soft_violation(q) == _soft_violation_by_loop(settings, q), q
        settings[133] = math.nan  # a range that compares false
        q = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 5.0)
        assert geometry.soft_violation(q) == _soft_violation_by_loop(settings, q)
