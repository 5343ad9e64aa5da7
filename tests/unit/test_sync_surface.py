"""The blocking facade (mirobot_async.sync): its surface matches the asyncio class, and the
generation rules work on any asyncio class (a toy one here, so no emulator is needed)."""

# The toy facades below are generated when their class is created, which a type checker cannot
# follow (the real facade has a generated stub, checked in test_sync_stub).
# mypy: disable-error-code="attr-defined"

from __future__ import annotations

import asyncio
import contextlib
import inspect
import threading
from collections.abc import AsyncGenerator, AsyncIterator, Callable
from typing import Any

import pytest

from mirobot_async import Mirobot as AsyncMirobot
from mirobot_async import MirobotConnectionError, MirobotUsageError
from mirobot_async.sync import BlockingFacade, BlockingIterator, Mirobot
from mirobot_async.sync._loop import LOOP_THREAD_NAME

pytestmark = pytest.mark.timeout(30)


def public_names(cls: type[Any]) -> list[str]:
    return [name for name in dir(cls) if not name.startswith("_")]


def loop_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith(LOOP_THREAD_NAME)]


# ---- the real surface ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", public_names(AsyncMirobot))
def test_every_public_member_exists_with_the_same_signature(name: str) -> None:
    original = inspect.getattr_static(AsyncMirobot, name)
    assert hasattr(Mirobot, name), f"mirobot_async.sync.Mirobot lacks {name}"
    facade = inspect.getattr_static(Mirobot, name)
    is_method = isinstance(original, classmethod | staticmethod) or callable(original)
    if isinstance(original, property) or not is_method:
        assert isinstance(facade, property), name
        if isinstance(original, property):
            assert (facade.fset is None) == (original.fset is None), name
        return
    assert isinstance(facade, classmethod) == isinstance(original, classmethod), name
    async_sig = inspect.signature(getattr(AsyncMirobot, name))
    sync_sig = inspect.signature(getattr(Mirobot, name))
    assert list(sync_sig.parameters.values()) == list(async_sig.parameters.values()), name
    if inspect.iscoroutinefunction(original):
        assert sync_sig.return_annotation == async_sig.return_annotation, name
    if name not in vars(BlockingFacade):  # the facade's own close() documents itself
        assert (inspect.getdoc(original) or "") in (getattr(Mirobot, name).__doc__ or ""), name


def test_the_surfaces_have_the_same_public_names() -> None:
    # The facade's own additions are exactly the blocking lifecycle (close is shared).
    assert set(public_names(AsyncMirobot)) <= set(public_names(Mirobot))
    assert set(public_names(Mirobot)) - set(public_names(AsyncMirobot)) == set()


def test_constructor_signature_and_instance_attributes_match() -> None:
    assert inspect.signature(Mirobot) == inspect.signature(AsyncMirobot)
    original = AsyncMirobot()
    facade = Mirobot()
    for name, value in vars(original).items():
        if name.startswith("_"):
            continue
        assert getattr(facade, name) == value, name
    facade.url = "loop://"
    assert facade.url == "loop://"
    facade.liveness_interval = 0.25
    assert facade.liveness_interval == 0.25
    assert AsyncMirobot().liveness_interval != 0.25  # set on the instance, not the class
    with pytest.raises(AttributeError):
        facade.no_such_attribute  # noqa: B018


def test_unconnected_calls_raise_what_asyncio_raises_and_start_no_thread() -> None:
    facade = Mirobot()
    with pytest.raises(MirobotConnectionError, match="not connected"):
        facade.status()
    with pytest.raises(MirobotUsageError):
        facade.status(timeout=-1)
    facade.close()
    assert not loop_threads()


def test_bad_arguments_raise_type_error_as_asyncio_would() -> None:
    with pytest.raises(TypeError):
        Mirobot().move_joints(no_such_joint=1)  # type: ignore[call-arg]


# ---- the generation rules, on a toy asyncio class -----------------------------------------------


class Toy:
    """A small asyncio class standing in for the client."""

    limit: float = 1.0
    made: list[Toy] = []  # noqa: RUF012 - every instance, so tests can look at the real object

    def __init__(self, *, name: str = "toy") -> None:
        Toy.made.append(self)
        self.name = name
        self.closed_count = 0
        self.cancelled: list[str] = []
        self._value = 0

    @classmethod
    def connect(cls, name: str) -> _ToyConnector:
        return _ToyConnector(cls(name=name))

    @property
    def value(self) -> int:
        return self._value

    async def add(self, amount: int, *, fail: bool = False) -> int:
        await asyncio.sleep(0)  # a coroutine that suspends, as the client's do
        if fail:
            raise MirobotUsageError(f"amount={amount} refused")
        self._value += amount
        return self._value

    async def wait_forever(self) -> None:
        try:
            await asyncio.Event().wait()
        except asyncio.CancelledError:
            self.cancelled.append("wait_forever")
            raise

    async def counting(self, stop: int) -> AsyncGenerator[int, None]:
        try:
            for number in range(stop):
                await asyncio.sleep(0)  # a generator that suspends, as the client's do
                yield number
        finally:
            self.cancelled.append("counting closed")

    def each(self, items: list[int], *, on_item: Callable[[int], object] | None = None) -> Any:
        return self._each(items, on_item)

    async def _each(self, items: list[int], on_item: Callable[[int], object] | None) -> int:
        for item in items:
            if on_item is not None:
                maybe = on_item(item)
                if inspect.isawaitable(maybe):
                    await maybe
        return len(items)

    @contextlib.asynccontextmanager
    async def scoped(self) -> AsyncIterator[Toy]:
        self._value += 100
        try:
            yield self
        finally:
            self._value -= 100

    def loop_thread_name(self) -> str:
        return threading.current_thread().name

    async def close(self) -> None:
        self.closed_count += 1


