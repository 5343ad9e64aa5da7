"""Interop tests: the client and the emulator with other people's software.

Third-party SDKs (the vendor's ``wlkata-mirobot-python`` 0.1.14, ``mirobot-py``, ``wlkatapython``
in a Python 3.10 venv built once from PyPI) drive the emulator unmodified, and ser2net serves an
emulator's pty over RFC 2217 and raw TCP to the real client. They need those tools installed, so
they run as their own command (README, ``.ci/run``); each skips with the reason when its tool is
missing, and ``MIROBOT_REQUIRE_SER2NET=1`` / ``MIROBOT_REQUIRE_THIRD_PARTY=1`` turn the skips into
failures. Every module checks that no task is left behind.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator

import pytest


@pytest.fixture
async def no_leftover_tasks() -> AsyncIterator[None]:
    """Fail the test if it leaves a task running (after every other fixture is torn down)."""
    before = asyncio.all_tasks()
    yield
    current = asyncio.current_task()
    others = {t for t in asyncio.all_tasks() if t is not current and t not in before}
    if others:
        _, pending = await asyncio.wait(others, timeout=1.0)
        for task in pending:
            task.cancel()
        assert not pending, f"tasks left behind: {pending}"
