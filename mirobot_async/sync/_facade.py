"""Generating a blocking facade from an asyncio class (the rules are in :mod:`mirobot_async.sync`).

``class X(BlockingFacade, wraps=AsyncX)`` installs, for every public member of ``AsyncX`` that
``X`` does not define itself, a blocking version chosen by the member's kind: coroutine function,
async generator function, plain method (an awaitable result is awaited), class method, property,
plain class attribute. Attributes the asyncio object sets on itself read and write through.
"""

from __future__ import annotations

import contextlib
import functools
import inspect
import queue
import threading
import weakref
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any, Generic, TypeVar

from mirobot_async.errors import MirobotLinkLostError
from mirobot_async.sync._loop import (
    CallerThreadCallback,
    EventLoopThread,
    LoopStopped,
    run_detached,
)

__all__ = ["BlockingContextManager", "BlockingFacade", "BlockingIterator"]

T = TypeVar("T")

# ---- adapters for what the asyncio methods return ----------------------------------------------


class BlockingIterator(Generic[T]):
    """An async iterator driven from another thread: ``for item in it``; :meth:`close` ends it.

    Each ``next()`` waits for one ``__anext__`` on the loop (with the iterator's own timeouts).
    Use it as a context manager (or call :meth:`close`) to release it at once when you stop early;
    otherwise it is released when garbage collected.
    """

    def __init__(self, iterator: AsyncIterator[T], runner: Callable[..., Any]) -> None:
        self._iterator = iterator
        self._runner = runner
        self._closed = False

    def __iter__(self) -> BlockingIterator[T]:
        return self

    def __next__(self) -> T:
        if self._closed:
            raise StopIteration

        async def step() -> T:
            return await anext(self._iterator)

        try:
            value: T = self._runner(step)
        except StopAsyncIteration:
            self._closed = True
            raise StopIteration from None
        return value

    def close(self) -> None:
        """Close the underlying async iterator (``aclose()``) now. Idempotent."""
        if self._closed:
            return
        self._closed = True
        aclose = getattr(self._iterator, "aclose", None)
        if aclose is not None:
            with contextlib.suppress(MirobotLinkLostError):
                self._runner(aclose)

    def __enter__(self) -> BlockingIterator[T]:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


class BlockingContextManager(Generic[T]):
    """An async context manager driven from another thread, usable with ``with``. What its
    ``__aenter__`` returns is adapted too, unless it is the manager itself (``arm.view()``
    enters as the view: its properties are read from any thread)."""

    def __init__(
        self, manager: Any, runner: Callable[..., Any], adapt: Callable[[Any], Any] | None = None
    ) -> None:
        self._manager = manager
        self._runner = runner
        self._adapt = adapt

    def __enter__(self) -> T:
        value: T = self._runner(self._manager.__aenter__)
        if self._adapt is not None and value is not self._manager:
            value = self._adapt(value)
        return value

    def __exit__(self, *exc_info: Any) -> bool:
        return bool(self._runner(functools.partial(self._manager.__aexit__, *exc_info)))


# ---- the generated facade -----------------------------------------------------------------------


def _callable_parameters(signature: inspect.Signature) -> frozenset[str]:
    """Names of the parameters annotated as callables (callbacks to run in the caller's thread)."""
    return frozenset(
        name
        for name, parameter in signature.parameters.items()
        if "Callable[" in str(parameter.annotation)
    )


