"""The event loop thread behind :mod:`mirobot_async.sync`, and blocking calls into it.

One asyncio loop runs in a daemon thread; :meth:`EventLoopThread.call` submits a coroutine and
blocks the calling thread until it ends, meanwhile running the callbacks the loop hands back
(so user callbacks run in the caller's thread).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import functools
import queue
import threading
from collections.abc import Awaitable, Callable, Coroutine
from typing import Any, TypeVar

from mirobot_async.errors import MirobotLinkLostError, MirobotUsageError

__all__ = [
    "CANCEL_GRACE",
    "LOOP_THREAD_NAME",
    "STOP_TIMEOUT",
    "CallerThreadCallback",
    "EventLoopThread",
    "LoopStopped",
    "run_detached",
]

T = TypeVar("T")

LOOP_THREAD_NAME = "mirobot-sync-loop"
STOP_TIMEOUT = 5.0
"""Seconds :meth:`EventLoopThread.stop` waits for the loop's tasks and thread to end."""
CANCEL_GRACE = 2.0
"""Seconds an interrupted call waits for its cancellation to reach the loop before re-raising."""

_DONE = object()


class CallbackJob:
    """One invocation of a user callback, queued by the loop for the calling thread to run."""

    def __init__(
        self,
        function: Callable[..., object],
        args: tuple[Any, ...],
        kwargs: dict[str, Any],
        loop: asyncio.AbstractEventLoop,
        future: asyncio.Future[object],
    ) -> None:
        self.function = function
        self.args = args
        self.kwargs = kwargs
        self.loop = loop
        self.future = future

    def run(self) -> None:
        """Run the callback here and hand its result (or ``Exception``) to the loop's future."""
        try:
            value = self.function(*self.args, **self.kwargs)
        except Exception as err:  # handed to the loop: it ends the call as in asyncio
            self._settle(functools.partial(self.future.set_exception, err))
        except BaseException:  # KeyboardInterrupt & co.: interrupt this thread's call
            self._settle(self.future.cancel)
            raise
        else:
            self._settle(functools.partial(self.future.set_result, value))

    def abandon(self) -> None:
        """The call was interrupted: do not run the callback, release the loop."""
        self._settle(self.future.cancel)

    def _settle(self, action: Callable[[], object]) -> None:
        def apply() -> None:
            if not self.future.done():
                action()

        with contextlib.suppress(RuntimeError):  # the loop is already closed
            self.loop.call_soon_threadsafe(apply)


class CallerThreadCallback:
    """Stands in for a user callback on the loop: queues it for the waiting thread to run.

    Returns an awaitable future, so the asyncio code (which awaits awaitable callback results)
    waits for the callback to finish in the caller's thread and sees its exception.
    """

    def __init__(self, function: Callable[..., object], inbox: queue.SimpleQueue[object]) -> None:
        self.function = function
        self.inbox = inbox
        self.finished = False

    def __call__(self, *args: Any, **kwargs: Any) -> object:
        if self.finished:  # called after its call returned: nobody waits, run it here
            return self.function(*args, **kwargs)
        loop = asyncio.get_running_loop()
        future: asyncio.Future[object] = loop.create_future()
        self.inbox.put(CallbackJob(self.function, args, kwargs, loop, future))
        return future


