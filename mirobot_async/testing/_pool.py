"""Emulator processes kept between tests: :class:`EmulatorPool` (one per process, e.g. per
pytest-xdist worker; the pytest plugin's ``mirobot_emulator_pool`` fixture is one per session).

Starting ``python -m mirobot_emulator`` costs ~0.2 s of CPU (an interpreter and numpy);
renewing a running one (its ``renew`` control command: a new port, a fresh power-on, only the
requested faults armed, counters at zero) costs milliseconds, and a client cannot tell the two
apart. The pool lends a process renewed with the borrower's settings, or starts one when none is
idle, and takes it back afterwards. It keeps (at most ``max_idle`` per link) only a process that
is still reusable: running, neither killed, stopped nor cut by a ``close`` fault, and renewed
once more on its return (which drops the borrower's client and any bytes in flight). Others are
stopped. Processes the pool starts get ``--exit-on-stdin-eof``: if the process owning the pool
dies, even by SIGKILL, its emulators exit too. Only the ``pty`` and ``tcp`` links are pooled;
a fixed ``HOST:PORT``, ``--listen``/``--link`` in ``extra_args`` or ``fresh=True`` get a new
process of their own, stopped when they are returned.

Async tests get a :class:`BorrowedEmulatorProcess`: the :class:`EmulatorProcess` API over the
pooled :class:`SyncEmulatorProcess`, whose blocking calls run in the pool's threads, so it works
on whatever event loop the test runs (pytest-asyncio gives each test its own).
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import threading
from collections.abc import AsyncIterator, Callable, Iterator, Sequence
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from typing import TypeVar

from mirobot_async.errors import MirobotTimeoutError
from mirobot_async.virtual._control import (
    CONTROL_TIMEOUT,
    DEFAULT_FIRMWARE,
    DEFAULT_TIME_SCALE,
    EXIT_ON_EOF,
    STARTUP_TIMEOUT,
    STOP_TIMEOUT,
    EmulatorError,
    default_link,
    emulator_args,
)
from mirobot_async.virtual._process import EmulatorProcess
from mirobot_async.virtual._sync import SyncEmulatorProcess

__all__ = ["DEFAULT_MAX_IDLE", "BorrowedEmulatorProcess", "EmulatorPool"]

_log = logging.getLogger("mirobot_async.testing")
_T = TypeVar("_T")

DEFAULT_MAX_IDLE = 2
"""Idle processes kept per link (a test borrows one at a time; a few borrow two)."""
POOLED_LINKS = ("pty", "tcp")
_PROCESS_OPTIONS = ("--listen", "--link", EXIT_ON_EOF)  # only a new process has other ones


class EmulatorPool:
    """Emulator processes lent to tests and renewed between them (thread-safe).

    :meth:`lend` (blocking) and :meth:`lend_async` are context managers lending a process for
    the duration of a block; :meth:`acquire` and :meth:`release` are the same in two calls.
    :meth:`close` stops every process the pool knows (idle or lent). ``max_idle`` 0 turns the
    pooling off: every borrower gets a new process, stopped on its return. With
    ``start_spares``, lending the last idle process of a link starts another in the background,
    so that the next borrower does not wait for a start when this one kills or closes its own;
    off by default: the start then competes for the CPU with the borrower's test, which can
    upset timing-sensitive tests on a loaded machine.
    """

    def __init__(
        self,
        max_idle: int = DEFAULT_MAX_IDLE,
        *,
        start_spares: bool = False,
        link: str | None = None,
    ) -> None:
        self.max_idle = max_idle
        self.start_spares = start_spares
        self.link = link
        """The link of a borrower that names none (``None``: :func:`default_link`)."""
        self._lock = threading.Lock()
        self._idle: dict[str, list[SyncEmulatorProcess]] = {}
        self._links: dict[SyncEmulatorProcess, str | None] = {}  # every process not stopped
        self._coming: dict[str, Future[None]] = {}  # a spare being started, per link
        self._closed = False
        self._executor = ThreadPoolExecutor(max_workers=4, thread_name_prefix="mirobot-emulator")
        self.started = 0
        """Processes started (a measure of what pooling saves)."""
        self.renewed = 0
        """Processes lent renewed instead of started."""

    # ------------------------------------------------------------------ blocking
    def acquire(
        self,
        firmware: str = DEFAULT_FIRMWARE,
        time_scale: float = DEFAULT_TIME_SCALE,
        *,
        extra_args: Sequence[str] = (),
        listen: str | None = None,
        fresh: bool = False,
        startup_timeout: float = STARTUP_TIMEOUT,
    ) -> SyncEmulatorProcess:
        """An emulator as a new one started with these settings would be (see
        :class:`SyncEmulatorProcess`); give it back with :meth:`release`.

        Renewing an idle one takes milliseconds (at most :data:`CONTROL_TIMEOUT` s before it
        is given up for a new process); starting one waits up to ``startup_timeout`` s
        (:class:`EmulatorError`). ``fresh``: a new process, never pooled.
        """
        emulator_args(firmware, time_scale, extra_args)  # bad settings: MirobotUsageError now
        link = listen or self.link or default_link()
        pooled = self._pooled(link, extra_args) and not fresh
        try:
            while pooled:
                with self._lock:
                    idle = self._idle.get(link)
                    emulator = idle.pop() if idle else None
                    coming = self._coming.get(link) if emulator is None else None
                if emulator is None:
                    if coming is None:
                        break
                    with contextlib.suppress(Exception):  # it comes to the idle list
                        coming.result()
                    with self._lock:  # (a spare cancelled by close() never ran to say so)
                        if self._coming.get(link) is coming:
                            del self._coming[link]
                    continue
                try:
                    emulator.renew(firmware, time_scale, extra_args=extra_args)
                except MirobotTimeoutError as exc:
                    _log.warning("emulator %d does not answer renew (%s)", emulator.pid, exc)
                    self._stop(emulator)
                    continue
                except EmulatorError as exc:  # refused these settings (unchanged), or dead
                    _log.debug("emulator %d not renewed (%s): starting one", emulator.pid, exc)
                    self._keep_or_stop(emulator, link)
                    break  # a new process gives the borrower the same answer (or error)
                self.renewed += 1
                return emulator
            return self._start(firmware, time_scale, extra_args, link, pooled, startup_timeout)
        finally:
            if pooled:
                self._start_spare(link)

    def _start(
        self,
        firmware: str,
        time_scale: float,
        extra_args: Sequence[str],
        link: str,
        pooled: bool,
        startup_timeout: float = STARTUP_TIMEOUT,
    ) -> SyncEmulatorProcess:
        extra = (*extra_args, EXIT_ON_EOF) if pooled else tuple(extra_args)
        emulator = SyncEmulatorProcess(
            firmware, time_scale, extra_args=extra, startup_timeout=startup_timeout, listen=link
        )
        with self._lock:
            self.started += 1
            self._links[emulator] = link if pooled else None
            closed = self._closed
        if closed:
            self._stop(emulator)
            raise EmulatorError("the emulator pool is closed")
        return emulator

    def _start_spare(self, link: str) -> None:
        """Start a process for the next borrower in the background (while this one's test
        runs) if no idle one is left for ``link`` and none is being started."""
        with self._lock:
            if not self.start_spares or self._closed or self._idle.get(link):
                return
            if link in self._coming:
                return
            self._coming[link] = self._executor.submit(self._make_spare, link)

    def _make_spare(self, link: str) -> None:
        try:
            spare = self._start(DEFAULT_FIRMWARE, DEFAULT_TIME_SCALE, (), link, True)
            self._keep_or_stop(spare, link)  # idle before it stops "coming": no gap to race
        except Exception as exc:  # the borrower that needs one starts it and sees why
            _log.debug("no spare emulator for %s: %s", link, exc)
        finally:
            with self._lock:
                self._coming.pop(link, None)

    def release(self, emulator: SyncEmulatorProcess) -> None:
        """Take back what :meth:`acquire` lent: keep it for the next borrower if it is still
        reusable and renews (at most :data:`CONTROL_TIMEOUT` s), else stop it."""
        with self._lock:
            link = self._links.get(emulator)
        if link is None or not emulator.reusable:
            self._stop(emulator)
            return
        try:
            emulator.renew()  # drops the borrower's client and bytes; proves it still answers
        except (EmulatorError, MirobotTimeoutError) as exc:
            _log.debug("emulator %d not renewed on its return (%s): stopping it", emulator.pid, exc)
            self._stop(emulator)
            return
        self._keep_or_stop(emulator, link)

    def _pooled(self, link: str, extra_args: Sequence[str]) -> bool:
        if self.max_idle <= 0 or link not in POOLED_LINKS:
            return False
        return not any(arg.split("=")[0] in _PROCESS_OPTIONS for arg in extra_args)

    def _keep_or_stop(self, emulator: SyncEmulatorProcess, link: str) -> None:
        with self._lock:
            idle = self._idle.setdefault(link, [])
            if emulator.reusable and not self._closed and len(idle) < self.max_idle:
                idle.append(emulator)
                return
        self._stop(emulator)

    def _stop(self, emulator: SyncEmulatorProcess) -> None:
        with self._lock:
            self._links.pop(emulator, None)
        emulator.stop()

    @contextlib.contextmanager
    def lend(
        self,
        firmware: str = DEFAULT_FIRMWARE,
        time_scale: float = DEFAULT_TIME_SCALE,
        *,
        extra_args: Sequence[str] = (),
        listen: str | None = None,
        fresh: bool = False,
    ) -> Iterator[SyncEmulatorProcess]:
        """:meth:`acquire` for the duration of the block, then :meth:`release`."""
        emulator = self.acquire(
            firmware, time_scale, extra_args=extra_args, listen=listen, fresh=fresh
        )
        try:
            yield emulator
        finally:
            self.release(emulator)

    def close(self) -> None:
        """Stop every process the pool knows, idle or lent (idempotent); lend no more."""
        with self._lock:
            self._closed = True
            emulators = list(self._links)
            self._idle.clear()
        for emulator in emulators:
            self._stop(emulator)
        self._executor.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> EmulatorPool:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # ------------------------------------------------------------------ asyncio
    @contextlib.asynccontextmanager
    async def lend_async(
        self,
        firmware: str = DEFAULT_FIRMWARE,
        time_scale: float = DEFAULT_TIME_SCALE,
        *,
        extra_args: Sequence[str] = (),
        listen: str | None = None,
        fresh: bool = False,
    ) -> AsyncIterator[EmulatorProcess]:
        """:meth:`lend` for asyncio: yields a :class:`BorrowedEmulatorProcess`.

        Acquiring and releasing run in the pool's threads (the event loop is not blocked).
        Cancelled while acquiring, the process is released when it arrives; the release at the
        end finishes even if the block is cancelled.
        """
        acquire = functools.partial(
            self.acquire, firmware, time_scale, extra_args=extra_args, listen=listen, fresh=fresh
        )
        future = self._executor.submit(acquire)
        try:
            emulator = await asyncio.shield(asyncio.wrap_future(future))
        except asyncio.CancelledError:
            future.add_done_callback(self._release_when_acquired)
            raise
        borrowed = BorrowedEmulatorProcess(emulator, self._executor)
        try:
            yield borrowed
        finally:
            borrowed.detach()
            release = self._executor.submit(self.release, emulator)  # finishes even if cancelled
            await asyncio.shield(asyncio.wrap_future(release))

    def _release_when_acquired(self, future: Future[SyncEmulatorProcess]) -> None:
        if not future.cancelled() and future.exception() is None:
            self.release(future.result())


class BorrowedEmulatorProcess(EmulatorProcess):
    """An :class:`EmulatorProcess` lent by an :class:`EmulatorPool` (see :meth:`lend_async`).

    The same API (``url``, ``command``, ``pid``, ``returncode``, :meth:`control`,
    :meth:`renew`, :meth:`kill`, :meth:`stop`) over a pooled :class:`SyncEmulatorProcess`; the
    blocking calls run in the pool's threads, so it works on any event loop. Killed, stopped
    or cut by a ``close`` fault, the process is not reused. Once returned to the pool the handle
    refuses every call (:class:`EmulatorError`): the process may be serving someone else.
    """

    def __init__(self, emulator: SyncEmulatorProcess, executor: Executor) -> None:
        # Not EmulatorProcess.__init__: there is no asyncio subprocess to read here.
        self._emulator = emulator
        self._executor = executor
        self._returned = False
        self.url = emulator.url
        self.command = emulator.command

    def detach(self) -> None:
        """The process went back to the pool: refuse every call from now on."""
        self._returned = True

    def _check(self, what: str) -> SyncEmulatorProcess:
        if self._returned:
            raise EmulatorError(f"cannot {what}: the emulator was returned to its pool")
        return self._emulator

    async def _call(self, func: Callable[[], _T]) -> _T:
        return await asyncio.wrap_future(self._executor.submit(func))

    @property
    def pid(self) -> int:
        """The emulator's process id."""
        return self._emulator.pid

    @property
    def returncode(self) -> int | None:
        """The exit status once the process has exited, else ``None``."""
        return self._emulator.returncode

    async def control(self, command: str, *, timeout: float = CONTROL_TIMEOUT) -> str:
        """As :meth:`EmulatorProcess.control` (a cancelled call still gets its answer, which
        is then dropped: the next call is not confused by it)."""
        emulator = self._check(f"send {command!r}")
        return await self._call(functools.partial(emulator.control, command, timeout=timeout))

    async def renew(
        self,
        firmware: str = DEFAULT_FIRMWARE,
        time_scale: float = DEFAULT_TIME_SCALE,
        *,
        extra_args: Sequence[str] = (),
        timeout: float = CONTROL_TIMEOUT,
    ) -> str:
        """As :meth:`EmulatorProcess.renew`."""
        emulator = self._check("renew")
        renew = functools.partial(
            emulator.renew, firmware, time_scale, extra_args=extra_args, timeout=timeout
        )
        self.url = await self._call(renew)
        self.command = emulator.command
        return self.url

    def kill(self) -> None:
        """SIGKILL the emulator now (like a pulled cable; it is not reused); does not wait."""
        self._check("kill").kill()

    async def stop(self, timeout: float = STOP_TIMEOUT) -> int:
        """Stop the emulator (SIGTERM, then SIGKILL after ``timeout`` s; it is not reused) and
        return its exit status. Idempotent; cancelled, the clean-up still finishes."""
        emulator = self._check("stop")
        stopping = asyncio.wrap_future(self._executor.submit(emulator.stop, timeout))
        try:
            return await asyncio.shield(stopping)
        except asyncio.CancelledError:
            await asyncio.wait({stopping})
            raise
