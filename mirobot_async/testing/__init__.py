"""Run the virtual Mirobot in tests: :func:`start_emulator` and a pytest plugin.

::

    from mirobot_async import Mirobot
    from mirobot_async.testing import start_emulator

    async with start_emulator(firmware="classic", time_scale=100) as url:
        async with Mirobot.connect(url) as arm:
            await arm.home()

:func:`start_emulator` starts ``python -m mirobot_emulator`` (the ``mirobot-emulator`` command) as
a subprocess in its own session (a terminal's Ctrl-C reaches only the program that started it)
on a fresh pseudo-terminal, or with ``listen="tcp"`` on a loopback TCP port (``socket://...``;
the default where there are no ptys, or everywhere with ``MIROBOT_TEST_LINK=tcp``), yields its
port URL and stops the process when the block ends (SIGTERM, then SIGKILL if it does not exit
within a few seconds). :class:`EmulatorProcess` is the same with a handle: ``.url``,
``await .control("drop-ok")`` for the emulator's fault-injection channel (it returns the
emulator's ``ack`` line), ``.kill()`` to pull the cable abruptly.

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

import asyncio
import contextlib
import inspect
import logging
import os
import signal
import sys
from collections.abc import AsyncIterator, Iterator, Sequence
from typing import TYPE_CHECKING, Any

from mirobot_async.errors import MirobotTimeoutError, MirobotUsageError
from mirobot_async.testing._control import (
    CONTROL_TIMEOUT,
    DEFAULT_FIRMWARE,
    DEFAULT_TIME_SCALE,
    LINK_ENV,
    STARTUP_TIMEOUT,
    STOP_TIMEOUT,
    EmulatorError,
    control_reply,
    control_result,
    control_text,
    default_link,
    emulator_command,
    renew_text,
    renewed_command,
    renewed_url,
)
from mirobot_async.testing._sync import SyncEmulatorProcess, run_emulator

_log = logging.getLogger("mirobot_async.testing")

if TYPE_CHECKING:
    import pytest

    from mirobot_async.testing._pool import BorrowedEmulatorProcess, EmulatorPool
    from mirobot_async.testing._spy import WireSpy
    from mirobot_async.testing._virtual import InProcessArm


def __getattr__(name: str) -> Any:
    if name == "WireSpy":  # imported on first use (it needs the client's wire module)
        from mirobot_async.testing._spy import WireSpy

        return WireSpy
    if name == "InProcessArm":  # imported on first use (it loads the firmware model)
        from mirobot_async.testing._virtual import InProcessArm

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
# asyncio


class EmulatorProcess:
    """A running emulator subprocess, driven from asyncio. Create with :meth:`start`.

    Use it as an async context manager (``async with await EmulatorProcess.start() as emu``) or
    call :meth:`stop` yourself; either way no process is left behind.
    """

    def __init__(
        self, process: asyncio.subprocess.Process, url: str, command: Sequence[str]
    ) -> None:
        self._process = process
        self.url = url
        """The emulator's port (a pty path or ``socket://HOST:PORT``) for ``Mirobot.connect``."""
        self.command = tuple(command)
        self._replies: asyncio.Queue[str | None] = asyncio.Queue()
        self._control_lock = asyncio.Lock()
        self._reader = asyncio.get_running_loop().create_task(
            self._read_stdout(), name=f"mirobot-emulator-stdout-{process.pid}"
        )

    @classmethod
    async def start(
        cls,
        firmware: str = DEFAULT_FIRMWARE,
        time_scale: float = DEFAULT_TIME_SCALE,
        *,
        extra_args: Sequence[str] = (),
        startup_timeout: float = STARTUP_TIMEOUT,
        listen: str | None = None,
    ) -> EmulatorProcess:
        """Start an emulator and wait for its port URL (at most ``startup_timeout`` seconds).

        ``listen``: ``"pty"``, ``"tcp"`` (a free loopback port) or ``"HOST:PORT"``; ``None``:
        ``$MIROBOT_TEST_LINK``, else a pty where ptys exist. Raises :class:`EmulatorError` if it
        exits or prints nothing in time (the process is then killed). Cancellation kills the
        process too.
        """
        command = emulator_command(firmware, time_scale, extra_args, listen)
        process = await asyncio.create_subprocess_exec(
            *command,
            stdin=asyncio.subprocess.PIPE,
            stdout=asyncio.subprocess.PIPE,
            start_new_session=True,  # a terminal's Ctrl-C reaches only the program that owns it
        )
        try:
            assert process.stdout is not None
            try:
                async with asyncio.timeout(startup_timeout):
                    first = await process.stdout.readline()
            except TimeoutError as err:
                raise EmulatorError(
                    f"the emulator printed no port path within {startup_timeout:g} s"
                ) from err
            url = first.decode("utf-8", "replace").strip()
            if not url:
                raise EmulatorError(
                    f"the emulator exited before printing its port path: {' '.join(command)}"
                )
        except BaseException:
            await _reap(process, kill_first=True)
            raise
        _log.debug("emulator %d serving %s", process.pid, url)
        return cls(process, url, command)

    @property
    def pid(self) -> int:
        """The emulator's process id."""
        return self._process.pid

    @property
    def returncode(self) -> int | None:
        """The exit status once the process has exited, else ``None``."""
        return self._process.returncode

    async def _read_stdout(self) -> None:
        stdout = self._process.stdout
        assert stdout is not None
        try:
            while line := await stdout.readline():
                reply = control_reply(line)
                if reply is not None:
                    self._replies.put_nowait(reply)
        except (OSError, ValueError):  # pragma: no cover - pipe torn down
            pass
        finally:
            self._replies.put_nowait(None)

    async def control(self, command: str, *, timeout: float = CONTROL_TIMEOUT) -> str:
        """Send one control command (``drop-ok``, ``corrupt-status``, ``ignore-status``,
        ``stall S``, ``hard-limit``, ``reset``, ``close``, ``time-scale X``, ``split-bytes on|off``,
        ``delay MS``, ``stats``, ``motion-ends``) and return the emulator's ``ack ...`` line, which
        means the fault is armed or done (``stats`` answers with the emulator's counters in that
        line, ``motion-ends`` with the ``time.monotonic()`` instants at which motion last ended).

        Raises :class:`EmulatorError` if the emulator refuses the command or has exited, and
        :class:`MirobotTimeoutError` after ``timeout`` seconds without an answer. Commands are
        answered in order; concurrent calls are serialised. Cancellation is safe (a late answer
        is skipped by the next call only if it has no reply waiting: prefer not to cancel).
        """
        text = control_text(command)
        async with self._control_lock:
            stdin = self._process.stdin
            if stdin is None or self._process.returncode is not None or stdin.is_closing():
                raise EmulatorError(f"cannot send {text!r}: the emulator is not running")
            stdin.write(text.encode("utf-8") + b"\n")
            try:
                async with asyncio.timeout(timeout):
                    await stdin.drain()
                    reply = await self._replies.get()
            except TimeoutError as err:
                raise MirobotTimeoutError(f"the emulator's answer to {text!r}", timeout) from err
            except (ConnectionError, OSError) as err:
                raise EmulatorError(f"cannot send {text!r}: {err}") from err
            if reply is None:
                self._replies.put_nowait(None)  # keep reporting the end to later calls
            return control_result(text, reply)

    async def renew(
        self,
        firmware: str = DEFAULT_FIRMWARE,
        time_scale: float = DEFAULT_TIME_SCALE,
        *,
        extra_args: Sequence[str] = (),
        timeout: float = CONTROL_TIMEOUT,
    ) -> str:
        """Make the running emulator what a new one started with these settings would be: a new
        port (its URL is returned and becomes :attr:`url`), a fresh power-on, only the faults of
        ``extra_args`` armed, counters at zero; milliseconds instead of a process start.

        ``extra_args`` cannot name ``--listen`` or ``--link``. Raises :class:`EmulatorError` if
        the emulator refuses or has exited, :class:`MirobotTimeoutError` after ``timeout`` s
        (as :meth:`control`).
        """
        text = renew_text(firmware, time_scale, extra_args)
        url = renewed_url(await self.control(text, timeout=timeout))
        self.url = url
        self.command = tuple(renewed_command(self.command, firmware, time_scale, extra_args))
        return url

    def kill(self) -> None:
        """SIGKILL the emulator now (its port disappears, like a pulled cable); does not wait."""
        if self._process.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                self._process.kill()

    async def stop(self, timeout: float = STOP_TIMEOUT) -> int:
        """Stop the emulator: SIGTERM, wait up to ``timeout`` s, then SIGKILL. Idempotent.

        Returns the exit status. Waits for the process and its pipes to be fully released, so no
        process or file descriptor is left behind (also when cancelled: the clean-up finishes).
        """
        task = asyncio.ensure_future(self._stop(timeout))
        try:
            return await asyncio.shield(task)
        except asyncio.CancelledError:
            await asyncio.wait({task})
            raise

    async def _stop(self, timeout: float) -> int:
        process = self._process
        if process.stdin is not None and not process.stdin.is_closing():
            process.stdin.close()
        if process.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                process.send_signal(signal.SIGTERM)
        returncode = await _reap(process, timeout=timeout)
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(timeout):
                await asyncio.wait({self._reader})  # the reader's own failure is not ours
        await _cancel_and_wait(self._reader)  # still running: stdout held open by a grandchild
        if process.stdin is not None:
            with contextlib.suppress(Exception):
                await process.stdin.wait_closed()
        return returncode

    async def __aenter__(self) -> EmulatorProcess:
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.stop()


