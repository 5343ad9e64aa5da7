"""Fixtures for the client's integration tests: a real emulator process on a real pty.

* ``profile``: both firmware profiles (``2021``, ``classic``), so every test using the emulator
  runs against each.
* ``emu``: an :class:`~mirobot_async.testing.EmulatorProcess` for the test, as a new process
  would be (its fault channel is ``await emu.control("drop-ok")``): a process of the session's
  pool (the plugin's ``mirobot_emulator_pool``) renewed with the test's options, or a new one.
  Its options come from the ``@pytest.mark.mirobot_emulator(firmware=..., time_scale=...,
  extra_args=..., fresh=...)`` marker (the plugin's marker); ``firmware`` there overrides the
  ``profile`` parameter; ``fresh=True`` asks for a process of its own. Default time scale 0:
  every motion completes at once.
* ``wire_spy``: a :class:`~mirobot_async.testing.WireSpy` (every byte written and received);
* ``arm``: a connected :class:`~mirobot_async.Mirobot` on ``emu`` (closed afterwards), its
  transport watched by ``wire_spy`` (the public ``open_transport`` seam).
* ``ready_arm``: ``arm`` unlocked (``$X`` + ``M50``), so motion works on both profiles.
* ``spawn``: ``spawn(call)`` starts a task cancelled and awaited when the test ends (the fault
  tests' concurrent calls; helpers for them in ``fault_harness.py``).

Every test module of the client also checks that no task is left behind (``no_leftover_tasks``,
in tests/conftest.py).
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import signal
import subprocess
import sys
import time
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from fault_harness import Spawn
from waiting import WaitTimeout

from mirobot_async import Mirobot, State
from mirobot_async._cli import main
from mirobot_async.testing import (
    EmulatorError,
    EmulatorPool,
    EmulatorProcess,
    InProcessArm,
    WireSpy,
    session_link,
)

PROFILES = ("2021", "classic", "2024")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """README's test command (no link chosen) runs the client's tests on in-process arms and
    leaves the tests of the emulator as a process (marked ``emulator_process``: faults on its
    wire, its control channel, its port) to the link lanes (``MIROBOT_TEST_LINK=pty|tcp``, as
    CI runs them)."""
    if session_link(config) is not None:
        return
    process = [item for item in items if item.get_closest_marker("emulator_process")]
    if process:
        config.hook.pytest_deselected(items=process)
        items[:] = [item for item in items if not item.get_closest_marker("emulator_process")]


def emulator_options(request: pytest.FixtureRequest, profile: str) -> dict[str, Any]:
    """The emulator settings of a test: its marker's keywords over the defaults."""
    options: dict[str, Any] = {"firmware": profile, "time_scale": 0.0, "extra_args": ()}
    marker = request.node.get_closest_marker("mirobot_emulator")
    if marker is not None:
        options.update(marker.kwargs)
    return options


@pytest.fixture(params=PROFILES)
def profile(request: pytest.FixtureRequest) -> str:
    """The firmware profile under test."""
    return str(request.param)


class InProcessEmulator(EmulatorProcess):
    """The ``emu`` of a test on the in-process link: an :class:`InProcessArm` behind the
    :class:`EmulatorProcess` API's ``url``; what only a process has (the control channel, a
    port, signals) fails with the way to ask for a process."""

    def __init__(self, arm: InProcessArm) -> None:
        # Not EmulatorProcess.__init__: there is no process.
        self.arm = arm
        self.url = arm.url
        self.command = ("in-process", arm.firmware_name, str(arm.time_scale))

    def _no_process(self, what: str) -> EmulatorError:
        return EmulatorError(
            f"cannot {what}: this test's emulator runs in-process; mark the test (or its "
            "module) @pytest.mark.emulator_process to get a process"
        )

    @property
    def pid(self) -> int:
        raise self._no_process("read the pid")

    @property
    def returncode(self) -> int | None:
        return None

    async def control(self, command: str, *, timeout: float = 5.0) -> str:  # noqa: ASYNC109
        raise self._no_process(f"send {command!r}")

    async def renew(self, *args: object, **kwargs: object) -> str:
        raise self._no_process("renew")

    def kill(self) -> None:
        raise self._no_process("kill it")

    async def stop(self, timeout: float = 5.0) -> int:  # noqa: ASYNC109
        raise self._no_process("stop it")


def runs_in_process(request: pytest.FixtureRequest, options: dict[str, Any]) -> bool:
    """Whether this test's ``emu`` is an in-process arm: README's test command (no link
    chosen) runs every client test on one, except those that need a process (marked
    ``emulator_process``, or asking for process options). ``--mirobot-link pty|tcp``
    (or ``$MIROBOT_TEST_LINK``) runs them all over that link instead."""
    if session_link(request.config) is not None:
        return False
    if request.node.get_closest_marker("emulator_process") is not None:
        return False
    return not (options["extra_args"] or options.get("listen") or options.get("fresh"))


EmulatorLender = Callable[..., contextlib.AbstractContextManager[str]]


