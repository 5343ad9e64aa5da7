"""A blocking facade of :class:`mirobot_async.Mirobot` for plain scripts, notebooks and threads.

::

    from mirobot_async.sync import Mirobot

    with Mirobot.connect("/dev/ttyUSB0") as arm:
        arm.home()
        arm.move_joints(j1=30, speed=1500)
        print(arm.status())
        for report in arm.statuses(0.2):       # a blocking iterator
            if report.state.value == "Idle":
                break
        result = arm.stream(open("square.gcode"), on_progress=print)

Every public name of the asyncio class exists here with the same arguments, return values and
errors: a coroutine method becomes a blocking call, an async generator a blocking iterator, an
awaitable result (``connect()``, ``stream()``) is awaited, an async context manager becomes a
plain one, properties and attributes read and write through. Nothing is listed by hand: the
members are generated from the asyncio class when this module is imported, so they cannot drift.

How: :meth:`Mirobot.connect` starts one event loop in a daemon thread (``mirobot-sync-loop``) and
opens the asyncio client on it; every call is submitted to that loop and the calling thread
blocks until it ends. So it works in a script, in Jupyter (whose own loop keeps running in the
calling thread, and is merely blocked for the duration of a call) and from several threads at once
(calls run concurrently on the loop, exactly as concurrent tasks would). Callbacks you pass
(``stream(on_progress=...)``) run in **your** thread, while your call waits; an exception they
raise ends the call as it would in asyncio. Timeouts are those of the asyncio methods; a
``KeyboardInterrupt`` (or any exception) in the waiting thread cancels the call on the loop, with
the cancellation behaviour the asyncio method documents (e.g. a cancelled stream stops sending).
:meth:`Mirobot.close` (or the end of a ``with`` block) closes the link, stops the loop and joins
its thread; a forgotten arm is closed when it is garbage collected or the interpreter exits.
Calls after ``close()`` raise what the asyncio client raises after ``close()``.

An iterable given to ``stream()`` is consumed on the loop thread: a plain list or file is fine;
a generator that blocks (waits for input) would hold the loop, so feed those lines from a list.
A callback may call the arm again (``on_progress`` may ask ``arm.status()``); a blocking call
made on the loop thread itself is refused with :class:`MirobotUsageError`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from mirobot_async import Mirobot as AsyncMirobot
from mirobot_async.sync._facade import BlockingContextManager, BlockingFacade, BlockingIterator
from mirobot_async.sync._loop import EventLoopThread

__all__ = [
    "BlockingContextManager",
    "BlockingFacade",
    "BlockingIterator",
    "EventLoopThread",
    "Mirobot",
]


class Mirobot(BlockingFacade, wraps=AsyncMirobot):
    """A blocking :class:`mirobot_async.Mirobot`: ``with Mirobot.connect(url) as arm: ...``.

    Every public method, property and attribute of the asyncio class, generated from it (see the
    module docstring). ``connect()`` returns the connected arm (close it, or use ``with``).
    """

    if TYPE_CHECKING:

        @classmethod
        def connect(cls, url: str, **options: Any) -> Mirobot:
            """Open ``url`` (see :meth:`mirobot_async.Mirobot.connect`) and return the arm."""

        def __enter__(self) -> Mirobot: ...