async def _cancel_and_wait(*tasks: asyncio.Task[Any]) -> None:
    """Cancel ``tasks`` and wait until they are done, logging their failures.

    A task's own failure is logged, never raised (it must not replace the caller's result or
    exception); a cancellation of the calling task while waiting propagates (``gather`` raises
    :class:`asyncio.CancelledError` only then: the tasks' own cancellations are results).
    """
    for task in tasks:
        task.cancel()
    results = await asyncio.gather(*tasks, return_exceptions=True)
    for task, result in zip(tasks, results, strict=True):
        if isinstance(result, Exception):  # not CancelledError (a BaseException)
            _log.warning("%s failed: %r", task.get_name(), result, exc_info=result)


async def _reap(
    process: asyncio.subprocess.Process, *, timeout: float = STOP_TIMEOUT, kill_first: bool = False
) -> int:
    """Wait for ``process`` to exit (killing it after ``timeout``); return its status."""
    if kill_first and process.returncode is None:
        with contextlib.suppress(ProcessLookupError):
            process.kill()
    if process.stdin is not None and not process.stdin.is_closing():
        process.stdin.close()
    try:
        async with asyncio.timeout(timeout):
            return await process.wait()
    except TimeoutError:
        _log.warning("emulator %d did not exit after SIGTERM; killing it", process.pid)
        with contextlib.suppress(ProcessLookupError):
            process.kill()
        return await process.wait()