class EventLoopThread:
    """One asyncio event loop running in a daemon thread, and blocking calls into it."""

    def __init__(self, name: str = LOOP_THREAD_NAME) -> None:
        self.loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._submit_lock = threading.Lock()
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()
        self._ready.wait()

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        self.loop.call_soon(self._ready.set)
        try:
            self.loop.run_forever()
        finally:
            self.loop.close()

    @property
    def running(self) -> bool:
        """True until :meth:`stop` is called (calls are accepted)."""
        return not self._stopping and self._thread.is_alive()

    def _submit(self, coroutine: Coroutine[Any, Any, T]) -> concurrent.futures.Future[T]:
        with self._submit_lock:
            if not self.running:
                coroutine.close()
                raise LoopStopped
            return asyncio.run_coroutine_threadsafe(coroutine, self.loop)

    def in_loop_thread(self) -> bool:
        """True when called from the loop's own thread."""
        return threading.current_thread() is self._thread

    def call(
        self,
        invoke: Callable[[], Awaitable[T]],
        inbox: queue.SimpleQueue[object] | None = None,
    ) -> T:
        """Run ``invoke()`` on the loop and block until it ends; return its result or raise.

        While waiting, run the callbacks the loop queues in ``inbox`` (see
        :class:`CallerThreadCallback`). No timeout of its own (the coroutine has its own). Any
        exception in this thread (``KeyboardInterrupt``) cancels the coroutine, waits up to
        :data:`CANCEL_GRACE` seconds for the cancellation to land, and propagates.
        """
        if self.in_loop_thread():
            raise MirobotUsageError(
                "a blocking mirobot_async.sync call was made on its own event loop thread "
                "(from a callback run by the loop?); it would wait for itself forever"
            )
        box: queue.SimpleQueue[object] = inbox if inbox is not None else queue.SimpleQueue()

        async def run() -> T:
            return await invoke()

        future = self._submit(run())
        future.add_done_callback(lambda _: box.put(_DONE))
        try:
            while (item := box.get()) is not _DONE:
                assert isinstance(item, CallbackJob)
                item.run()
        except BaseException:
            future.cancel()
            with contextlib.suppress(BaseException):
                concurrent.futures.wait([future], timeout=CANCEL_GRACE)
            _abandon_jobs(box)
            raise
        try:
            return future.result()
        except concurrent.futures.CancelledError:
            # Cancelled on the loop (it is stopping): the facade was closed under this call.
            raise MirobotLinkLostError("the connection was closed") from None

    def read(self, getter: Callable[[], T]) -> T:
        """Evaluate ``getter()`` on the loop (attributes the loop mutates), or here if stopped."""
        if self.in_loop_thread():
            return getter()

        async def evaluate() -> T:
            return getter()

        try:
            future = self._submit(evaluate())
        except LoopStopped:
            return getter()
        try:
            return future.result(STOP_TIMEOUT)
        except concurrent.futures.CancelledError:  # stopped meanwhile
            return getter()

    def stop(self, timeout: float = STOP_TIMEOUT) -> None:
        """Cancel the loop's remaining tasks, finalize async generators, stop, join. Idempotent."""
        if self.in_loop_thread():
            raise MirobotUsageError("close() was called on the sync facade's own loop thread")
        with self._submit_lock:
            was_running = self.running
            self._stopping = True
        if was_running:
            wind_down = asyncio.run_coroutine_threadsafe(_wind_down(), self.loop)
            with contextlib.suppress(BaseException):
                wind_down.result(timeout)
            with contextlib.suppress(RuntimeError):
                self.loop.call_soon_threadsafe(self.loop.stop)
        self._thread.join(timeout)


class LoopStopped(Exception):
    """The loop thread no longer accepts calls (its owner was closed)."""


async def _wind_down() -> None:
    current = asyncio.current_task()
    tasks = [task for task in asyncio.all_tasks() if task is not current]
    for task in tasks:
        task.cancel()
    if tasks:
        await asyncio.wait(tasks, timeout=STOP_TIMEOUT)
    loop = asyncio.get_running_loop()
    await loop.shutdown_asyncgens()
    await loop.shutdown_default_executor()


def _abandon_jobs(box: queue.SimpleQueue[object]) -> None:
    while True:
        try:
            item = box.get_nowait()
        except queue.Empty:
            return
        if isinstance(item, CallbackJob):
            item.abandon()


def run_detached(invoke: Callable[[], Awaitable[T]]) -> T:
    """Run ``invoke()`` on a throw-away loop in a throw-away thread (joined before returning).

    Used when no loop thread runs (not connected, or closed): the asyncio object then raises
    exactly what it raises after ``close()``, and no thread is left behind.
    """
    outcome: list[Any] = []

    def target() -> None:
        async def run() -> T:
            return await invoke()

        try:
            outcome.append((True, asyncio.run(run())))
        except BaseException as err:  # re-raised in the calling thread
            outcome.append((False, err))

    thread = threading.Thread(target=target, name=f"{LOOP_THREAD_NAME}-detached", daemon=True)
    thread.start()
    thread.join()
    ok, value = outcome[0]
    if ok:
        return value  # type: ignore[no-any-return]
    raise value
