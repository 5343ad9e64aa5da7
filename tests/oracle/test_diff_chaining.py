"""The client against the vendor's firmware (classic, in the simulator): streaming keeps a
program's meaning. Random programs of joint and Cartesian moves, absolute and relative, with and
without the mode word repeated on every line, streamed with ``stream()`` end where the same lines
sent one at a time (each after the arm stopped) end, or are refused before their first byte; the
client's own ``wait=False`` moves end where ``wait=True`` ones do. One oracle for the module, at
``-s 0`` (as fast as it goes); the client opens its pty as a user opens a real arm's port.
"""

from __future__ import annotations

import asyncio
import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, event, given, settings
from integration.chaining_programs import joints_of, programs, stepped, streamed, to_zero

from mirobot_async import Mirobot, MotionChainError, StatusReport

from .harness import Device, spawn_oracle

STATUS_TIMEOUT = 10.0
"""The simulator's clock slips behind the wall clock on a loaded host (a CI run timed out once
at the client's 2 s); the replies' timing is not what these tests judge."""
STEP = 0.06
"""Two whole motor steps of the coarsest joint, in degrees (J3: 64 steps/degree)."""


@pytest.fixture
def oracle_port(tmp_path: Path) -> Iterator[str]:
    """A fresh oracle for the test, powered on (banner read); its pty's path, free for the
    client to open (fresh per test: an alarm in one test must not reach the next, nor its
    rerun)."""
    device: Device = spawn_oracle(tmp_path)
    try:
        device.connect()
        path = os.ttyname(device.fd)
        os.close(device.fd)  # the firmware keeps running; the client opens the pty itself
        device.fd = -1
        yield path
    finally:
        device.close()


async def _both(port: str, program: list[str]) -> tuple[object, object]:
    async with Mirobot.connect(port, status_timeout=STATUS_TIMEOUT) as arm:
        await arm.unlock()
        through_stream = await streamed(arm, program)
        one_at_a_time = await stepped(arm, program)
    return through_stream, one_at_a_time


def test_streamed_programs_end_where_stepped_ones_do(oracle_port: str) -> None:
    @settings(
        max_examples=4,
        deadline=None,
        phases=(Phase.explicit, Phase.generate),
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    )
    @given(program=programs("classic"))
    def check(program: list[str]) -> None:
        through_stream, one_at_a_time = asyncio.run(_both(oracle_port, program))
        if isinstance(through_stream, MotionChainError):
            event("refused before the first byte")
            return
        event("streamed")
        assert not isinstance(one_at_a_time, MotionChainError)
        assert isinstance(through_stream, StatusReport), through_stream
        assert isinstance(one_at_a_time, StatusReport), one_at_a_time
        assert joints_of(through_stream) == pytest.approx(joints_of(one_at_a_time), abs=STEP)

    check()


async def _issue_case(port: str) -> tuple[float, float]:
    async with Mirobot.connect(port, status_timeout=STATUS_TIMEOUT) as arm:
        await arm.unlock()
        await to_zero(arm)
        await arm.move_joints(j1=-4, wait=False)
        await arm.move_joints(j1=6, relative=True, wait=False)
        chained = (await arm.wait_idle()).joints[0]
        # the same program with M21 on every line: refused before its first byte
        result = await arm.stream(["M21 G90 G0 X-4", "M21 G91 G0 X6"])
        assert result.sent == 0 and isinstance(result.errors[0].error, MotionChainError)
        # sent anyway (validate=False): the firmware restarts the second line from where the
        # arm is (near 2, where line 1 starts), not from -4
        await arm.stream(["M21 G90 G0 X-4", "M21 G91 G0 X6"], validate=False)
        restarted = (await arm.wait_idle()).joints[0]
    return chained, restarted


def test_wait_false_moves_chain_on_the_firmware(oracle_port: str) -> None:
    chained, restarted = asyncio.run(_issue_case(oracle_port))
    assert chained == pytest.approx(2, abs=STEP)  # -4 + 6
    assert restarted > 6  # measured from where the arm was (about 2): about 8


async def _own_moves(port: str, wait: bool) -> tuple[float, ...]:
    async with Mirobot.connect(port, status_timeout=STATUS_TIMEOUT) as arm:
        await arm.unlock()
        await to_zero(arm)
        await arm.move_joints(j1=-3, j2=2, wait=wait)
        await arm.move_pose(x=3, z=-3, relative=True, wait=wait)
        await arm.move_joints(j3=2, relative=True, wait=wait)
        await arm.move_pose(y=-3, relative=True, linear=True, speed=2000, wait=wait)
        return joints_of(await arm.wait_idle())


def test_the_clients_own_moves_chain_without_waiting(oracle_port: str) -> None:
    queued = asyncio.run(_own_moves(oracle_port, wait=False))
    waited = asyncio.run(_own_moves(oracle_port, wait=True))
    assert queued == pytest.approx(waited, abs=STEP)


def test_a_path_after_a_queued_move_ends_at_its_last_point(oracle_port: str) -> None:
    """``move_path`` right after a ``wait=False`` joint move: the header restates nothing
    that restarts the points from the moving arm; the path ends at its last point."""

    async def run() -> tuple[float, ...]:
        async with Mirobot.connect(oracle_port, status_timeout=STATUS_TIMEOUT) as arm:
            await arm.unlock()
            await to_zero(arm)
            await arm.move_joints(j1=5, wait=False)
            report = await arm.move_joint_path([(None, 4), (None, None, -4)], speed=2000)
            return joints_of(report)

    assert asyncio.run(run())[:3] == pytest.approx((5, 4, -4), abs=STEP)
