"""What the fault tests share: the emulator's counters of what really crossed the wire (its
``stats`` control command, so "nothing was resent" is checked on the robot's side too), a status
monitor as users write it, a call bounded in time, and slow moves that keep lines in flight.
"""

# ruff: noqa: ASYNC109

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Awaitable, Callable
from typing import Any

from waiting import poll_until

from mirobot_async import Mirobot, StatusReport
from mirobot_async.testing import EmulatorProcess

SLOW_MOVES = [f"M21 G90 G1 X{10 + (i % 2) * 10} F600" for i in range(60)]  # ~1 s each
# A lost reply is found by a liveness check: after this long without progress (the client's
# default is 1 s), not before the reply grace (0.5 s, kept) after the line was written.
QUICK_LIVENESS = 0.1

Spawn = Callable[[Awaitable[Any]], "asyncio.Task[Any]"]
"""The ``spawn`` fixture (conftest.py): start a task that is cancelled and awaited at the end."""


async def emulator_stats(emu: EmulatorProcess) -> dict[str, int]:
    """The emulator's counters (its ``stats`` control command)."""
    answer = await emu.control("stats")
    words = answer.split()
    assert words[:2] == ["ack", "stats"], answer
    return {name: int(value) for name, value in (word.split("=") for word in words[2:])}


async def wire_settled(emu: EmulatorProcess, arm: Mirobot, timeout: float = 5.0) -> dict[str, int]:
    """Wait until the emulator has received every byte the client says it wrote; its stats."""
    seen: dict[str, int] = {}

    async def settled() -> dict[str, int] | None:
        seen.update(stats := await emulator_stats(emu))
        assert stats["bytes_in"] <= arm.stats.bytes_sent, (stats, arm.stats)
        return stats if stats["bytes_in"] == arm.stats.bytes_sent else None

    return await poll_until(
        settled, timeout, lambda: f"settled wire: the emulator got {seen}, the client {arm.stats}"
    )


async def output_mark(emu: EmulatorProcess, arm: Mirobot) -> tuple[int, int]:
    """What the emulator has written and the client received so far (on a quiet link)."""
    return (await emulator_stats(emu))["bytes_out"], arm.stats.bytes_received


async def wire_quiet(
    emu: EmulatorProcess, arm: Mirobot, mark: tuple[int, int], timeout: float = 10.0
) -> dict[str, int]:
    """:func:`wire_settled`, and every byte the emulator wrote since ``mark`` has reached the
    client (a report to a "?" still in flight may follow the last reply); its stats."""
    seen: dict[str, int] = {}

    async def quiet() -> dict[str, int] | None:
        seen.update(stats := await wire_settled(emu, arm))
        written = stats["bytes_out"] - mark[0]
        received = arm.stats.bytes_received - mark[1]
        return stats if stats["output_held"] == 0 and received >= written else None

    return await poll_until(
        quiet, timeout, lambda: f"quiet wire: the emulator {seen}, the client {arm.stats}"
    )


async def monitor(
    arm: Mirobot, reports: list[StatusReport], interval: float = 0.01, timeout: float = 2.0
) -> None:
    """A monitoring loop as users write it: ``statuses()`` until cancelled."""
    async with contextlib.aclosing(arm.statuses(interval=interval, timeout=timeout)) as stream:
        async for report in stream:
            reports.append(report)


async def stop(task: asyncio.Task[Any]) -> None:
    """Cancel ``task`` and wait for it (its exception, if any, is re-raised)."""
    task.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await task


async def finishes_within(seconds: float, call: Awaitable[Any]) -> Any:
    """Await ``call``; return its result or its exception; fail if it takes over ``seconds``
    (a bound with room for a loaded machine: what it rules out is a call left waiting for a
    reply that never comes, or for moves of a minute; the caller checks the outcome's kind)."""
    start = time.monotonic()
    try:
        result: Any = await asyncio.wait_for(call, seconds)
    except TimeoutError as err:
        if time.monotonic() - start >= seconds:
            raise AssertionError(f"not done within {seconds} s") from err
        result = err
    except Exception as err:
        result = err
    return result
