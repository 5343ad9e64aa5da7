"""A wire spy for tests: every byte the client writes and receives, seen at the transport.

::

    spy = WireSpy()
    async with Mirobot.connect(url, open_transport=spy.opener) as arm:
        await arm.send("M3 S0")
    assert spy.lines() == [b"M3 S0\\n"]

:class:`WireSpy` wraps a :class:`~mirobot_async._client.wire.TransportOpener` (the serial port by
default): the client's public seam for its transport, so tests never touch private attributes.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mirobot_async._client.wire import DataCallback, LostCallback, Transport, TransportOpener

__all__ = ["WireSpy"]

_REALTIME = frozenset({b"?", b"!", b"~", b"%"})
_DESCRIBED = ("link_kind", "baudrate", "time_scale", "firmware_profile", "clock")


class _SpiedTransport:
    def __init__(self, inner: Transport, spy: WireSpy) -> None:
        self._inner = inner
        self._spy = spy
        # what the link says of itself, if it says it: the ? spacing, and a recorded tape's
        # header and clock (connect(record=...))
        for name in ("status_min_gap", *_DESCRIBED):
            value = getattr(inner, name, None)
            if value is not None:
                setattr(self, name, value)

    def write(self, data: bytes) -> None:
        chunk = bytes(data)
        self._spy.writes.append(chunk)
        for hook in tuple(self._spy.write_hooks):
            hook(chunk)
        self._inner.write(data)

    def abort(self) -> None:
        self._inner.abort()

    async def close(self) -> None:
        await self._inner.close()


class WireSpy:
    """Records the chunks written (:attr:`writes`) and received (:attr:`received`).

    ``write_hooks`` are called with each chunk just before it is written; ``receive_hooks``
    with each received chunk just after the client has handled it (its events dispatched).
    ``inner`` is the opener to wrap (default: the serial port with the default options).
    """

    def __init__(self, inner: TransportOpener | None = None) -> None:
        self._inner = inner
        self.writes: list[bytes] = []
        self.received: list[bytes] = []
        self.write_hooks: list[Callable[[bytes], None]] = []
        self.receive_hooks: list[Callable[[bytes], None]] = []

    async def opener(
        self, url: str, *, on_data: DataCallback, on_lost: LostCallback, timeout: float
    ) -> Transport:
        """The :class:`~mirobot_async._client.wire.TransportOpener` to pass as
        ``open_transport``."""
        inner = self._inner
        if inner is None:
            from mirobot_async._client.wire import serial_opener

            inner = serial_opener()

        def received(data: bytes) -> None:
            self.received.append(bytes(data))
            on_data(data)
            for hook in tuple(self.receive_hooks):
                hook(data)

        transport = await inner(url, on_data=received, on_lost=on_lost, timeout=timeout)
        return _SpiedTransport(transport, self)

    def mark(self) -> int:
        """A position in :attr:`writes`, for :meth:`since` and :meth:`lines`."""
        return len(self.writes)

    def since(self, mark: int = 0) -> list[bytes]:
        """Every chunk written since ``mark``."""
        return self.writes[mark:]

    def lines(self, mark: int = 0) -> list[bytes]:
        """The lines written since ``mark`` (realtime bytes such as ``?`` left out)."""
        return [w for w in self.writes[mark:] if w not in _REALTIME]
