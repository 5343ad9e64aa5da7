"""Shared test configuration: hypothesis profiles (deterministic in CI, no deadlines) and scale.

``MIROBOT_TEST_SCALE`` multiplies every hypothesis example count: the suite's default 0.3 keeps
README's test command fast; ``MIROBOT_TEST_SCALE=1`` runs the counts the tests name, larger
values a thorough run. A count is never scaled below ``min(named count, 25)``, so every property
still sees a real sample. Stateful machines (``TestCase.settings``) are scaled the same way.
"""

from __future__ import annotations

import asyncio
import compileall
import os
import sys
from collections.abc import AsyncIterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

SCALE = float(os.environ.get("MIROBOT_TEST_SCALE", "0.3"))
FLOOR = 25


def scaled_examples(named: int) -> int:
    """The example count to run for a test that names ``named`` examples, at this scale."""
    return max(min(named, FLOOR), round(named * SCALE))


settings.register_profile(
    "default",
    deadline=None,
    max_examples=scaled_examples(100),
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "ci",
    deadline=None,
    derandomize=True,
    max_examples=scaled_examples(100),
    suppress_health_check=[HealthCheck.too_slow],
    print_blob=True,
)
settings.load_profile("ci" if os.environ.get("CI") else "default")


def _rescale(test: object) -> None:
    """Scale the example count a ``@settings(max_examples=...)`` decorator named on ``test``."""
    if not getattr(test, "_hypothesis_internal_settings_applied", False):
        return  # no explicit settings: the profile's count (already scaled) applies
    named = test._hypothesis_internal_use_settings  # type: ignore[attr-defined]
    if getattr(test, "_mirobot_named_examples", None) is None:
        test._mirobot_named_examples = named.max_examples  # type: ignore[attr-defined]
        test._hypothesis_internal_use_settings = settings(  # type: ignore[attr-defined]
            named, max_examples=scaled_examples(named.max_examples)
        )


def pytest_configure(config: pytest.Config) -> None:
    """Compile the project once, before the workers start (in xdist's controller, or the only
    process), and let every process the suite starts keep its bytecode where Python keeps it
    (``__pycache__``) even under ``PYTHONDONTWRITEBYTECODE``. The suite starts about 60 Python
    processes (workers, CLI commands, emulators); without a cache each compiles the package
    again and each worker rewrites every test module's asserts again (about 12 s of CPU per
    run). ``MIROBOT_TEST_BYTECODE=off`` leaves the interpreter's setting alone."""
    if hasattr(config, "workerinput") or os.environ.get("MIROBOT_TEST_BYTECODE") == "off":
        return
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)  # the workers and every subprocess
    sys.dont_write_bytecode = False
    import mirobot_emulator

    import mirobot_async

    for package in (mirobot_async, mirobot_emulator):
        if package.__file__ is not None:
            compileall.compile_dir(Path(package.__file__).parent, quiet=2)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Apply ``MIROBOT_TEST_SCALE`` to every hypothesis test and stateful machine collected."""
    seen: set[int] = set()
    for item in items:
        test = getattr(item, "obj", None)
        if test is not None and getattr(test, "is_hypothesis_test", False):
            _rescale(getattr(test, "__func__", test))
        cls = getattr(item, "cls", None)
        machine_settings = getattr(cls, "settings", None) if cls is not None else None
        if isinstance(machine_settings, settings) and id(cls) not in seen:
            seen.add(id(cls))
            named = getattr(cls, "_mirobot_named_examples", None)
            if named is None:
                cls._mirobot_named_examples = machine_settings.max_examples  # type: ignore[union-attr]
                cls.settings = settings(  # type: ignore[union-attr]
                    machine_settings, max_examples=scaled_examples(machine_settings.max_examples)
                )


@pytest.fixture
async def no_leftover_tasks() -> AsyncIterator[None]:
    """Fail the test if it leaves a task running (after every other fixture is torn down)."""
    before = asyncio.all_tasks()
    yield
    current = asyncio.current_task()
    others = {t for t in asyncio.all_tasks() if t is not current and t not in before}
    if others:
        # Give tasks that are finishing (transport clean-up) a moment, then insist.
        _, pending = await asyncio.wait(others, timeout=1.0)
        for task in pending:
            task.cancel()
        assert not pending, f"tasks left behind: {pending}"
