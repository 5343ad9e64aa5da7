"""The one way a test waits for something: poll a condition until it holds, within a deadline.

``wait_for`` blocks (threads, subprocesses, code outside an event loop); ``wait_until`` yields
to the event loop between checks (conditions of a client or emulator running on that loop);
``poll_until`` awaits a check that must itself ask (an emulator's counters, a status). Each
returns the first truthy value of its check and fails with ``WaitTimeout`` (both an
``AssertionError`` and a ``TimeoutError``) naming what was awaited and how long was waited. A
test never sleeps a fixed time for something to settle: it waits for the condition itself.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Awaitable, Callable
from typing import TypeVar

_T = TypeVar("_T")

POLL = 0.005
"""Seconds between two checks of a condition: short next to any deadline, long next to a check."""


class WaitTimeout(AssertionError, TimeoutError):
    """A condition did not hold within its deadline (a failed test, and a timeout)."""


Described = str | Callable[[], str]
"""What a wait is for, or a function saying it at the timeout (with the state last seen)."""


def _timed_out(what: Described, within: float, started: float) -> WaitTimeout:
    waited = time.monotonic() - started
    said = what if isinstance(what, str) else what()
    return WaitTimeout(f"no {said} within {within} s (waited {waited:.2f} s)")


def wait_for(
    condition: Callable[[], _T | None], within: float, what: Described, *, every: float = POLL
) -> _T:
    """Block until ``condition()`` is truthy and return that value; ``WaitTimeout`` naming
    ``what`` once ``within`` seconds have passed (checked every ``every`` seconds)."""
    started = time.monotonic()
    deadline = started + within
    while not (found := condition()):
        if time.monotonic() > deadline:
            raise _timed_out(what, within, started)
        time.sleep(every)  # the poll interval of a bounded wait on a condition
    return found


async def wait_until(
    condition: Callable[[], _T | None], within: float, what: Described, *, every: float = POLL
) -> _T:
    """Yield to the event loop until ``condition()`` is truthy and return that value;
    ``WaitTimeout`` naming ``what`` once ``within`` seconds have passed. Cancelling the
    awaiting task cancels the wait."""
    started = time.monotonic()
    deadline = started + within
    while not (found := condition()):
        if time.monotonic() > deadline:
            raise _timed_out(what, within, started)
        await asyncio.sleep(every)  # the poll interval of a bounded wait on a condition
    return found


async def poll_until(
    ask: Callable[[], Awaitable[_T | None]], within: float, what: Described, *, every: float = POLL
) -> _T:
    """Await ``ask()`` until its answer is truthy and return that answer; ``WaitTimeout``
    naming ``what`` once ``within`` seconds have passed (an answer still being awaited then
    is cancelled). Cancelling the awaiting task cancels the wait."""
    started = time.monotonic()
    scope = asyncio.timeout(within)
    try:
        async with scope:
            while not (found := await ask()):  # noqa: ASYNC110 - a check, not an event
                await asyncio.sleep(every)  # the poll interval of a bounded wait on a condition
            return found
    except TimeoutError:
        if scope.expired():
            raise _timed_out(what, within, started) from None
        raise  # the check's own
