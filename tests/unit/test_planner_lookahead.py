"""Unit tests of the look-ahead planner (mirobot_emulator.motion._planner): GRBL's junction
deviation rule, reverse/forward passes, blending vs stopping, feed hold across block ends,
whole-step positions, deferred cycle start and the starvation counters."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirobot_emulator.motion import (
    AXES,
    ZERO,
    AxisLimits,
    Block,
    Planner,
    Vec7,
    dwell_block,
    joint_block,
    junction_speed_sqr,
    path_blocks,
)
from mirobot_emulator.motion._planner import HOLD_LATENCY, HOLD_SEGMENT_SECONDS
from mirobot_emulator.settings import default_settings

CLASSIC = AxisLimits.from_settings(default_settings("classic"))
"""Classic factory settings: steps per degree, $11 = 0.010, 50 deg/s^2, J1 2000 deg/min."""

IDEAL = AxisLimits(
    CLASSIC.max_rate, CLASSIC.accel, steps=None, junction_deviation=CLASSIC.junction_deviation
)
"""The same without motor steps: exact positions for hand computations."""

STOPPING = AxisLimits(CLASSIC.max_rate, CLASSIC.accel)
"""No $11: every junction stops."""


def vec(*values: float) -> Vec7:
    v = [0.0] * AXES
    v[: len(values)] = values
    return (v[0], v[1], v[2], v[3], v[4], v[5], v[6])


def run_all(planner: Planner) -> float:
    """Advance until idle; the simulated seconds it took."""
    total = 0.0
    while (step := planner.time_to_next_change()) is not None:
        planner.advance(step)
        total += step
    return total


def push_path(planner: Planner, points: list[Vec7], feed: float, limits: AxisLimits) -> None:
    for point in points:
        planner.push(joint_block(planner.planned_position, point, feed, limits))


# ---- settings ----------------------------------------------------------------------------------


def test_limits_from_settings_read_steps_and_junction_deviation() -> None:
    assert CLASSIC.junction_deviation == pytest.approx(0.01)
    assert CLASSIC.steps is not None
    assert CLASSIC.steps[0] == pytest.approx(56.73)  # $104 is J1
    assert CLASSIC.to_steps(vec(10)) == (567, 0, 0, 0, 0, 0, 0)
    assert CLASSIC.to_steps(vec(-0.5 / 56.73)) == (-1, 0, 0, 0, 0, 0, 0)  # lround: away from 0
    with pytest.raises(ValueError):
        AxisLimits(CLASSIC.max_rate, CLASSIC.accel, junction_deviation=-1.0)
    with pytest.raises(ValueError):
        IDEAL.to_steps(vec(1))


# ---- junction speed ----------------------------------------------------------------------------


def test_junction_speed_formula_by_hand() -> None:
    east, north, west = vec(1), vec(0, 1), vec(-1)
    # 90 degrees: sin(theta/2) = sqrt(1/2); v^2 = a d s / (1 - s)
    s = math.sqrt(0.5)
    assert junction_speed_sqr(east, north, 50.0, 0.01) == pytest.approx(50 * 0.01 * s / (1 - s))
    assert junction_speed_sqr(east, west, 50.0, 0.01) == 0.0  # reversal
    assert junction_speed_sqr(east, north, 50.0, 0.0) == 0.0  # $11 = 0
    straight = junction_speed_sqr(east, east, 50.0, 0.01)
    assert straight > 1e5  # only the nominal speeds limit a straight junction


@given(st.floats(0.0, math.pi), st.floats(1.0, 500.0), st.floats(1e-4, 1.0))
def test_junction_speed_grows_as_the_corner_opens(turn: float, accel: float, dev: float) -> None:
    a = vec(1)
    b = vec(math.cos(turn), math.sin(turn))
    wider = vec(math.cos(turn * 0.5), math.sin(turn * 0.5))
    assert junction_speed_sqr(a, wider, accel, dev) >= junction_speed_sqr(a, b, accel, dev)


# ---- blending and stopping ----------------------------------------------------------------------


def test_collinear_blocks_blend_into_one_move() -> None:
    planner = Planner(ZERO)
    push_path(planner, [vec(10 * k) for k in range(1, 10)], 2000.0, IDEAL)
    one = joint_block(ZERO, vec(90), 2000.0, IDEAL)
    assert planner.remaining_time() == pytest.approx(one.duration, rel=1e-9)
    assert run_all(planner) == pytest.approx(one.duration, rel=1e-9)
    assert planner.position == pytest.approx(vec(90))


def test_reversals_and_stopping_limits_stop_at_every_block() -> None:
    points = [vec(10), vec(0), vec(10), vec(0)]
    for limits in (IDEAL, STOPPING):
        planner = Planner(ZERO)
        push_path(planner, points, 2000.0, limits)
        starts = [ZERO, *points[:-1]]
        alone = math.fsum(
            joint_block(a, b, 2000.0, limits).duration for a, b in zip(starts, points, strict=True)
        )
        assert run_all(planner) == pytest.approx(alone, rel=1e-9)
    planner = Planner(ZERO)
    push_path(planner, [vec(10 * k) for k in range(1, 4)], 2000.0, STOPPING)
    single = joint_block(ZERO, vec(10), 2000.0, STOPPING).duration
    assert planner.remaining_time() == pytest.approx(3 * single)


def test_right_angle_corner_passes_at_the_junction_speed() -> None:
    planner = Planner(ZERO, hold_latency=0.0)
    push_path(planner, [vec(30), vec(30, 30)], 2000.0, IDEAL)
    first = planner.running
    assert first is not None
    while planner.running is first:
        planner.advance(planner.time_to_next_change() or 0.0)
    s = math.sqrt(0.5)
    expected = math.sqrt(50.0 * 0.01 * s / (1 - s))
    assert planner.speed == pytest.approx(expected, rel=1e-9)
    assert 0.0 < planner.speed < 2.0


def test_look_ahead_raises_the_exit_of_the_running_block_as_blocks_arrive() -> None:
    planner = Planner(ZERO)
    planner.push(joint_block(ZERO, vec(40), 2000.0, IDEAL))
    planner.advance(0.5)
    alone = planner.remaining_time()
    planner.push(joint_block(vec(40), vec(80), 2000.0, IDEAL))
    # the first block no longer brakes to rest at 40
    together = planner.remaining_time()
    both_alone = alone + joint_block(vec(40), vec(80), 2000.0, IDEAL).duration
    assert together < both_alone - 0.5
    planner.advance(planner.time_to_next_change() or 0.0)
    assert planner.position == pytest.approx(vec(40))
    assert planner.speed == pytest.approx(2000.0 / 60.0)


def test_a_dwell_stops_the_motion_before_and_after_it() -> None:
    planner = Planner(ZERO)
    planner.push(joint_block(ZERO, vec(20), 2000.0, IDEAL))
    planner.push(dwell_block(0.5, vec(20)))
    planner.push(joint_block(vec(20), vec(40), 2000.0, IDEAL))
    single = joint_block(ZERO, vec(20), 2000.0, IDEAL).duration
    assert run_all(planner) == pytest.approx(2 * single + 0.5, rel=1e-9)


chains = st.lists(
    st.tuples(st.tuples(*[st.floats(-40.0, 40.0)] * 3), st.one_of(st.none(), st.floats(300, 5000))),
    min_size=2,
    max_size=12,
)


@settings(max_examples=40, deadline=None)
@given(chains, st.floats(0.001, 0.5))
def test_blended_motion_respects_nominal_speed_and_acceleration(
    moves: list[tuple[tuple[float, float, float], float | None]], deviation: float
) -> None:
    limits = AxisLimits(IDEAL.max_rate, IDEAL.accel, junction_deviation=deviation)
    planner = Planner(ZERO)
    for (x, y, z), feed in moves:
        planner.push(joint_block(planner.planned_position, vec(x, y, z), feed, limits))
    final = planner.planned_position
    h = 0.002
    previous_block: Block | None = planner.running
    previous_speed = planner.speed
    for _ in range(200_000):
        if not planner.busy:
            break
        planner.advance(h)
        block = planner.running
        speed = planner.speed
        if block is not None:
            assert speed <= block.speed * (1 + 1e-9) + 1e-9
            # never so fast that the rest of the queue could not stop in time
            if block is previous_block:
                assert abs(speed - previous_speed) <= block.accel * h * (1 + 1e-6) + 1e-9
        previous_block, previous_speed = block, speed
    assert planner.position == pytest.approx(final, abs=1e-9)


@settings(max_examples=40, deadline=None)
@given(chains)
def test_planner_can_always_stop_by_the_end_of_the_queue(
    moves: list[tuple[tuple[float, float, float], float | None]],
) -> None:
    planner = Planner(ZERO)
    for (x, y, z), feed in moves:
        planner.push(joint_block(planner.planned_position, vec(x, y, z), feed, IDEAL))
    while planner.busy:
        planner.advance(0.01)
        block = planner.running
        if block is None:
            break
        rest = block.length - planner.progress
        queue = list(planner.blocks)
        # what braking at each block's own acceleration can absorb before the queue ends
        room = 2 * (block.accel * rest + math.fsum(b.accel * b.length for b in queue[1:]))
        assert planner.speed**2 <= room * (1 + 1e-6) + 1e-6


# ---- feed hold -----------------------------------------------------------------------------------


def test_hold_brakes_across_block_ends_after_the_latency_and_resumes() -> None:
    planner = Planner(ZERO, hold_segment=0.0)  # the latency alone: numbers by hand
    push_path(planner, [vec(3 * k) for k in range(1, 17)], 2000.0, IDEAL)  # 3-deg blocks to 48
    planner.advance(0.8)  # cruising at 33.3 deg/s
    v = planner.speed
    assert v == pytest.approx(2000 / 60)
    here = planner.position[0]
    planner.hold()
    assert planner.state == "hold"
    run_all(planner)
    assert planner.state == "hold"
    stopped = planner.position[0]
    # latency at cruise speed, then v^2 / (2 a): several 3-degree blocks further
    assert stopped - here == pytest.approx(HOLD_LATENCY * v + v * v / 100.0, rel=1e-6)
    assert planner.free > Planner.CAPACITY - 16
    planner.resume()
    assert planner.state == "run"
    run_all(planner)
    assert planner.state == "idle"
    assert planner.position == pytest.approx(vec(48))


# ---- whole steps --------------------------------------------------------------------------------


def test_positions_are_whole_motor_steps() -> None:
    block = joint_block(ZERO, vec(10), 2000.0, CLASSIC)
    assert block.end[0] == 567 / 56.73  # 9.995 in the status report
    assert f"{block.end[0]:.3f}" == "9.995"
    assert CLASSIC.steps is not None
    steps = CLASSIC.steps
    planner = Planner(ZERO)
    push_path(planner, [vec(10, -5, 3.3, 40, 7, -12, 2), vec(-4, 3, 1)], 1500.0, CLASSIC)
    previous = planner.position
    while planner.busy:
        planner.advance(0.013)
        q = planner.position
        for i in range(AXES):
            n = q[i] * steps[i]
            assert n == pytest.approx(round(n), abs=1e-6)
            assert abs(q[i] - previous[i]) * steps[i] <= 2000 / 60 * 0.013 * steps[i] + 1.0
        previous = q
    assert planner.position_steps(CLASSIC) == CLASSIC.to_steps(vec(-4, 3, 1))


def test_step_rounding_is_not_cumulative_for_absolute_targets() -> None:
    planner = Planner(ZERO)
    for k in range(1, 11):
        planner.push(joint_block(planner.planned_position, vec(4.0 * k), 2000.0, CLASSIC))
    run_all(planner)
    # 2269 steps: 39.996, as the oracle reports 100 relative moves of 0.4 degrees
    assert f"{planner.position[0]:.3f}" == "39.996"


# ---- cycle start and starvation ------------------------------------------------------------------


def test_deferred_start_waits_for_cycle_start() -> None:
    planner = Planner(ZERO, deferred_start=True)
    planner.push(joint_block(ZERO, vec(10), 2000.0, IDEAL))
    planner.push(joint_block(vec(10), vec(20), 2000.0, IDEAL))
    assert (planner.state, planner.busy, planner.running) == ("idle", True, None)
    assert planner.time_to_next_change() is None
    planner.advance(5.0)
    assert planner.position == ZERO
    planner.hold()  # nothing runs: ignored
    planner.cycle_start()
    assert planner.state == "run"
    assert run_all(planner) == pytest.approx(joint_block(ZERO, vec(20), 2000.0, IDEAL).duration)


def test_starvations_count_restarts_after_running_empty() -> None:
    planner = Planner(ZERO)
    assert (planner.starvations, planner.run_outs) == (0, 0)
    planner.push(joint_block(ZERO, vec(5), 2000.0, IDEAL))
    planner.advance(math.inf)
    assert (planner.starvations, planner.run_outs) == (0, 1)
    planner.advance(0.25)
    planner.push(joint_block(vec(5), vec(10), 2000.0, IDEAL))
    assert planner.starvations == 1
    assert planner.starved_seconds == pytest.approx(0.25)
    planner.advance(0.1)
    planner.abort()  # a reset is not a starvation
    planner.push(joint_block(planner.planned_position, vec(0), 2000.0, IDEAL))
    assert planner.starvations == 1


# ---- Cartesian paths as joint blocks ------------------------------------------------------------


def test_path_blocks_cut_a_path_into_blending_joint_blocks() -> None:
    def poses(u: float) -> Vec7:
        return vec(20 * math.sin(u), 10 * u, -5 * u * u)

    blocks = path_blocks(ZERO, poses, 40.0, 1200.0, CLASSIC, segments=20)
    assert len(blocks) == 20
    assert all(b.kind == "line" for b in blocks)
    assert blocks[-1].end == CLASSIC.quantise(poses(1.0))
    planner = Planner(ZERO)
    for block in blocks[: Planner.CAPACITY]:
        planner.push(block)
    planner.advance(0.5)
    speeds: list[float] = []
    while planner.busy and len(speeds) < 12:
        planner.advance(planner.time_to_next_change() or 0.0)
        speeds.append(planner.speed)
    assert min(speeds[:8]) > 0.0  # no stop between the segments
    with pytest.raises(ValueError):
        path_blocks(vec(3), poses, 40.0, 1200.0, CLASSIC)


@pytest.mark.parametrize("held_at", [0.500, 0.5003, 0.505, 0.5097, 0.51])
def test_a_hold_brakes_at_the_next_segment_boundary_after_the_latency(held_at: float) -> None:
    """Oracle: the braking starts at a multiple of ``HOLD_SEGMENT_SECONDS`` since the motion
    began, the first at least ``HOLD_LATENCY`` after the ``!``."""
    planner = Planner(ZERO)
    planner.push(joint_block(ZERO, vec(60), 1000.0, IDEAL))
    planner.advance(held_at)  # cruising: 60 deg at 1000 deg/min take 3.6 s
    v = planner.speed
    here = planner.position[0]
    planner.hold()
    run_all(planner)
    boundary = math.ceil((held_at + HOLD_LATENCY) / HOLD_SEGMENT_SECONDS - 1e-9)
    delay = boundary * HOLD_SEGMENT_SECONDS - held_at
    assert HOLD_LATENCY <= delay < HOLD_LATENCY + HOLD_SEGMENT_SECONDS
    assert planner.position[0] - here == pytest.approx(delay * v + v * v / 100.0, rel=1e-6)