@contextlib.asynccontextmanager
async def start_emulator(
    firmware: str = DEFAULT_FIRMWARE,
    time_scale: float = DEFAULT_TIME_SCALE,
    *,
    extra_args: Sequence[str] = (),
    startup_timeout: float = STARTUP_TIMEOUT,
    listen: str | None = None,
    in_process: bool = False,
) -> AsyncIterator[str]:
    """Run a virtual Mirobot for the duration of the block; yields its port URL.

    ``firmware`` is ``"2021"``, ``"classic"`` or ``"2024"``; ``time_scale`` is simulated seconds
    per wall
    second (0: motion completes at once, 1: real time, 100: a 10 s homing takes 0.1 s);
    ``extra_args`` go to the ``mirobot-emulator`` command line (``--baud``, ``--fault``...);
    ``listen`` is ``"pty"``, ``"tcp"`` or ``"HOST:PORT"`` (``None``: ``$MIROBOT_TEST_LINK``, else a
    pty where ptys exist).
    Startup waits at most ``startup_timeout`` s (:class:`EmulatorError`); on exit the process is
    stopped and reaped even if the block was cancelled. Use :class:`EmulatorProcess` for a
    handle with the fault-injection channel.

    ``in_process=True`` runs the firmware model inside this process instead
    (:class:`~mirobot_async.testing._virtual.InProcessArm`, a ``virtual://N`` URL for
    ``Mirobot.connect``): no subprocess and no pty, a test costs milliseconds; ``extra_args``
    and ``listen`` are then refused (the process's options: pacing, faults, links).
    """
    if in_process:
        if extra_args or listen is not None:
            raise MirobotUsageError(
                "start_emulator(in_process=True) takes no extra_args or listen: those are "
                "options of the emulator process"
            )
        from mirobot_async.testing._virtual import InProcessArm

        with InProcessArm(firmware, time_scale) as arm:
            yield arm.url
        return
    emulator = await EmulatorProcess.start(
        firmware,
        time_scale,
        extra_args=extra_args,
        startup_timeout=startup_timeout,
        listen=listen,
    )
    try:
        yield emulator.url
    finally:
        await emulator.stop()


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
        from mirobot_async.testing._virtual import InProcessArm

        with InProcessArm(firmware, time_scale) as arm:
            yield arm.url

    globals()["mirobot_link"] = mirobot_link
    globals()["mirobot_emulator_pool"] = mirobot_emulator_pool
    globals()["mirobot_emulator_process"] = mirobot_emulator_process
    globals()["mirobot_emulator"] = mirobot_emulator
    globals()["mirobot_virtual_arm"] = mirobot_virtual_arm


if "pytest" in sys.modules:
    _define_fixtures()