@pytest.fixture
def lend_emulator(
    request: pytest.FixtureRequest, mirobot_emulator_pool: EmulatorPool
) -> EmulatorLender:
    """``with lend_emulator(firmware, time_scale) as url:`` an arm for one hypothesis example
    (a fresh power-on each time): in-process on README's test command, else a process of the
    session's pool on its link (as ``emu``). ``in_process_time_scale``: the time scale to use
    in-process instead (there lines reach the firmware the instant they are written, so a
    faster arm still moves while the lines after it are parsed)."""

    @contextlib.contextmanager
    def lend(
        firmware: str, time_scale: float, *, in_process_time_scale: float | None = None
    ) -> Iterator[str]:
        options = {"firmware": firmware, "time_scale": time_scale, "extra_args": ()}
        if runs_in_process(request, options):
            scale = time_scale if in_process_time_scale is None else in_process_time_scale
            with InProcessArm(firmware, scale) as arm:
                yield arm.url
            return
        with mirobot_emulator_pool.lend(firmware, time_scale) as emulator:
            yield emulator.url

    return lend


@pytest.fixture
async def emu(
    request: pytest.FixtureRequest, profile: str, mirobot_emulator_pool: EmulatorPool
) -> AsyncIterator[EmulatorProcess]:
    """An emulator for this test as a new process would be (renewed from the session's pool,
    or started); returned to the pool afterwards (or stopped, if it was killed or closed).
    On README's test command, an in-process arm unless the test needs a process."""
    options = emulator_options(request, profile)
    if runs_in_process(request, options):
        with InProcessArm(options["firmware"], options["time_scale"]) as arm:
            yield InProcessEmulator(arm)
        return
    async with mirobot_emulator_pool.lend_async(
        options["firmware"],
        options["time_scale"],
        extra_args=tuple(options["extra_args"]),
        listen=options.get("listen"),
        fresh=bool(options.get("fresh", False)),
    ) as emulator:
        yield emulator


@pytest.fixture
def wire_spy() -> WireSpy:
    """Records every chunk the ``arm`` fixture's client writes and receives."""
    return WireSpy()


@pytest.fixture
async def arm(emu: EmulatorProcess, wire_spy: WireSpy) -> AsyncIterator[Mirobot]:
    """A client connected to ``emu`` through ``wire_spy``."""
    async with Mirobot.connect(emu.url, open_transport=wire_spy.opener) as connected:
        yield connected


StateWait = Callable[..., Awaitable[None]]


async def _first_status(arm: Mirobot, state: State, limit: float = 5.0) -> None:
    started = time.monotonic()
    try:
        async with asyncio.timeout(limit):
            async with contextlib.aclosing(arm.statuses(interval=0.0)) as reports:
                async for report in reports:
                    if report.state is state:
                        return
    except TimeoutError:
        waited = time.monotonic() - started
        raise WaitTimeout(
            f"no status {state.value} within {limit} s (waited {waited:.2f} s)"
        ) from None


@pytest.fixture
def first_status() -> StateWait:
    """``await first_status(arm, state, limit=5.0)``: returns once a status of ``arm`` (polled
    back to back) shows ``state``; ``WaitTimeout`` (a ``TimeoutError``) after ``limit`` s."""
    return _first_status


@pytest.fixture
async def ready_arm(arm: Mirobot) -> Mirobot:
    """``arm`` with its axes unlocked (both profiles power on locked; 2021 also in Alarm)."""
    await arm.unlock()
    return arm


@pytest.fixture
async def spawn() -> AsyncIterator[Spawn]:
    """Start tasks that are cancelled and awaited (exceptions retrieved) when the test ends."""
    tasks: list[asyncio.Task[Any]] = []

    def start(awaitable: Awaitable[Any]) -> asyncio.Task[Any]:
        task = asyncio.ensure_future(_await(awaitable))
        tasks.append(task)
        return task

    yield start
    for task in tasks:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)


async def _await(awaitable: Awaitable[Any]) -> Any:
    return await awaitable


Cli = Callable[..., subprocess.CompletedProcess[str]]


@pytest.fixture
def cli(capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> Iterator[Cli]:
    """``mirobot ARGS`` as ``main(argv)`` in this process, to completion: its exit status and
    what it wrote, captured at the file descriptors (an embedded emulator's or a child's output
    is there too, as in a subprocess's pipes). Keywords: ``cwd`` (run from there), ``env``
    (added to the environment), ``stdin`` (the text standard input holds; default empty).
    ``main`` installs SIGINT/SIGTERM handlers while it runs: the test's are put back after."""
    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}

    def run(
        *args: str, cwd: Path | None = None, env: dict[str, str] | None = None, stdin: str = ""
    ) -> subprocess.CompletedProcess[str]:
        capfd.readouterr()  # only this command's output
        with monkeypatch.context() as patch:
            for name, value in (env or {}).items():
                patch.setenv(name, value)
            patch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(stdin.encode())))
            with contextlib.chdir(cwd) if cwd is not None else contextlib.nullcontext():
                try:
                    status: object = main(list(args))
                except SystemExit as exited:  # argparse: --help, usage errors
                    status = 0 if exited.code is None else exited.code
        out, err = capfd.readouterr()
        assert isinstance(status, int), status
        return subprocess.CompletedProcess(["mirobot", *args], status, out, err)

    try:
        yield run
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)