class _ToyConnector:
    def __init__(self, toy: Toy) -> None:
        self.toy = toy

    def __await__(self) -> Any:
        async def opened() -> Toy:
            return self.toy

        return opened().__await__()


class SyncToy(BlockingFacade, wraps=Toy):
    """The facade generated from Toy."""


@pytest.fixture
def toy() -> Any:
    facade = SyncToy.connect("t")
    yield facade
    facade.close()
    assert not loop_threads(), "the loop thread outlived close()"


def test_generated_members_cover_every_kind(toy: Any) -> None:
    assert toy.name == "t"
    assert toy.add(2) == 2
    assert toy.value == 2
    assert toy.limit == 1.0
    with pytest.raises(MirobotUsageError, match="amount=3 refused"):
        toy.add(3, fail=True)
    assert toy.loop_thread_name() == LOOP_THREAD_NAME  # plain methods run on the loop too
    numbers = toy.counting(3)
    assert isinstance(numbers, BlockingIterator)
    assert list(numbers) == [0, 1, 2]
    with toy.scoped() as inside:
        assert inside is toy  # the asyncio object is handed back as its facade
        assert toy.value == 102
    assert toy.value == 2
    assert list(inspect.signature(SyncToy.add).parameters) == ["self", "amount", "fail"]


def test_a_member_added_to_the_asyncio_class_appears_in_a_new_facade() -> None:
    class Grown(Toy):
        async def double(self, x: int) -> int:
            return 2 * x

    class SyncGrown(BlockingFacade, wraps=Grown):
        pass

    grown: Any = SyncGrown.connect("g")
    try:
        assert grown.double(21) == 42
    finally:
        grown.close()


def test_callbacks_run_in_the_calling_thread_and_their_errors_end_the_call(toy: Any) -> None:
    seen: list[tuple[int, str]] = []
    assert toy.each([1, 2, 3], on_item=lambda i: seen.append((i, threading.current_thread().name)))
    assert seen == [(i, threading.current_thread().name) for i in (1, 2, 3)]

    def refuse(item: int) -> None:
        if item == 2:
            raise RuntimeError("stop at 2")

    with pytest.raises(RuntimeError, match="stop at 2"):
        toy.each([1, 2, 3], on_item=refuse)
    # A callback may call the facade again (it runs in this thread while the loop is free).
    assert toy.each([1, 2], on_item=lambda i: toy.add(i)) == 2
    assert toy.value == 3


def test_generated_names_and_completion(toy: Any) -> None:
    assert SyncToy.add.__qualname__ == "SyncToy.add"
    assert Mirobot.move_joints.__qualname__ == "Mirobot.move_joints"
    assert {"name", "add", "value", "close"} <= set(dir(toy))


def test_an_interrupt_in_the_calling_thread_cancels_the_call_on_the_loop(toy: Any) -> None:
    def interrupt(item: int) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        toy.each([1], on_item=interrupt)
    # A call blocked on the loop is cancelled when its caller stops waiting.
    result: list[BaseException] = []

    def blocked() -> None:
        try:
            toy.wait_forever()
        except BaseException as err:
            result.append(err)

    worker = threading.Thread(target=blocked)
    worker.start()
    toy.close()  # from another thread: the waiting call is released
    worker.join(5)
    assert not worker.is_alive()
    assert toy.cancelled == ["wait_forever"]
    assert result and type(result[0]).__name__ == "MirobotLinkLostError"


def test_an_iterator_left_early_is_closed_on_the_loop(toy: Any) -> None:
    with toy.counting(10) as numbers:
        assert next(numbers) == 0
    assert "counting closed" in toy.cancelled
    assert next(numbers, None) is None


def test_calls_from_inside_a_running_event_loop(toy: Any) -> None:
    async def notebook_cell() -> int:
        total: int = toy.add(5)  # blocking, as in a Jupyter cell
        await asyncio.sleep(0)  # the caller's own loop still works afterwards
        return total

    assert asyncio.run(notebook_cell()) == 5


def test_close_is_idempotent_and_calls_after_close_run_detached() -> None:
    facade: Any = SyncToy.connect("c")
    assert len(loop_threads()) == 1
    facade.close()
    facade.close()
    assert not loop_threads()
    assert facade.closed_count == 1
    assert facade.add(1) == 1  # the toy has no "closed" state: the call still runs, detached
    assert not loop_threads()


def test_a_forgotten_facade_is_closed_when_collected() -> None:
    import gc

    facade: Any = SyncToy.connect("f")
    target_closed = Toy.made[-1]
    assert target_closed.name == "f"
    del facade
    gc.collect()
    assert not loop_threads()
    assert target_closed.closed_count == 1
