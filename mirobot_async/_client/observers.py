"""Who watches one connection's lines (the 3D view that follows a script: ``Mirobot.view()``).

An observer hears each fact once, from its owner, as it happens: a line written (its one parse
with it), its reply (``ok`` with its output and refusal, or an error), a line refused before any
byte of it was written (the validation, the envelope, a stream judged whole), an alarm and a
reset. Observers only watch: they are called synchronously on the connection's loop, must not
block, and an observer that raises is logged and dropped (it never disturbs the link).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Protocol

from mirobot_async._core.modal import MotionModes
from mirobot_async._core.outgoing import OutgoingLine
from mirobot_async._core.protocol import LineAcknowledged, LineRejected
from mirobot_async.errors import MirobotError

__all__ = ["LineObserver", "LineObservers", "Offset"]

_log = logging.getLogger("mirobot_async.client")

Offset = tuple[float, float, float]


class LineObserver(Protocol):
    """What a watcher of the lines implements (every method is called on the loop)."""

    def line_written(
        self, line: OutgoingLine, modes: MotionModes, base_offset: Offset | None
    ) -> None: ...

    def line_answered(self, line: OutgoingLine, reply: LineAcknowledged | LineRejected) -> None: ...

    def line_not_sent(self, command: str, error: MirobotError) -> None: ...

    def alarm(self, text: str) -> None: ...

    def reset(self) -> None: ...


class LineObservers:
    """The observers of one connection, told each fact in turn."""

    def __init__(self) -> None:
        self._observers: list[LineObserver] = []

    def add(self, observer: LineObserver) -> None:
        self._observers.append(observer)

    def remove(self, observer: LineObserver) -> None:
        if observer in self._observers:
            self._observers.remove(observer)

    def __bool__(self) -> bool:
        return bool(self._observers)

    def written(self, line: OutgoingLine, modes: MotionModes, base_offset: Offset | None) -> None:
        """``line`` was written; ``modes`` and ``base_offset`` (``$41..$43``, ``None``: unknown)
        are what the client knows of the arm before it (the modes it parses the line with)."""
        for observer in self._observers[:]:
            self._tell(observer, observer.line_written, line, modes, base_offset)

    def answered(self, line: OutgoingLine, reply: LineAcknowledged | LineRejected) -> None:
        for observer in self._observers[:]:
            self._tell(observer, observer.line_answered, line, reply)

    def not_sent(self, command: str, error: MirobotError) -> None:
        for observer in self._observers[:]:
            self._tell(observer, observer.line_not_sent, command, error)

    def alarm(self, text: str) -> None:
        for observer in self._observers[:]:
            self._tell(observer, observer.alarm, text)

    def reset(self) -> None:
        for observer in self._observers[:]:
            self._tell(observer, observer.reset)

    def _tell(self, observer: LineObserver, method: Callable[..., object], *args: object) -> None:
        try:
            method(*args)
        except Exception:
            _log.exception("a line observer failed; it is removed")
            self.remove(observer)
