"""The pytest plugin; the virtual arm itself lives in :mod:`mirobot_async.virtual` (its names
are re-exported here).

**pytest plugin** (registered through the ``pytest11`` entry point, so installing mirobot-async is
enough)::

    @pytest.mark.mirobot_emulator(firmware="classic", time_scale=100)
    async def test_my_app(mirobot_emulator):          # the port path, e.g. "/dev/pts/7"
        async with Mirobot.connect(mirobot_emulator) as arm:
            ...

The ``mirobot_virtual_arm`` fixture yields instead the ``virtual://N`` URL of an
:class:`InProcessArm`: the firmware model in the test's own process (milliseconds per test; no
serial pacing, faults or control channel).
The ``mirobot_emulator`` fixture yields the port URL of an emulator for the test;
``mirobot_emulator_process`` yields its :class:`SyncEmulatorProcess` handle (``.url``,
``.control(cmd)``, ``.kill()``). The emulator is exactly what a process started for the test
would be, but usually it is not a new one: the session-scoped ``mirobot_emulator_pool``
(:class:`EmulatorPool`, one per pytest-xdist worker) keeps processes between tests and
*renews* one for each test (the emulator's ``renew`` control command: a new port, a fresh
power-on, only the test's faults armed, counters at zero), which takes milliseconds instead of
a process start. A process the test killed, stopped or closed (``close`` fault) is not reused;
all are stopped at the end of the session, and the pooled ones exit by themselves if pytest
dies. ``--mirobot-pool-size 0`` (or the marker's ``fresh=True``) gives a new process every
time. :meth:`EmulatorProcess.renew` and :meth:`SyncEmulatorProcess.renew` renew a handle of
your own. The settings come from the ``mirobot_emulator(firmware=..., time_scale=...,
extra_args=..., listen=..., fresh=...)`` marker, else from the command line options
``--mirobot-firmware`` (default ``2021``), ``--mirobot-time-scale`` (default ``0``: every
motion completes at once) and ``--mirobot-link`` (``pty``, ``tcp`` or ``both``: every test
using the fixtures runs once per link; default ``$MIROBOT_TEST_LINK``, else ``pty`` where ptys
exist). The ``mirobot_link`` fixture names the test's link. The fixtures are synchronous (the
emulator is a separate process), so they work in any test style: plain, pytest-asyncio (any
mode), anyio or trio.

This module imports only the standard library at import time, so loading the plugin is cheap.
"""

from __future__ import annotations

import inspect
import os
import sys
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from mirobot_async.errors import MirobotUsageError
from mirobot_async.virtual._control import (
    DEFAULT_FIRMWARE,
    DEFAULT_TIME_SCALE,
    LINK_ENV,
    EmulatorError,
    default_link,
    emulator_command,
)
from mirobot_async.virtual._process import EmulatorProcess, start_emulator
from mirobot_async.virtual._sync import SyncEmulatorProcess, run_emulator

if TYPE_CHECKING:
    import pytest

    from mirobot_async.testing._pool import BorrowedEmulatorProcess, EmulatorPool
    from mirobot_async.testing._spy import WireSpy
    from mirobot_async.virtual import InProcessArm


