"""The tests' one wait helper (tests/waiting.py): the first truthy value, or a failure naming
what was awaited and how long."""

from __future__ import annotations

import itertools

import pytest
from waiting import WaitTimeout, poll_until, wait_for, wait_until


def test_wait_for_returns_the_first_truthy_value() -> None:
    answers = iter([0, None, "", 7, 8])
    assert wait_for(lambda: next(answers), 5, "an answer", every=0) == 7


async def test_wait_until_returns_the_first_truthy_value() -> None:
    answers = iter([0, None, [3], [4]])
    assert await wait_until(lambda: next(answers), 5, "an answer", every=0) == [3]


async def test_poll_until_returns_the_first_truthy_answer() -> None:
    counter = itertools.count()

    async def ask() -> int:
        return next(counter) // 3  # 0, 0, 0, 1, ...

    assert await poll_until(ask, 5, "an answer", every=0) == 1


def test_a_timeout_names_what_and_the_time_waited() -> None:
    with pytest.raises(WaitTimeout, match=r"^no the door open within 0.05 s \(waited 0\.\d\d s\)$"):
        wait_for(lambda: False, 0.05, "the door open")


async def test_a_timeout_is_a_failed_assertion_and_a_timeout() -> None:
    with pytest.raises(AssertionError, match="no light within"):
        await wait_until(lambda: None, 0.02, "light")
    with pytest.raises(TimeoutError, match="no light within"):
        await wait_until(lambda: None, 0.02, "light")


async def test_the_description_may_say_the_state_last_seen() -> None:
    seen: list[int] = []

    async def ask() -> bool:
        seen.append(len(seen))
        return False

    with pytest.raises(WaitTimeout, match=r"no answer \(asked [1-9]\d* times\) within"):
        await poll_until(ask, 0.05, lambda: f"answer (asked {len(seen)} times)")


async def test_a_timeout_of_the_check_itself_is_not_taken_for_the_waits() -> None:
    async def ask() -> bool:
        raise TimeoutError("the check's own")

    with pytest.raises(TimeoutError, match="the check's own"):
        await poll_until(ask, 5, "an answer")
