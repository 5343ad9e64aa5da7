"""The pytest plugin: virtual Mirobots as fixtures (registered by the ``pytest11`` entry point).

::

    @pytest.mark.mirobot_emulator(firmware="classic", time_scale=100)
    async def test_my_app(mirobot_emulator):          # the port path, e.g. "/dev/pts/7"
        async with Mirobot.connect(mirobot_emulator) as arm:
            ...

Fixtures: ``mirobot_emulator`` (the port URL of an emulator process),
``mirobot_emulator_process`` (its :class:`SyncEmulatorProcess`: ``.url``, ``.control(cmd)``,
``.kill()``), ``mirobot_virtual_arm`` (the ``virtual://N`` URL of an :class:`InProcessArm` in
the test's process), ``mirobot_link`` and the session's ``mirobot_emulator_pool``
(:class:`EmulatorPool`: processes renewed between tests in milliseconds). Settings: the
``mirobot_emulator(firmware=, time_scale=, extra_args=, listen=, fresh=)`` marker, else
``--mirobot-firmware``, ``--mirobot-time-scale``, ``--mirobot-link`` (``pty``, ``tcp``,
``both``; default ``$MIROBOT_TEST_LINK``) and ``--mirobot-pool-size``. The fixtures are
synchronous (any test style); an ``async def`` test that uses them runs on pytest-asyncio
without ``asyncio_mode = "auto"``. Tests that use none of them see nothing of the plugin.

The virtual arm itself lives in :mod:`mirobot_async.virtual`; its names are re-exported here.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import pytest

from mirobot_async.errors import MirobotUsageError
from mirobot_async.testing import _options
from mirobot_async.testing._options import session_link
from mirobot_async.virtual._control import default_link

if TYPE_CHECKING:
    from mirobot_async.testing._pool import BorrowedEmulatorProcess, EmulatorPool
    from mirobot_async.testing._spy import WireSpy
    from mirobot_async.virtual import (
        EmulatorError,
        EmulatorProcess,
        InProcessArm,
        SyncEmulatorProcess,
        emulator_command,
        run_emulator,
        start_emulator,
    )

__all__ = [
    "BorrowedEmulatorProcess",
    "EmulatorError",
    "EmulatorPool",
    "EmulatorProcess",
    "InProcessArm",
    "SyncEmulatorProcess",
    "WireSpy",
    "emulator_command",
    "run_emulator",
    "session_link",
    "start_emulator",
]
_HOMES = {"WireSpy": "._spy", "EmulatorPool": "._pool", "BorrowedEmulatorProcess": "._pool"}


def __getattr__(name: str) -> Any:  # imported on first use: loading the plugin stays cheap
    if name not in __all__:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    home = importlib.import_module(_HOMES.get(name, "mirobot_async.virtual"), __name__)
    return getattr(home, name)


def pytest_addoption(parser: pytest.Parser) -> None:
    _options.add_options(parser)


def pytest_configure(config: pytest.Config) -> None:
    _options.add_marker(config)


def pytest_pycollect_makeitem(collector: pytest.Collector, name: str, obj: object) -> None:
    """Mark an ``async def`` test that uses this plugin's fixtures or marker with
    ``pytest.mark.asyncio`` (before pytest's own hook, which runs last, builds the item)."""
    if inspect.iscoroutinefunction(obj) and _options.wants_asyncio(obj, collector.config):
        pytest.mark.asyncio(obj)


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Run a test that uses the fixtures once per ``--mirobot-link``."""
    links = _options.links(metafunc)
    if links is not None:
        metafunc.parametrize("mirobot_link", links, indirect=True, scope="function")


@pytest.fixture
def mirobot_link(request: pytest.FixtureRequest) -> str:
    """The arm's link for this test: ``pty`` or ``tcp`` (``--mirobot-link``)."""
    return str(getattr(request, "param", None) or default_link())


@pytest.fixture(scope="session")
def mirobot_emulator_pool(request: pytest.FixtureRequest) -> Iterator[EmulatorPool]:
    """Emulator processes renewed between this session's tests, all stopped at its end."""
    from mirobot_async.testing._pool import DEFAULT_MAX_IDLE, EmulatorPool

    size = request.config.getoption("--mirobot-pool-size")
    link = session_link(request.config)
    with EmulatorPool(DEFAULT_MAX_IDLE if size is None else size, link=link) as pool:
        yield pool


@pytest.fixture
def mirobot_emulator_process(
    request: pytest.FixtureRequest, mirobot_link: str, mirobot_emulator_pool: EmulatorPool
) -> Iterator[SyncEmulatorProcess]:
    """An emulator process for this test, as a new one would be (renewed from the pool)."""
    arm = _options.settings(request)
    listen = arm.listen or mirobot_link
    with mirobot_emulator_pool.lend(
        arm.firmware, arm.time_scale, extra_args=arm.extra_args, listen=listen, fresh=arm.fresh
    ) as emulator:
        yield emulator


@pytest.fixture
def mirobot_emulator(mirobot_emulator_process: SyncEmulatorProcess) -> str:
    """The port URL of an emulator process for this test."""
    return mirobot_emulator_process.url


@pytest.fixture
def mirobot_virtual_arm(request: pytest.FixtureRequest) -> Iterator[str]:
    """The ``virtual://N`` URL of a virtual Mirobot in this process (:class:`InProcessArm`; the
    marker's ``firmware`` and ``time_scale`` apply, the process's options do not)."""
    from mirobot_async.virtual import InProcessArm

    arm = _options.settings(request)
    if arm.extra_args:
        raise MirobotUsageError(
            "mirobot_virtual_arm runs in this process: extra_args (the emulator process's "
            "options) do not apply; use the mirobot_emulator fixture"
        )
    with InProcessArm(arm.firmware, arm.time_scale) as virtual:
        yield virtual.url
