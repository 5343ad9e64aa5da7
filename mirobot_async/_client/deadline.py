"""Deadlines and timeout translation for the asyncio client (one place for both).

Every awaiting call of :class:`~mirobot_async._client.client.Mirobot` turns its ``timeout=`` into an
absolute deadline on the event loop's clock (:func:`deadline_after`), bounds inner waits such
as status requests by what is left of it (:func:`clip`), and turns asyncio's ``TimeoutError``
into a :class:`~mirobot_async.errors.MirobotTimeoutError` naming what it waited for
(:class:`within`).
"""

from __future__ import annotations

import asyncio
from types import TracebackType

from mirobot_async.errors import MirobotError, MirobotTimeoutError, MirobotUsageError

__all__ = ["check_timeout", "clip", "deadline_after", "within"]


def check_timeout(timeout: float | None) -> None:
    """Raise :class:`MirobotUsageError` unless ``timeout`` is ``None`` or a number >= 0.

    Every public awaiting call checks its ``timeout`` before it writes anything.
    """
    if timeout is None:
        return
    if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not timeout >= 0:
        raise MirobotUsageError(f"timeout={timeout!r} must be a number >= 0 or None")


def deadline_after(loop: asyncio.AbstractEventLoop, timeout: float | None) -> float | None:
    """The loop time ``timeout`` seconds from now (``None``: no deadline); checks ``timeout``."""
    check_timeout(timeout)
    if timeout is None:
        return None
    return loop.time() + timeout


def clip(timeout: float, deadline: float | None, now: float) -> float:
    """An inner wait's ``timeout`` (a status request) bounded by what is left of ``deadline``."""
    if deadline is None:
        return timeout
    return max(0.0, min(timeout, deadline - now))


class within:
    """``async with within(deadline, what, timeout, command=...)``: a deadline whose expiry
    raises :class:`MirobotTimeoutError` naming ``what`` (which may be changed while waiting).

    A :class:`MirobotError` raised inside (a ``MirobotTimeoutError`` too) passes unchanged.
    """

    def __init__(
        self,
        deadline: float | None,
        what: str,
        timeout: float | None,
        *,
        command: str | None = None,
    ) -> None:
        self.what = what
        self._timeout = timeout
        self._command = command
        # No deadline: nothing to arm (asyncio.timeout_at(None) would never fire either).
        self._inner = None if deadline is None else asyncio.timeout_at(deadline)

    async def __aenter__(self) -> within:
        if self._inner is not None:
            await self._inner.__aenter__()
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._inner is None:
            return
        try:
            await self._inner.__aexit__(exc_type, exc, tb)
        except TimeoutError as err:
            if isinstance(err, MirobotError):
                raise
            raise MirobotTimeoutError(self.what, self._timeout, command=self._command) from err