def __getattr__(name: str) -> Any:
    if name == "WireSpy":  # imported on first use (it needs the client's wire module)
        from mirobot_async.testing._spy import WireSpy

        return WireSpy
    if name == "InProcessArm":  # imported on first use (it loads the firmware model)
        from mirobot_async.virtual import InProcessArm

        return InProcessArm
    if name in ("EmulatorPool", "BorrowedEmulatorProcess"):  # it builds on EmulatorProcess
        from mirobot_async.testing import _pool as pool

        return getattr(pool, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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

# --------------------------------------------------------------------------------------------
# pytest plugin (entry point pytest11 -> mirobot_async.testing)

_MARKER_HELP = (
    "mirobot_emulator(firmware='2021', time_scale=0.0, extra_args=(), listen=None, fresh=False): "
    "settings of the virtual Mirobot behind the mirobot_emulator fixture (fresh: a new process, "
    "not one renewed from the pool)"
)
_MARKER_KEYS = frozenset({"firmware", "time_scale", "extra_args", "listen", "fresh"})
LINK_CHOICES = ("pty", "tcp", "both")


def pytest_addoption(parser: pytest.Parser) -> None:
    """Register ``--mirobot-firmware`` and ``--mirobot-time-scale``."""
    group = parser.getgroup("mirobot", "virtual Mirobot (mirobot-async)")
    group.addoption(
        "--mirobot-firmware",
        choices=("2021", "classic", "2024"),
        default=DEFAULT_FIRMWARE,
        help="firmware profile of the mirobot_emulator fixture (default: 2021)",
    )
    group.addoption(
        "--mirobot-time-scale",
        type=float,
        default=DEFAULT_TIME_SCALE,
        help="time scale of the mirobot_emulator fixture; 0 = instant motion (default: 0)",
    )
    group.addoption(
        "--mirobot-link",
        choices=LINK_CHOICES,
        default=None,
        help="link of the mirobot_emulator fixture: pty, tcp or both (each test runs once per "
        "link); default $MIROBOT_TEST_LINK, else pty where ptys exist",
    )
    group.addoption(
        "--mirobot-pool-size",
        type=int,
        default=None,
        metavar="N",
        help="idle emulator processes kept per link between tests and renewed for the next "
        "(default 2; 0: a new process for every test)",
    )


def pytest_configure(config: pytest.Config) -> None:
    """Register the ``mirobot_emulator`` marker (works with ``--strict-markers``)."""
    config.addinivalue_line("markers", _MARKER_HELP)


_PLUGIN_FIXTURES = frozenset({"mirobot_emulator", "mirobot_virtual_arm"})


def pytest_pycollect_makeitem(collector: Any, name: str, obj: object) -> None:
    """An ``async def`` test that takes this plugin's fixtures or wears its marker runs on
    pytest-asyncio even where the project has not set ``asyncio_mode = "auto"`` (README's example
    as written). Marked here, before pytest (its own hook runs last) builds the test item."""
    if not inspect.iscoroutinefunction(obj):
        return
    config = collector.config
    if not config.pluginmanager.hasplugin("asyncio"):
        return
    marks = {mark.name for mark in getattr(obj, "pytestmark", [])}
    if "asyncio" in marks:
        return
    if "mirobot_emulator" in marks or _PLUGIN_FIXTURES & set(inspect.signature(obj).parameters):
        import pytest

        pytest.mark.asyncio(obj)


def session_link(config: pytest.Config) -> str | None:
    """The link chosen for the whole session (``--mirobot-link``, else ``$MIROBOT_TEST_LINK``):
    ``pty``, ``tcp``, or ``None`` for ``both`` or no choice."""
    chosen: str | None = config.getoption("--mirobot-link", None)
    if chosen is None:
        chosen = default_link() if os.environ.get(LINK_ENV, "").strip() else None
    return None if chosen == "both" else chosen


def _argnames(names: Any) -> list[str]:
    if isinstance(names, str):
        return [name.strip() for name in names.split(",")]
    return [str(name) for name in names]


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Parametrise ``mirobot_link`` (hence the emulator fixtures) by ``--mirobot-link``."""
    if "mirobot_link" not in metafunc.fixturenames:
        return
    if any(
        "mirobot_link" in _argnames(mark.args[0])
        for mark in metafunc.definition.iter_markers("parametrize")
        if mark.args
    ):
        return  # the test parametrises it itself
    chosen = metafunc.config.getoption("--mirobot-link") or default_link()
    links = ["pty", "tcp"] if chosen == "both" else [chosen]
    metafunc.parametrize("mirobot_link", links, indirect=True, scope="function")


def _fixture_settings(request: Any, link: str) -> tuple[str, float, tuple[str, ...], str, bool]:
    firmware: str = request.config.getoption("--mirobot-firmware")
    time_scale: float = request.config.getoption("--mirobot-time-scale")
    extra: tuple[str, ...] = ()
    fresh = False
    marker = request.node.get_closest_marker("mirobot_emulator")
    if marker is not None:
        if marker.args:
            raise MirobotUsageError(
                "@pytest.mark.mirobot_emulator takes keyword arguments only "
                "(firmware=, time_scale=, extra_args=, listen=)"
            )
        unknown = set(marker.kwargs) - _MARKER_KEYS
        if unknown:
            raise MirobotUsageError(
                f"@pytest.mark.mirobot_emulator: unknown argument(s) {', '.join(sorted(unknown))}"
            )
        firmware = marker.kwargs.get("firmware", firmware)
        time_scale = marker.kwargs.get("time_scale", time_scale)
        extra = tuple(marker.kwargs.get("extra_args", ()))
        link = marker.kwargs.get("listen") or link
        fresh = bool(marker.kwargs.get("fresh", False))
    return firmware, time_scale, extra, link, fresh


def _define_fixtures() -> None:
    try:
        import pytest
    except ImportError:  # pragma: no cover - the plugin is only loaded by pytest
        return

    @pytest.fixture
    def mirobot_link(request: Any) -> str:
        """The arm's link for this test: ``pty`` or ``tcp`` (``--mirobot-link``)."""
        link: str = getattr(request, "param", None) or default_link()
        return link

    @pytest.fixture(scope="session")
    def mirobot_emulator_pool(request: Any) -> Iterator[EmulatorPool]:
        """Emulator processes renewed between this session's tests (every one stopped at its
        end; see :mod:`mirobot_async.testing._pool`). Size: ``--mirobot-pool-size``."""
        from mirobot_async.testing._pool import DEFAULT_MAX_IDLE, EmulatorPool

        size = request.config.getoption("--mirobot-pool-size")
        max_idle = DEFAULT_MAX_IDLE if size is None else size
        with EmulatorPool(max_idle, link=session_link(request.config)) as pool:
            yield pool

    @pytest.fixture
    def mirobot_emulator_process(
        request: Any, mirobot_link: str, mirobot_emulator_pool: EmulatorPool
    ) -> Iterator[SyncEmulatorProcess]:
        """A virtual Mirobot for this test, as a new process would be (see
        :mod:`mirobot_async.testing`): renewed from the session's pool, or started."""
        firmware, time_scale, extra, link, fresh = _fixture_settings(request, mirobot_link)
        with mirobot_emulator_pool.lend(
            firmware, time_scale, extra_args=extra, listen=link, fresh=fresh
        ) as emulator:
            yield emulator

    @pytest.fixture
    def mirobot_emulator(mirobot_emulator_process: SyncEmulatorProcess) -> str:
        """The port URL of a virtual Mirobot started for this test."""
        return mirobot_emulator_process.url

    @pytest.fixture
    def mirobot_virtual_arm(request: Any) -> Iterator[str]:
        """The ``virtual://N`` URL of a virtual Mirobot inside the test's own process
        (:class:`InProcessArm`: no subprocess, no pty), for ``Mirobot.connect``; the marker's
        ``firmware`` and ``time_scale`` apply (its process options do not)."""
        firmware, time_scale, extra, _link, _fresh = _fixture_settings(request, "pty")
        if extra:
            raise MirobotUsageError(
                "mirobot_virtual_arm runs in this process: extra_args (the emulator process's "
                "options) do not apply; use the mirobot_emulator fixture"
            )
        from mirobot_async.virtual import InProcessArm

        with InProcessArm(firmware, time_scale) as arm:
            yield arm.url

    globals()["mirobot_link"] = mirobot_link
    globals()["mirobot_emulator_pool"] = mirobot_emulator_pool
    globals()["mirobot_emulator_process"] = mirobot_emulator_process
    globals()["mirobot_emulator"] = mirobot_emulator
    globals()["mirobot_virtual_arm"] = mirobot_virtual_arm


if "pytest" in sys.modules:
    _define_fixtures()