class BlockingFacade:
    """Base of a blocking facade generated from an asyncio class: ``class X(BlockingFacade,
    wraps=AsyncX)``. See the module docstring for the rules; members the subclass defines itself
    are kept."""

    _wraps: type[Any] = object

    def __init_subclass__(cls, *, wraps: type[Any], **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls._wraps = wraps
        own = {name for klass in cls.__mro__[:-1] for name in vars(klass)}
        for name in dir(wraps):
            if name.startswith("_") or name in own:
                continue
            member = _facade_member(wraps, name)
            function = getattr(member, "__func__", member)
            if callable(function) and not isinstance(member, property):
                function.__qualname__ = f"{cls.__qualname__}.{name}"
            setattr(cls, name, member)
        init = _make_init(wraps)
        cls.__init__ = init  # type: ignore[method-assign]

    def __init__(self, *args: Any, **kwargs: Any) -> None:  # replaced per subclass
        self._adopt(self._wraps(*args, **kwargs), None)

    def _adopt(self, target: Any, loop: EventLoopThread | None) -> None:
        self.__dict__["_target"] = target
        self.__dict__["_loop"] = loop
        self.__dict__["_lock"] = threading.Lock()
        if loop is not None:
            self.__dict__["_finalizer"] = weakref.finalize(self, _finalize, target, loop)

    @classmethod
    def _wrap_connected(cls, target: Any, loop: EventLoopThread) -> Any:
        facade = cls.__new__(cls)
        facade._adopt(target, loop)
        return facade

    # -- calls

    def _run(self, invoke: Callable[[], Awaitable[T]], inbox: Any = None) -> T:
        loop: EventLoopThread | None = self.__dict__.get("_loop")
        if loop is not None:
            try:
                return loop.call(invoke, inbox)
            except LoopStopped:
                pass
        return run_detached(invoke)

    def _run_adapted(self, invoke: Callable[[], Awaitable[Any]]) -> Any:
        return self._adapt(self._run(invoke))

    def _adapt(self, value: Any) -> Any:
        """A value returned by the asyncio object, made usable from a thread without a loop."""
        if value is self.__dict__.get("_target"):
            return self
        if hasattr(value, "__anext__"):
            return BlockingIterator(value, self._run)
        if hasattr(value, "__aenter__") and hasattr(value, "__aexit__"):
            return BlockingContextManager(value, self._run, self._adapt)
        return value

    # -- attributes the asyncio object sets on itself (not visible on its class)

    def __getattr__(self, name: str) -> Any:
        target = self.__dict__.get("_target")
        if name.startswith("_") or target is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        loop: EventLoopThread | None = self.__dict__.get("_loop")
        if loop is None:
            return getattr(target, name)
        return loop.read(lambda: getattr(target, name))

    def __setattr__(self, name: str, value: Any) -> None:
        if name.startswith("_"):
            object.__setattr__(self, name, value)
            return
        target = self.__dict__["_target"]
        loop: EventLoopThread | None = self.__dict__.get("_loop")
        if loop is None:
            setattr(target, name, value)
        else:
            loop.read(lambda: setattr(target, name, value))

    # -- lifecycle

    def close(self) -> None:
        """Close the asyncio object (its ``close()``), stop the loop and join its thread.

        Idempotent; never hangs longer than about :data:`STOP_TIMEOUT` seconds. Calls waiting in
        other threads fail as they would in asyncio (``MirobotLinkLostError``).
        """
        target = self.__dict__["_target"]
        with self.__dict__["_lock"]:
            loop: EventLoopThread | None = self.__dict__.get("_loop")
            finalizer: weakref.finalize[Any, Any] | None = self.__dict__.get("_finalizer")
            if finalizer is not None:
                finalizer.detach()
            close = getattr(target, "close", None)
            try:
                if close is not None and loop is not None and loop.running:
                    loop.call(close)
            finally:
                if loop is not None:
                    loop.stop()

    def __enter__(self) -> Any:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __dir__(self) -> list[str]:
        """The class's names and the asyncio object's attributes (for tab completion)."""
        target = self.__dict__.get("_target")
        names = set(super().__dir__())
        if target is not None:
            names.update(name for name in vars(target) if not name.startswith("_"))
        return sorted(names)

    def __repr__(self) -> str:
        return f"<blocking {self.__dict__.get('_target')!r}>"


def _finalize(target: Any, loop: EventLoopThread) -> None:
    """Garbage collection or interpreter exit of a facade that was not closed."""
    with contextlib.suppress(Exception):
        close = getattr(target, "close", None)
        if close is not None and loop.running and not loop.in_loop_thread():
            loop.call(close)
    loop.stop(timeout=1.0)


def _make_init(wraps: type[Any]) -> Callable[..., None]:
    def __init__(self: BlockingFacade, *args: Any, **kwargs: Any) -> None:
        self._adopt(wraps(*args, **kwargs), None)

    __init__.__signature__ = inspect.signature(wraps.__init__)  # type: ignore[attr-defined]
    __init__.__doc__ = f"An unconnected object, as ``{wraps.__qualname__}(...)``."
    return __init__


def _facade_member(wraps: type[Any], name: str) -> Any:
    """The facade's version of ``wraps.<name>``, chosen by what kind of member it is."""
    static = inspect.getattr_static(wraps, name)
    if isinstance(static, classmethod):
        return classmethod(_blocking_classmethod(wraps, name, static.__func__))
    if isinstance(static, staticmethod) or not callable(static):
        if isinstance(static, staticmethod):
            return static
        return _forwarding_property(name, static)
    return _blocking_method(name, static)


def _forwarding_property(name: str, static: Any) -> property:
    """Read (and, if the original allows, write) ``name`` on the asyncio object."""

    def get(self: BlockingFacade) -> Any:
        target = self.__dict__["_target"]
        loop: EventLoopThread | None = self.__dict__.get("_loop")
        if loop is None:
            return getattr(target, name)
        return loop.read(lambda: getattr(target, name))

    def set_(self: BlockingFacade, value: Any) -> None:
        target = self.__dict__["_target"]
        loop: EventLoopThread | None = self.__dict__.get("_loop")
        if loop is None:
            setattr(target, name, value)
        else:
            loop.read(lambda: setattr(target, name, value))

    writable = not isinstance(static, property) or static.fset is not None
    doc = (
        static.__doc__ if isinstance(static, property) else f"As ``{name}`` of the asyncio object."
    )
    return property(get, set_ if writable else None, doc=doc)


def _blocking_method(name: str, function: Callable[..., Any]) -> Callable[..., Any]:
    signature = inspect.signature(function)
    callbacks = _callable_parameters(signature)

    def method(self: BlockingFacade, *args: Any, **kwargs: Any) -> Any:
        inbox: queue.SimpleQueue[object] = queue.SimpleQueue()
        wrapped: list[CallerThreadCallback] = []
        if callbacks:
            bound = signature.bind(self, *args, **kwargs)
            for key in callbacks & bound.arguments.keys():
                value = bound.arguments[key]
                if callable(value):
                    wrapped.append(CallerThreadCallback(value, inbox))
                    bound.arguments[key] = wrapped[-1]
            args, kwargs = bound.args[1:], bound.kwargs
        target = self.__dict__["_target"]

        async def invoke() -> Any:
            result = getattr(target, name)(*args, **kwargs)
            if inspect.isawaitable(result):
                result = await result
            return result

        try:
            return self._adapt(self._run(invoke, inbox))
        finally:
            for callback in wrapped:
                callback.finished = True

    _describe(method, name, function, signature)
    return method


def _blocking_classmethod(wraps: type[Any], name: str, function: Callable[..., Any]) -> Any:
    """A class method (``connect``): run on a new loop thread; an instance result is adopted."""
    signature = inspect.signature(function)

    def method(cls: type[BlockingFacade], *args: Any, **kwargs: Any) -> Any:
        loop = EventLoopThread()

        async def invoke() -> Any:
            result = getattr(wraps, name)(*args, **kwargs)
            if inspect.isawaitable(result):
                result = await result
            return result

        try:
            result = loop.call(invoke)
        except BaseException:
            loop.stop()
            raise
        if isinstance(result, wraps):
            return cls._wrap_connected(result, loop)
        loop.stop()
        return result

    _describe(method, name, function, signature)
    return method


def _describe(
    method: Callable[..., Any], name: str, original: Callable[..., Any], sig: inspect.Signature
) -> None:
    """Give the generated ``method`` the original's name, signature and (annotated) docstring."""
    if not inspect.iscoroutinefunction(original):
        sig = sig.replace(return_annotation=inspect.Signature.empty)
    method.__name__ = name
    method.__signature__ = sig  # type: ignore[attr-defined]
    kind = "a blocking iterator" if inspect.isasyncgenfunction(original) else "blocking"
    method.__doc__ = f"({kind} form of the asyncio method)\n\n{inspect.getdoc(original) or ''}"
