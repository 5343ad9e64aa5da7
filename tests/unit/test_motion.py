"""Unit tests of mirobot_emulator.motion: trapezoidal timing, coordination, the 17-block planner
(GRBL's 18-slot ring keeps one slot free; the oracle acknowledges 17 motion lines, then waits).

These limits have no ``$11`` and no steps: blocks stop at every junction and positions are
exact, so the from-rest timing is checked by hand here; look-ahead, steps and blending are in
test_planner_lookahead.py.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirobot_emulator.motion import (
    AXES,
    SEQUENTIAL_SEARCH_FRACTION,
    ZERO,
    AxisLimits,
    Block,
    HomeSearchBlock,
    Planner,
    PlannerFull,
    Vec7,
    dwell_block,
    homing_blocks,
    joint_block,
    joints_to_letters,
    letters_to_joints,
    path_block,
)

# Defaults of PROTOCOL.md section 7, letter order a..g = J4, J5, J6, D, J1, J2, J3.
RATES_2021 = (1800.0, 1500.0, 2500.0, 500.0, 1800.0, 1500.0, 1800.0)
RATES_CLASSIC = (1800.0, 1500.0, 2500.0, 500.0, 2000.0, 2000.0, 2000.0)


def settings_for(rates: tuple[float, ...], accel: float = 50.0) -> dict[int, float]:
    out = {110 + k: r for k, r in enumerate(rates)}
    out.update({120 + k: accel for k in range(AXES)})
    return out


LIMITS_2021 = AxisLimits.from_settings(settings_for(RATES_2021))
LIMITS_CLASSIC = AxisLimits.from_settings(settings_for(RATES_CLASSIC))


def vec(*values: float) -> Vec7:
    v = [0.0] * AXES
    v[: len(values)] = values
    return (v[0], v[1], v[2], v[3], v[4], v[5], v[6])


def closed_form(length: float, speed: float, accel: float) -> float:
    if length >= speed * speed / accel:
        return length / speed + speed / accel
    return 2.0 * math.sqrt(length / accel)


# ---- strategies ------------------------------------------------------------------------------

coord = st.floats(-300.0, 300.0, allow_nan=False)
vec7s = st.tuples(coord, coord, coord, coord, coord, coord, coord)
limit_sets = st.builds(
    AxisLimits,
    st.tuples(*[st.floats(100.0, 5000.0)] * AXES),
    st.tuples(*[st.floats(5.0, 500.0)] * AXES),
)
feeds = st.one_of(st.none(), st.floats(10.0, 10000.0))


# ---- settings order and limits ---------------------------------------------------------------


def test_settings_are_converted_from_letter_order() -> None:
    # $114 is J1, $110 is J4, $113 the rail.
    assert LIMITS_2021.max_rate == (1800.0, 1500.0, 1800.0, 1800.0, 1500.0, 2500.0, 500.0)
    assert LIMITS_CLASSIC.max_rate[0] == 2000.0
    q = vec(1, 2, 3, 4, 5, 6, 7)
    assert joints_to_letters(q) == (4.0, 5.0, 6.0, 7.0, 1.0, 2.0, 3.0)
    assert letters_to_joints(joints_to_letters(q)) == q


def test_settings_of_zero_are_clamped_and_bad_limits_rejected() -> None:
    limits = AxisLimits.from_settings(settings_for((0.0, -5.0, *RATES_2021[2:]), accel=0.0))
    assert min(limits.max_rate) > 0.0
    assert min(limits.accel) > 0.0
    with pytest.raises(ValueError):
        AxisLimits(vec(1, 1, 1, 1, 1, 1, 0), vec(1, 1, 1, 1, 1, 1, 1))
    with pytest.raises(ValueError):
        AxisLimits(vec(1, 1, 1, 1, 1, 1, 1), vec(1, 1, 1, 1, 1, 1, math.nan))


# ---- timing model by hand --------------------------------------------------------------------


def test_g0_j1_90_degrees_2021_by_hand() -> None:
    # $114 = 1800 deg/min = 30 deg/s, accel 50 deg/s^2: accelerating takes 0.6 s over 9 deg,
    # decelerating the same, cruise 72 deg at 30 deg/s = 2.4 s. Total 3.6 s = 90/30 + 30/50.
    block = joint_block(ZERO, vec(90), None, LIMITS_2021)
    assert block.kind == "move"
    assert block.speed == pytest.approx(30.0)
    assert block.accel == pytest.approx(50.0)
    assert block.duration == pytest.approx(3.6, abs=1e-12)
    assert block.position_at_time(0.6) == pytest.approx(vec(9.0))
    assert block.position_at_time(1.8) == pytest.approx(vec(45.0))
    assert block.position_at_time(3.0) == pytest.approx(vec(81.0))


def test_g0_j1_90_degrees_classic_by_hand() -> None:
    # $114 = 2000 deg/min = 33.33 deg/s: 90 / 33.33 + 33.33 / 50 = 2.7 + 0.6667.
    block = joint_block(ZERO, vec(90), None, LIMITS_CLASSIC)
    assert block.duration == pytest.approx(2.7 + 2.0 / 3.0, abs=1e-12)


def test_g0_two_axes_limited_by_the_slowest_ratio() -> None:
    # J1 90 and J2 45 (2021: 30 and 25 deg/s). J1 is limiting: it runs at exactly 30 deg/s and
    # 50 deg/s^2, so the move takes as long as J1 alone: 3.6 s. J2 runs at 15 deg/s.
    block = joint_block(ZERO, vec(90, 45), None, LIMITS_2021)
    assert block.length == pytest.approx(math.hypot(90, 45))
    assert block.speed * 90 / block.length == pytest.approx(30.0)
    assert block.accel * 90 / block.length == pytest.approx(50.0)
    assert block.duration == pytest.approx(3.6, abs=1e-12)


def test_feed_is_along_the_joint_vector_and_reduced_by_max_rates() -> None:
    # F600 = 10 deg/s on one axis: 30/10 + 10/50 = 3.2 s.
    assert joint_block(ZERO, vec(30), 600.0, LIMITS_2021).duration == pytest.approx(3.2, abs=1e-12)
    # J1 30, J2 40 (length 50) at F1200 = 20 deg/s along the vector: J1 12, J2 16 deg/s.
    block = joint_block(ZERO, vec(30, 40), 1200.0, LIMITS_2021)
    assert block.speed == pytest.approx(20.0)
    # F3000 = 50 deg/s would drive J2 at 40 deg/s > 25 (1500 deg/min): reduced to 25 / 0.8.
    block = joint_block(ZERO, vec(30, 40), 3000.0, LIMITS_2021)
    assert block.speed == pytest.approx(31.25)
    # G0 on the rail: 500 mm/min = 8.33 mm/s over 100 mm: 12 s + 1/6 s.
    rail = joint_block(ZERO, vec(0, 0, 0, 0, 0, 0, 100), None, LIMITS_2021)
    assert rail.duration == pytest.approx(12.0 + 1.0 / 6.0, abs=1e-12)


def test_triangle_for_short_moves() -> None:
    # 5 deg < 30^2 / 50 = 18 deg: never reaches 30 deg/s. T = 2 sqrt(5 / 50).
    block = joint_block(ZERO, vec(5), None, LIMITS_2021)
    assert block.duration == pytest.approx(2.0 * math.sqrt(0.1), abs=1e-12)
    assert block.position_at_time(block.duration / 2) == pytest.approx(vec(2.5))


@given(
    st.floats(1e-3, 2000.0),
    st.floats(1.0, 10000.0),
    st.floats(1.0, 1000.0),
)
def test_duration_equals_closed_form(distance: float, feed: float, accel: float) -> None:
    limits = AxisLimits(vec(*[1e6] * AXES), vec(*[accel] * AXES))
    block = joint_block(ZERO, vec(0, 0, distance), feed, limits)
    assert block.speed == pytest.approx(feed / 60.0)
    assert block.duration == pytest.approx(closed_form(distance, feed / 60, accel), abs=1e-9)
    assert block.position_at_time(block.duration) == vec(0, 0, distance)


def test_zero_length_move_and_invalid_feeds() -> None:
    block = joint_block(vec(1, 2), vec(1, 2), None, LIMITS_2021)
    assert block.length == 0.0
    assert block.duration == 0.0
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError):
            joint_block(ZERO, vec(1), bad, LIMITS_2021)
    with pytest.raises(ValueError):
        joint_block(ZERO, vec(math.nan), None, LIMITS_2021)


# ---- coordination and limits, by numerical differentiation -----------------------------------


def check_block_kinematics(block: Block, limits: AxisLimits, steps: int = 300) -> None:
    """Sample the nominal profile; check rates, accelerations, monotony and the end points."""
    duration = block.duration
    h = duration / steps
    qs = [block.position_at_time(duration * k / steps) for k in range(steps)]
    qs.append(block.position_at_time(duration))
    assert qs[0] == block.start
    assert qs[-1] == block.end
    scale = max(1.0, *(abs(x) for q in qs for x in q))
    noise = 16 * 2.2e-16 * scale
    for i in range(AXES):
        rate = limits.max_rate[i] / 60.0
        acc = limits.accel[i]
        direction = block.end[i] - block.start[i]
        for k in range(steps):
            step = qs[k + 1][i] - qs[k][i]
            assert step * direction >= -noise, "an axis moved away from its target"
            assert abs(step) <= rate * h * (1 + 1e-9) + noise
        for k in range(steps - 1):
            second = qs[k + 2][i] - 2 * qs[k + 1][i] + qs[k][i]
            assert abs(second) <= acc * h * h * (1 + 1e-6) + 4 * noise


@settings(max_examples=60)
@given(vec7s, vec7s, feeds, limit_sets)
def test_joint_move_respects_every_axis_limit(
    start: Vec7, end: Vec7, feed: float | None, limits: AxisLimits
) -> None:
    block = joint_block(start, end, feed, limits)
    if block.length < 1e-6:
        return
    check_block_kinematics(block, limits)
    # The limiting axis reaches its max rate or the feed (when the move is long enough).
    shares = [abs(e - s) / block.length for s, e in zip(start, end, strict=True)]
    limit = min(limits.max_rate[i] / 60 / shares[i] for i in range(AXES) if shares[i] > 0)
    if feed is not None:
        limit = min(limit, feed / 60)
    assert block.speed == pytest.approx(limit)
    assert block.duration == pytest.approx(
        closed_form(block.length, block.speed, block.accel), abs=1e-9
    )


@settings(max_examples=60)
@given(vec7s, vec7s, feeds, st.floats(0.0, 1.0))
def test_all_joints_start_and_stop_together(
    start: Vec7, end: Vec7, feed: float | None, fraction: float
) -> None:
    block = joint_block(start, end, feed, LIMITS_2021)
    if block.length < 1e-6:
        return
    t = fraction * block.duration
    q = block.position_at_time(t)
    moved = [i for i in range(AXES) if abs(end[i] - start[i]) > 1e-3]
    parts = [(q[i] - start[i]) / (end[i] - start[i]) for i in moved]
    if parts:
        assert max(parts) - min(parts) < 1e-9
        if 0.01 < fraction < 0.99:
            assert 0 < min(parts) <= max(parts) < 1


# ---- Cartesian paths -------------------------------------------------------------------------


def linear_poses(start: Vec7, end: Vec7) -> Callable[[float], Vec7]:
    def poses(u: float) -> Vec7:
        return vec(*(a + (b - a) * u for a, b in zip(start, end, strict=True)))

    return poses


def test_path_block_follows_poses_at_the_feed() -> None:
    start, end = vec(0, 10, 20), vec(10, 10, 0)
    calls: list[float] = []
    base = linear_poses(start, end)

    def poses(u: float) -> Vec7:
        calls.append(u)
        return base(u)

    block = path_block(start, poses, 100.0, 600.0, LIMITS_2021, samples=10)
    assert block.kind == "line"
    assert block.end == end
    assert len(calls) == 11
    # 10 mm/s along the tool path; joints move at most 20 deg per 100 mm: well within limits.
    assert block.speed == pytest.approx(10.0)
    # ASSUMED Cartesian accel: min accel_i / |dq_i/ds| = 50 / 0.2 = 250 mm/s^2.
    assert block.accel == pytest.approx(250.0)
    assert block.duration == pytest.approx(100 / 10 + 10 / 250, abs=1e-12)
    for t in (0.01, 0.7, 3.3, 9.0, 10.0):
        s = block.s_at(t)
        assert block.position_at(s) == pytest.approx(base(s / 100.0))
    check_block_kinematics(block, LIMITS_2021)


def test_path_block_reduces_the_feed_for_joint_rates() -> None:
    # 10 mm of tool travel needs J1 to turn 90 deg: at F6000 (100 mm/s) J1 would need 900 deg/s.
    start, end = ZERO, vec(90)
    block = path_block(start, linear_poses(start, end), 10.0, 6000.0, LIMITS_2021, kind="arc")
    assert block.kind == "arc"
    assert block.speed == pytest.approx(30.0 / 9.0)  # J1 at 30 deg/s, 9 deg per mm
    check_block_kinematics(block, LIMITS_2021)


def test_path_block_on_a_curved_joint_path_stays_within_rates() -> None:
    def poses(u: float) -> Vec7:
        return vec(60 * math.sin(math.pi * u), 30 * u * u, -20 * u)

    block = path_block(ZERO, poses, 50.0, 3000.0, LIMITS_2021, samples=200)
    assert block.end == pytest.approx(poses(1.0))
    h = block.duration / 400
    for k in range(400):
        a, b = block.position_at_time(k * h), block.position_at_time((k + 1) * h)
        for i in range(AXES):
            assert abs(b[i] - a[i]) <= LIMITS_2021.max_rate[i] / 60 * h * 1.01


def test_path_block_refusals_and_fallback() -> None:
    with pytest.raises(ValueError):  # poses(0) is not where the arm is
        path_block(vec(5), linear_poses(ZERO, vec(10)), 10.0, 600.0, LIMITS_2021)

    def unreachable(u: float) -> Vec7:
        if u > 0.5:
            raise ValueError("GOAL OUT OF WORKSPACE")
        return vec(u)

    with pytest.raises(ValueError):
        path_block(ZERO, unreachable, 10.0, 600.0, LIMITS_2021)
    with pytest.raises(ValueError):
        path_block(ZERO, linear_poses(ZERO, vec(1)), 10.0, 0.0, LIMITS_2021)

    # Reachable at every sample, not between two of them: position_at interpolates the samples.
    def grazing(u: float) -> Vec7:
        if 0.52 < u < 0.58:
            raise ValueError("GOAL OUT OF WORKSPACE")
        return vec(10 * u)

    block = path_block(ZERO, grazing, 10.0, 600.0, LIMITS_2021, samples=10)
    assert block.position_at(5.5) == pytest.approx(vec(5.5))


def test_path_with_no_tool_travel_is_timed_in_joint_space() -> None:
    # M20 G1 A30 at the same point: the wrist turns 30 deg; F600 read as 10 deg/s (ASSUMED).
    block = path_block(ZERO, linear_poses(ZERO, vec(0, 0, 0, 30)), 0.0, 600.0, LIMITS_2021)
    assert block.length == pytest.approx(30.0)
    assert block.duration == pytest.approx(30 / 10 + 10 / 50, abs=1e-9)
    nothing = path_block(ZERO, linear_poses(ZERO, ZERO), 0.0, 600.0, LIMITS_2021)
    assert nothing.duration == 0.0


# ---- the planner -----------------------------------------------------------------------------


def chain(n: int, step: float = 10.0, feed: float | None = None) -> list[Block]:
    blocks: list[Block] = []
    position = ZERO
    for k in range(n):
        target = vec(position[0] + step, position[1] - step / 2, 0, 0, 0, 0, float(k))
        blocks.append(joint_block(position, target, feed, LIMITS_2021))
        position = target
    return blocks


def test_planner_capacity_free_slots_and_order() -> None:
    planner = Planner(ZERO)
    assert Planner.CAPACITY == 17
    assert (planner.state, planner.busy, planner.free, planner.running) == ("idle", False, 17, None)
    assert planner.time_to_next_change() is None
    blocks = chain(17)
    for k, block in enumerate(blocks):
        planner.push(block)
        assert planner.free == 16 - k
    assert planner.planned_position == blocks[-1].end
    with pytest.raises(PlannerFull):
        planner.push(joint_block(blocks[-1].end, ZERO, None, LIMITS_2021))
    for k, block in enumerate(blocks):
        assert planner.running is block
        assert planner.state == "run"
        assert planner.time_to_next_change() == pytest.approx(block.duration, abs=1e-12)
        assert planner.estimated_duration(block) == block.duration
        planner.advance(block.duration / 2)
        assert planner.time_to_next_change() == pytest.approx(block.duration / 2, abs=1e-12)
        planner.advance(planner.time_to_next_change() or 0.0)
        assert planner.position == block.end
        assert planner.free == 17 - (16 - k)
    assert (planner.state, planner.busy, planner.running) == ("idle", False, None)
    assert planner.time_to_next_change() is None


def test_push_must_start_where_the_planner_ends() -> None:
    planner = Planner(vec(1))
    with pytest.raises(ValueError):
        planner.push(joint_block(ZERO, vec(5), None, LIMITS_2021))
    planner.push(joint_block(vec(1), vec(5), None, LIMITS_2021))
    with pytest.raises(RuntimeError):
        planner.set_position(ZERO)


def test_remaining_time_and_next_change_loop_finish_everything() -> None:
    planner = Planner(ZERO)
    blocks = chain(17, feed=900.0)
    for block in blocks:
        planner.push(block)
    total = math.fsum(b.duration for b in blocks)
    assert planner.remaining_time() == pytest.approx(total)
    changes = 0
    while (step := planner.time_to_next_change()) is not None:
        planner.advance(step)
        changes += 1
        assert changes <= 17
    assert changes == 17
    assert planner.position == blocks[-1].end


@pytest.mark.parametrize("dt", [math.inf, 1e12])
def test_huge_dt_finishes_everything(dt: float) -> None:
    planner = Planner(ZERO)
    blocks = chain(17)
    for block in blocks:
        planner.push(block)
    planner.advance(dt)
    assert (planner.state, planner.free, planner.position) == ("idle", 17, blocks[-1].end)


def test_zero_and_tiny_dt() -> None:
    planner = Planner(ZERO)
    planner.push(joint_block(ZERO, ZERO, None, LIMITS_2021))  # zero-length: done at advance(0)
    assert planner.time_to_next_change() == 0.0
    planner.advance(0.0)
    assert planner.state == "idle"
    block = joint_block(ZERO, vec(3), None, LIMITS_2021)
    planner.push(block)
    planner.advance(0.0)
    assert planner.position == ZERO
    planner.advance(block.duration - 5e-10)  # within the snap: finished, not stuck forever
    assert planner.state == "idle"
    assert planner.position == vec(3)
    with pytest.raises(ValueError):
        planner.advance(-1.0)
    with pytest.raises(ValueError):
        planner.advance(math.nan)


def test_many_small_steps_do_not_leave_a_block_running() -> None:
    planner = Planner(ZERO)
    block = joint_block(ZERO, vec(1.0 / 3.0), 37.0, LIMITS_2021)
    planner.push(block)
    steps = 0
    while planner.busy:
        planner.advance(1e-3)
        steps += 1
        assert steps <= block.duration / 1e-3 + 2
    assert planner.position == block.end


@settings(max_examples=50)
@given(
    st.lists(st.tuples(vec7s, feeds), min_size=1, max_size=5),
    st.lists(st.floats(0.0, 3.0), min_size=1, max_size=40),
)
def test_one_big_step_equals_many_small_steps(
    moves: list[tuple[Vec7, float | None]], steps: list[float]
) -> None:
    one, many = Planner(ZERO), Planner(ZERO)
    for target, feed in moves:
        block = joint_block(one.planned_position, target, feed, LIMITS_2021)
        one.push(block)
        many.push(block)
    for dt in steps:
        many.advance(dt)
    one.advance(math.fsum(steps))
    assert one.state == many.state
    assert one.free == many.free
    assert one.position == pytest.approx(many.position, abs=1e-6)


def test_positions_move_monotonically_toward_the_target() -> None:
    planner = Planner(vec(10, -20, 30, 0, 5, -5, 100))
    target = vec(-40, 25, -10, 90, -30, 45, 60)
    planner.push(joint_block(planner.position, target, 2000.0, LIMITS_2021))
    previous = planner.position
    while planner.busy:
        planner.advance(0.05)
        q = planner.position
        for i in range(AXES):
            lo, hi = sorted((previous[i], target[i]))
            assert lo - 1e-9 <= q[i] <= hi + 1e-9
        previous = q
    assert planner.position == target


def test_hold_decelerates_freezes_and_resume_reaches_the_target() -> None:
    planner = Planner(ZERO, hold_latency=0.0)  # brake at once: numbers by hand
    planner.push(joint_block(ZERO, vec(90), None, LIMITS_2021))
    planner.push(joint_block(vec(90), vec(80), None, LIMITS_2021))
    planner.advance(1.0)  # cruising at 30 deg/s, at 9 + 0.4 * 30 = 21 deg
    assert planner.position == pytest.approx(vec(21))
    assert planner.speed == pytest.approx(30.0)
    planner.hold()
    assert planner.state == "hold"  # at once, while decelerating
    assert planner.time_to_next_change() == pytest.approx(0.6)  # 30 / 50
    planner.advance(0.3)
    assert planner.position == pytest.approx(vec(21 + 30 * 0.3 - 25 * 0.09))
    planner.advance(0.3)
    stopped = planner.position
    assert stopped == pytest.approx(vec(30.0))  # 30^2 / (2 * 50) = 9 deg to stop
    assert planner.time_to_next_change() is None
    planner.advance(100.0)
    assert planner.position == stopped
    assert (planner.state, planner.free) == ("hold", 15)
    planner.hold()  # no effect while held
    planner.resume()
    assert planner.state == "run"
    assert planner.time_to_next_change() == pytest.approx(60 / 30 + 30 / 50)
    planner.advance(2.6)
    assert planner.position == vec(90)
    planner.advance(math.inf)
    assert (planner.state, planner.position) == ("idle", vec(80))


def test_resume_while_still_decelerating_is_continuous() -> None:
    planner = Planner(ZERO, hold_latency=0.0)  # brake at once: numbers by hand
    planner.push(joint_block(ZERO, vec(90), None, LIMITS_2021))
    planner.advance(1.0)
    planner.hold()
    planner.advance(0.2)
    before, speed = planner.position, planner.speed
    assert speed == pytest.approx(20.0)
    planner.resume()
    assert planner.position == before
    assert planner.speed == pytest.approx(speed)
    planner.advance(math.inf)
    assert planner.position == vec(90)


def test_hold_at_the_end_of_the_last_block_ends_idle() -> None:
    planner = Planner(ZERO)
    block = joint_block(ZERO, vec(90), None, LIMITS_2021)
    planner.push(block)
    planner.advance(block.duration - 0.3)  # decelerating: stopping now lands on the end
    planner.hold()
    planner.advance(1.0)
    assert (planner.state, planner.position) == ("idle", vec(90))


def test_hold_while_idle_is_ignored_and_resume_without_hold_too() -> None:
    planner = Planner(ZERO)
    planner.hold()
    planner.resume()
    assert planner.state == "idle"
    planner.push(joint_block(ZERO, vec(4), None, LIMITS_2021))
    assert planner.state == "run"


def test_hold_pauses_a_dwell() -> None:
    planner = Planner(vec(3))
    planner.push(dwell_block(2.0, vec(3)))
    assert planner.running is not None and planner.running.kind == "dwell"
    planner.advance(0.5)
    assert planner.state == "run"
    planner.hold()
    assert planner.state == "hold"
    planner.advance(10.0)
    assert planner.state == "hold"
    planner.resume()
    assert planner.time_to_next_change() == pytest.approx(1.5)
    planner.advance(1.5)
    assert (planner.state, planner.position) == ("idle", vec(3))
    with pytest.raises(ValueError):
        dwell_block(-1.0, ZERO)


def test_abort_stops_at_once_and_clears() -> None:
    planner = Planner(ZERO)
    for block in chain(5):
        planner.push(block)
    planner.advance(0.9)
    here = planner.position
    planner.hold()
    planner.abort()
    assert (planner.state, planner.busy, planner.free) == ("idle", False, 17)
    assert planner.position == here
    assert planner.planned_position == here
    planner.advance(5.0)
    assert planner.position == here
    planner.set_position(ZERO)
    assert planner.position == ZERO


def test_homing_state_sequence_home_run_idle() -> None:
    start = vec(20, -10, 15, 30, -40, 50, 123)
    blocks = homing_blocks(start, 10.0, LIMITS_2021, sequential=False)
    assert [b.kind for b in blocks] == ["home_search", "home_pulloff"]
    planner = Planner(start)
    for block in blocks:
        planner.push(block)
    assert planner.state == "home"
    planner.advance(9.9)
    assert planner.state == "home"
    assert planner.position == start  # the joints stay during the switch search (ASSUMED)
    planner.hold()  # ignored while homing
    assert planner.state == "home"
    planner.advance(0.2)
    assert planner.state == "run"
    planner.hold()
    assert planner.state == "run"
    pulloff = blocks[1]
    assert pulloff.duration == pytest.approx(
        joint_block(start, vec(0, 0, 0, 0, 0, 0, 123), None, LIMITS_2021).duration
    )
    planner.advance(pulloff.duration)
    assert planner.state == "idle"
    assert planner.position == vec(0, 0, 0, 0, 0, 0, 123)  # rail unchanged for $H


def test_sequential_and_rail_homing() -> None:
    start = vec(5, 5, 5, 5, 5, 5, 50)
    blocks = homing_blocks(start, 10.0, LIMITS_2021, sequential=True)
    searches = [b for b in blocks if isinstance(b, HomeSearchBlock)]
    assert [b.axes for b in searches] == [(0,), (1,), (2,), (3,), (4,)]  # J1..J5
    assert math.fsum(b.duration for b in searches) == pytest.approx(
        5 * SEQUENTIAL_SEARCH_FRACTION * 10.0
    )
    assert blocks[-1].end == vec(0, 0, 0, 0, 0, 0, 50)
    rail = homing_blocks(start, 1.0, LIMITS_2021, sequential=False, home_rail=True)
    assert rail[-1].end == ZERO
    planner = Planner(start)
    for block in blocks:
        planner.push(block)
    planner.advance(math.inf)
    assert (planner.state, planner.position) == ("idle", vec(0, 0, 0, 0, 0, 0, 50))


def test_homing_from_zero_goes_straight_to_idle_after_the_search() -> None:
    planner = Planner(ZERO)
    for block in homing_blocks(ZERO, 0.5, LIMITS_2021, sequential=False):
        planner.push(block)
    planner.advance(0.5)
    assert (planner.state, planner.position) == ("idle", ZERO)


operations = st.lists(
    st.one_of(
        st.tuples(st.just("advance"), st.floats(0.0, 2.0)),
        st.tuples(st.just("hold"), st.just(0.0)),
        st.tuples(st.just("resume"), st.just(0.0)),
    ),
    max_size=30,
)


@settings(max_examples=80)
@given(st.lists(st.tuples(vec7s, feeds), min_size=1, max_size=4), operations)
def test_holds_and_resumes_never_exceed_rates_and_end_at_the_target(
    moves: list[tuple[Vec7, float | None]], ops: list[tuple[str, float]]
) -> None:
    planner = Planner(ZERO)
    for target, feed in moves:
        planner.push(joint_block(planner.planned_position, target, feed, LIMITS_2021))
    final = planner.planned_position
    previous = planner.position
    for op, dt in ops:
        if op == "hold":
            planner.hold()
            assert planner.state in ("hold", "idle")
        elif op == "resume":
            planner.resume()
            assert planner.state in ("run", "idle")
        else:
            planner.advance(dt)
            q = planner.position
            for i in range(AXES):
                limit = LIMITS_2021.max_rate[i] / 60 * dt
                assert abs(q[i] - previous[i]) <= limit * (1 + 1e-9) + 1e-9
            previous = q
    planner.advance(math.inf)  # stops any deceleration, never finishes a held path
    planner.resume()
    planner.advance(math.inf)
    assert (planner.state, planner.position) == ("idle", final)


def test_2021_homing_variants() -> None:
    start = vec(5, 5, 5, 5, 5, 5, 50)
    h7 = homing_blocks(
        start, 4.0, LIMITS_2021, sequential=True, order=((0, 1, 2, 3, 4, 5), (6,)), home_rail=True
    )
    assert [b.kind for b in h7] == ["home_search", "home_search", "home_pulloff"]
    assert h7[-1].end == ZERO
    he = homing_blocks(start, 4.0, LIMITS_2021, sequential=True, order=((1, 2), (0, 3, 4)))
    assert [b.axes for b in he if isinstance(b, HomeSearchBlock)] == [(1, 2), (0, 3, 4)]
    single = homing_blocks(start, 4.0, LIMITS_2021, sequential=False, axes=(2,))
    assert single[-1].end == vec(5, 5, 0, 5, 5, 5, 50)
    with pytest.raises(ValueError):
        homing_blocks(start, 4.0, LIMITS_2021, sequential=False, axes=(7,))
