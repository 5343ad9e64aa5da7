"""A seeded, randomized fault campaign against the real client and emulator.

Several tasks send lines, stream, poll and cancel while the emulator is told, at random
moments, to drop an ``ok``, corrupt or ignore a status report, stall or delay its output,
reset, or split its output into single bytes. Invariants:

* no call returns another call's output (each kind of line has a recognisable answer);
  a dropped ``ok`` is the one fault no GRBL client can attribute while several lines are in
  flight (the protocol has no sequence numbers: the replies after it shift by one), so the
  drop-ok campaign keeps one line in flight (one sender, no stream);
* every call ends within its timeout (plus a small scheduling margin);
* nothing but :class:`MirobotError` (and ``CancelledError`` for the cancelled) is raised.

Bounded: a few seconds per seed and profile.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import random
import time
from collections.abc import Awaitable, Callable

import pytest

from mirobot_async import (
    Mirobot,
    MirobotAlarmError,
    MirobotCommandError,
    MirobotError,
    MirobotOutcomeUnknownError,
    MirobotResetError,
    MirobotTimeoutError,
)
from mirobot_async.testing import EmulatorProcess

pytestmark = [
    pytest.mark.timeout(60),
    pytest.mark.usefixtures("no_leftover_tasks"),
    pytest.mark.emulator_process,  # faults on the wire: the emulator's control channel
]

CHAOS_SECONDS = 2.0
CALL_TIMEOUT = 1.5
STREAM_TIMEOUT = 4.5
MARGIN = 1.0  # scheduling slack on a loaded machine (a timeout ignored would be far more)
FAULTS = [
    "corrupt-status",
    "ignore-status 2",
    "stall 0.15",
    "reset",
    "split-bytes on",
    "split-bytes off",
    "delay 40",
    "delay 0",
]


class Campaign:
    """Runs the workers and records every broken invariant."""

    def __init__(self, arm: Mirobot, emu: EmulatorProcess, seed: int, faults: list[str]) -> None:
        self.arm = arm
        self.fault_kinds = faults
        self.emu = emu
        self.rng = random.Random(seed)
        self.problems: list[str] = []
        self.calls = 0
        self.end = 0.0

    async def timed(
        self, what: str, call: Callable[[], Awaitable[object]], limit: float = CALL_TIMEOUT
    ) -> object:
        """Run one call; check its duration and the kind of its exception."""
        self.calls += 1
        start = time.monotonic()
        try:
            return await call()
        except MirobotError as err:
            return err
        except asyncio.CancelledError:
            raise
        except BaseException as err:  # the invariant is exactly this
            self.problems.append(f"{what} raised {err!r}, outside the MirobotError tree")
            return err
        finally:
            took = time.monotonic() - start
            if took > limit + MARGIN:
                self.problems.append(f"{what} took {took:.3f} s (timeout {limit} s)")

    def running(self) -> bool:
        return time.monotonic() < self.end

    async def send_pwm(self, value: int) -> tuple[str, ...]:
        return await self.arm.send(f"M3 S{value}", timeout=CALL_TIMEOUT)

    async def sender(self, name: str) -> None:
        while self.running():
            pick = self.rng.random()
            if pick < 0.6:
                value = self.rng.randrange(1, 1000)
                got = await self.timed(f"{name} M3", functools.partial(self.send_pwm, value))
                if isinstance(got, tuple) and got != ():
                    self.problems.append(f"{name}: 'M3 S{value}' returned {got!r}")
                if isinstance(got, MirobotCommandError) and not isinstance(got, MirobotAlarmError):
                    self.problems.append(f"{name}: 'M3 S{value}' got another reply: {got!r}")
            elif pick < 0.8:
                got = await self.timed(
                    f"{name} M99", lambda: self.arm.send("M99", timeout=CALL_TIMEOUT)
                )
                if isinstance(got, tuple):
                    self.problems.append(f"{name}: 'M99' (invalid) returned {got!r}")
            else:
                got = await self.timed(
                    f"{name} $$", lambda: self.arm.settings(timeout=CALL_TIMEOUT)
                )
                if isinstance(got, dict) and len(got) < 20:
                    self.problems.append(f"{name}: '$$' returned {got!r}")

    async def streamer(self) -> None:
        while self.running():
            lines = [f"M4 E{self.rng.randrange(0, 1000)}" for _ in range(15)]
            stream = self.arm.stream(lines, timeout=STREAM_TIMEOUT)
            got = await self.timed("stream", stream.run, STREAM_TIMEOUT)
            for result in stream.result.errors:
                error = result.error
                if isinstance(error, MirobotCommandError) and not isinstance(
                    error, MirobotAlarmError
                ):
                    self.problems.append(f"stream line {result.line!r} got {error!r}")
            if isinstance(got, MirobotCommandError):
                self.problems.append(f"stream raised {got!r}")

    async def poller(self) -> None:
        while self.running():
            await self.timed("status", lambda: self.arm.status(timeout=CALL_TIMEOUT))

    async def canceller(self) -> None:
        while self.running():
            task = asyncio.create_task(self.arm.send("M3 S1", timeout=CALL_TIMEOUT))
            await asyncio.sleep(self.rng.uniform(0, 0.02))  # a random moment to cancel at
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, MirobotError):
                await task

    async def faults(self) -> None:
        while self.running():
            await asyncio.sleep(self.rng.uniform(0.05, 0.3))  # a random gap between faults
            await self.emu.control(self.rng.choice(self.fault_kinds))

    async def run(self, *, pipelined: bool) -> None:
        self.end = time.monotonic() + CHAOS_SECONDS
        workers = [self.sender("a"), self.poller(), self.faults()]
        if pipelined:
            workers += [self.sender("b"), self.sender("c"), self.streamer(), self.canceller()]
        await asyncio.gather(*workers)


@pytest.mark.parametrize(
    ("seed", "pipelined", "faults"),
    [(1, True, FAULTS), (2, False, [*FAULTS, "drop-ok", "drop-ok"])],
    ids=["pipelined", "drop-ok"],
)
async def test_random_faults_never_mix_up_calls(
    ready_arm: Mirobot, emu: EmulatorProcess, seed: int, pipelined: bool, faults: list[str]
) -> None:
    arm = ready_arm
    arm.liveness_interval = 0.2
    # A reply later than the grace counts as lost, and the replies after it would shift: keep the
    # client's default, since a loaded machine delays the emulator's replies past 0.1 s (the
    # drop-ok campaign then saw a '$$' dump returned by the next line)
    arm.reply_grace = 0.5
    arm.status_retry_interval = 0.05
    campaign = Campaign(arm, emu, seed, faults)
    await campaign.run(pipelined=pipelined)
    await emu.control("split-bytes off")
    await emu.control("delay 0")
    assert campaign.problems == []
    assert campaign.calls > 20
    # still in step afterwards: a fresh call gets its own reply (a drop-ok or two may still be
    # armed: such a line is given up as lost, and the next one tried)
    await arm.reset(timeout=5)
    for _ in range(6):
        try:
            await arm.unlock(timeout=5)
            assert await arm.send("M3 S77", timeout=5) == ()
            break
        # (or a late banner of a reset fault: the line it caught on its way has an unknown fate)
        except (MirobotTimeoutError, MirobotResetError, MirobotOutcomeUnknownError):
            continue
    assert (await arm.status(fresh=True)).pump_pwm == 77
