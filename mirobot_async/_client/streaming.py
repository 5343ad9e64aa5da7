"""Streaming: :class:`Stream` (what :meth:`Mirobot.stream
<mirobot_async._client.client.Mirobot.stream>` returns), its :class:`LineResult` per line and
:class:`StreamResult`.

A producer task writes lines as the line scheduler allows (character counting); the consumer
(the ``Stream``'s iterator) awaits their replies in order. A failing reply stops the producer
synchronously, as it is dispatched (:meth:`_StreamRun.watch`), so nothing is written after it.
"""

from __future__ import annotations

import asyncio
import contextlib
import inspect
from collections import deque
from collections.abc import (
    AsyncGenerator,
    AsyncIterable,
    AsyncIterator,
    Callable,
    Generator,
    Iterable,
)
from dataclasses import dataclass, field
from typing import Any, Final

from mirobot_async._client.condition import RobotCondition
from mirobot_async._client.deadline import deadline_after
from mirobot_async._client.guard import EnvelopeGuard, NullGuard
from mirobot_async._client.scheduler import LineScheduler, SendRules, Slot, StreamStopped
from mirobot_async._core.line import ParsedLine, parse_line
from mirobot_async._core.outgoing import OutgoingLine
from mirobot_async._core.protocol import LineRejected, encode_line
from mirobot_async._core.stream_verdict import judge_stream
from mirobot_async._core.validation import InvalidLineError, ModalState
from mirobot_async.errors import (
    MirobotAlarmError,
    MirobotError,
    MirobotLinkLostError,
    MirobotResetError,
    MirobotTimeoutError,
    MirobotUsageError,
    MotionChainError,
)

__all__ = ["LineResult", "Stream", "StreamResult"]

_END: Final = object()
_FATAL = (MirobotResetError, MirobotAlarmError, MirobotTimeoutError)

MOTION_BARRIER: Final = b"G4 P0\n"
_BARRIER_RULES: Final = SendRules(warn_unchecked=False)
"""Written after a ``wait=True`` stream's last line: the firmware answers a dwell only once its
planner is empty (GRBL's G4; oracle: the ``ok`` comes as the arm stops), so its ``ok`` is the end
of the motion for 4 bytes of output, where a status report costs about 190."""


@dataclass(frozen=True, slots=True)
class LineResult:
    """The outcome of one streamed line: ``number`` is its 1-based position in the input."""

    number: int
    line: str
    output: tuple[str, ...] = ()
    error: MirobotError | None = None

    @property
    def ok(self) -> bool:
        """True when the line was acknowledged and not refused."""
        return self.error is None


@dataclass(slots=True)
class StreamResult:
    """The outcome of :meth:`Mirobot.stream`.

    ``sent`` lines were written, ``acknowledged`` of them were answered ``ok`` (and not refused);
    ``errors`` lists the failed lines in order; ``stopped`` is True when the stream ended before
    its input did (first error without ``continue_on_error``, a reset, an alarm, a timeout).
    """

    sent: int = 0
    acknowledged: int = 0
    errors: list[LineResult] = field(default_factory=list)
    stopped: bool = False

    @property
    def ok(self) -> bool:
        """True when every input line was acknowledged without error."""
        return not self.errors and not self.stopped

    def raise_for_errors(self) -> None:
        """Raise the first line's error, if any."""
        for result in self.errors:
            if result.error is not None:
                raise result.error


def _text(item: object) -> str:
    if isinstance(item, bytes | bytearray):
        return bytes(item).decode("ascii", "replace").rstrip("\r\n")
    return str(item).rstrip("\r\n")


@dataclass(frozen=True, slots=True)
class _Judged:
    """A list of lines parsed, and judged (:func:`judge_stream`), before the stream began."""

    lines: list[ParsedLine]
    judged_from: tuple[ModalState | None, ...]


_LEARN_FIRMWARE: Final = LineResult(0, "", ())
"""A stream judged before its first byte whose verdict depends on the firmware profile."""


@dataclass(slots=True)
class _Queued:
    """A line taken from the input: its slot once written, or the error that kept it back."""

    number: int
    command: str
    sent: Slot | MirobotError


@dataclass(slots=True, eq=False)
class _StreamRun:
    """The state of one running stream, shared by its producer and its consumer."""

    scheduler: LineScheduler
    condition: RobotCondition
    continue_on_error: bool
    deadline: float | None
    timeout: float | None
    rules: SendRules  # how its lines are sent (envelope, validation; warned once, not per line)
    result: StreamResult
    queue: deque[_Queued] = field(default_factory=deque)
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    stop: bool = False  # write nothing more
    done: bool = False  # the producer ended
    exhausted: bool = False  # the input ended
    reset_epoch: int = 0  # the robot's resets when the stream started: it stops at the next
    alarm_epoch: int = 0  # the robot's alarms when the stream started
    wait: bool = False  # end with the motion barrier (MOTION_BARRIER)
    judged: _Judged | None = None  # the input's lines parsed and judged before the stream began
    barrier: Slot | MirobotError | None = None  # its slot once written, or what kept it back

    def should_stop(self) -> bool:
        if self.condition.reset_epoch != self.reset_epoch:
            self.stop = True  # a reset: the program's modal state is gone, even if no line failed
        return self.stop

    def watch(self, slot: Slot) -> None:
        """Runs as a reply is dispatched, before the producer can wake: a failing line stops
        the stream at once, so nothing is written after its reply arrived."""
        outcome = slot.fut.result()
        if isinstance(outcome, BaseException):
            self.stop = True  # reset, alarm, lost reply, lost link: always fatal
        elif isinstance(outcome, LineRejected):
            if not self.continue_on_error or "alarm lock" in outcome.text.lower():
                self.stop = True
        elif outcome.refusal is not None and not self.continue_on_error:
            self.stop = True

    def _push(self, number: int, command: str, sent: Slot | MirobotError) -> None:
        self.queue.append(_Queued(number, command, sent))
        self.wake.set()

    async def produce(self, lines: Iterable[Any] | AsyncIterable[Any]) -> None:
        """Write the input's lines as the scheduler allows, until stopped or exhausted."""
        number = 0
        sync_items = iter(lines) if not isinstance(lines, AsyncIterable) else None
        async_items = aiter(lines) if isinstance(lines, AsyncIterable) else None
        rx_buffer_size = self.scheduler.rx_buffer_size
        try:
            while not self.should_stop():
                if async_items is not None:
                    item = await anext(async_items, _END)
                else:
                    assert sync_items is not None
                    item = next(sync_items, _END)
                if item is _END:
                    self.exhausted = True
                    break
                number += 1
                try:
                    data = encode_line(item, rx_buffer_size)
                except MirobotUsageError as err:
                    self._push(number, _text(item), err)
                    if self.continue_on_error:
                        continue
                    break
                if not data:
                    continue  # a blank line
                command = data.decode("ascii")
                parsed, judged_from = self._judged(number, command)
                line = OutgoingLine.of(data, f"stream line {number} {command!r}", parsed=parsed)
                try:
                    slot = await self.scheduler.submit(
                        line,
                        deadline=self.deadline,
                        timeout=self.timeout,
                        rules=self.rules,
                        should_stop=self.should_stop,
                        watch=self.watch,
                        judged_from=judged_from,
                    )
                except StreamStopped:
                    break
                except _FATAL as err:
                    self._push(number, command, err)
                    break
                except InvalidLineError as err:  # not written, as a bad line
                    self._push(number, command, err)
                    if self.continue_on_error:
                        continue
                    break
                except MirobotUsageError as err:  # the safety envelope: stop before it
                    self._push(number, command, err)
                    self.stop = True
                    break
                self.result.sent += 1
                self._push(number, command, slot)
            if self.wait and self.exhausted and not self.should_stop():
                await self._write_barrier()
        finally:
            self.done = True
            self.wake.set()

    def _judged(self, number: int, command: str) -> tuple[ParsedLine | None, ModalState | None]:
        """Input line ``number`` as parsed before the stream began, when it is ``command``
        (parsing is a function of the text: the scheduler need not parse it again), and the
        modal state it was found free of problems from (:attr:`StreamVerdict.judged_from`)."""
        judged = self.judged
        if judged is None or number > len(judged.lines):
            return None, None
        line = judged.lines[number - 1]
        if line.source != command:
            return None, None
        return line, judged.judged_from[number - 1] if number <= len(judged.judged_from) else None

    async def _write_barrier(self) -> None:
        """Write :data:`MOTION_BARRIER` right after the last line (no round trip in between)."""
        command = MOTION_BARRIER.decode("ascii").strip()
        try:
            self.barrier = await self.scheduler.submit(
                OutgoingLine.of(MOTION_BARRIER, f"{command!r} (the end of the stream's motion)"),
                deadline=self.deadline,
                timeout=self.timeout,
                rules=_BARRIER_RULES,
                should_stop=self.should_stop,
            )
        except StreamStopped:
            pass
        except MirobotError as err:
            self.barrier = err

    async def await_barrier(self) -> None:
        """Wait for the barrier's ``ok``: the robot's planner is empty (the motion ended)."""
        barrier = self.barrier
        if isinstance(barrier, MirobotError):
            raise barrier
        if barrier is None or self.stop:
            return
        await self.scheduler.await_slot(barrier, self.deadline, self.timeout)
        # A reset answers a pending dwell (GRBL ends it): an ok after a reset is no end of motion.
        condition = self.condition
        if barrier.reply_epoch != self.reset_epoch or condition.reset_epoch != self.reset_epoch:
            raise MirobotResetError(None, "before the stream's motion finished")
        if condition.alarm_epoch != self.alarm_epoch:
            raise MirobotAlarmError(barrier.command, condition.alarm or "the robot is in Alarm")

    async def _next(self) -> _Queued | None:
        while not self.queue:
            if self.done:
                return None
            self.wake.clear()
            if not self.queue and not self.done:
                await self.wake.wait()
        return self.queue.popleft()

    async def consume(self, producer: asyncio.Task[None]) -> AsyncGenerator[LineResult, None]:
        """Await the replies in order and yield each line's result."""
        try:
            while (queued := await self._next()) is not None:
                sent = queued.sent
                if isinstance(sent, MirobotError):
                    line_result = LineResult(queued.number, queued.command, (), sent)
                else:
                    try:
                        output = await self.scheduler.await_slot(sent, self.deadline, self.timeout)
                    except MirobotLinkLostError:
                        raise
                    except MirobotError as err:
                        line_result = LineResult(
                            queued.number, queued.command, getattr(err, "output", ()), err
                        )
                    else:
                        line_result = LineResult(queued.number, queued.command, output)
                if line_result.error is None:
                    self.result.acknowledged += 1
                else:
                    self.result.errors.append(line_result)
                    if isinstance(line_result.error, _FATAL) or not self.continue_on_error:
                        self.stop = True
                yield line_result
            if producer.done() and not producer.cancelled():
                error = producer.exception()
                if error is not None:
                    raise error  # a lost link while sending, or a failing input iterator
            self.result.stopped = self.stop and not self.exhausted
            if self.wait and not self.result.stopped:
                await self.await_barrier()
        finally:
            self.stop = True
            if not producer.done():
                producer.cancel()
            await asyncio.wait((producer,))
            if not producer.cancelled():
                producer.exception()  # retrieved (raised above if it mattered)
            # Lines written but not awaited (the consumer left early): abandon their slots, so
            # their replies are consumed and discarded.
            for leftover in self.queue:
                if isinstance(leftover.sent, Slot) and not leftover.sent.fut.done():
                    leftover.sent.fut.cancel()
            if isinstance(self.barrier, Slot) and not self.barrier.fut.done():
                self.barrier.fut.cancel()


class Stream:
    """A pipelined stream of lines, returned by :meth:`Mirobot.stream`. Use it once, either way:

    * ``result = await arm.stream(lines)`` -> :class:`StreamResult` (``on_progress`` is called
      with each :class:`LineResult` in order); a ``Stream`` is awaitable but not a coroutine:
      to run it in a task use :meth:`run`, ``asyncio.create_task(arm.stream(lines).run())``;
    * ``async for result in arm.stream(lines): ...`` -> each :class:`LineResult` in order as it
      is acknowledged (close the iteration early with ``contextlib.aclosing`` to stop sending at
      once).

    An input item that is not ``str``, ``bytes`` or ``bytearray`` (or not one ASCII line without
    realtime bytes) is a bad line: its :class:`LineResult` carries a :class:`MirobotUsageError`
    and nothing of it is written.
    """

    def __init__(
        self,
        parts: tuple[LineScheduler, RobotCondition, EnvelopeGuard | NullGuard],
        lines: Iterable[str | bytes] | AsyncIterable[str | bytes],
        on_progress: Callable[[LineResult], object] | None,
        continue_on_error: bool,
        timeout: float | None,
        check_envelope: bool = True,
        validate: bool = True,
        wait: bool = False,
    ) -> None:
        self._parts = parts
        self._wait = wait
        self._validate = validate
        self._lines = lines
        self._on_progress = on_progress
        self._continue = continue_on_error
        self._timeout = timeout
        self._check_envelope = check_envelope
        self._used = False
        self.result = StreamResult()
        """Filled in as the stream runs (also in the iterator form)."""

    def _take(self) -> AsyncGenerator[LineResult, None]:
        if self._used:
            raise MirobotUsageError("a Stream can be awaited or iterated only once")
        self._used = True
        return self._results()

    async def _results(self) -> AsyncGenerator[LineResult, None]:
        scheduler, condition, guard = self._parts
        loop = asyncio.get_running_loop()
        deadline = deadline_after(loop, self._timeout)
        condition.check_sendable(None, motion=False)
        if not self._check_envelope:
            guard.warn_stream_unchecked()
        refused, judged = self._restart_refusal()
        if refused is _LEARN_FIRMWARE:  # the verdict depends on the firmware: learn it first
            await scheduler.require_firmware(deadline, self._timeout)
            refused, judged = self._restart_refusal()
        if refused is not None:  # nothing is written
            if scheduler.observers and refused.error is not None:
                scheduler.observers.not_sent(refused.line, refused.error)
            self.result.errors.append(refused)
            self.result.stopped = True
            yield refused
            return
        run = _StreamRun(
            scheduler,
            condition,
            self._continue,
            deadline,
            self._timeout,
            SendRules(
                check_envelope=self._check_envelope, validate=self._validate, warn_unchecked=False
            ),
            self.result,
            reset_epoch=condition.reset_epoch,
            alarm_epoch=condition.alarm_epoch,
            wait=self._wait,
            judged=judged,
        )
        producer = loop.create_task(run.produce(self._lines), name="mirobot-stream-producer")
        results = run.consume(producer)
        async with contextlib.aclosing(results):
            async for line_result in results:
                yield line_result

    def _restart_refusal(self) -> tuple[LineResult | None, _Judged | None]:
        """A list or tuple of lines is judged whole before its first byte: a line that would
        restart from where the moving arm is (its ``M20``/``M21``) refuses the stream. Also
        the lines as parsed, and each line's verdict decided on the way (the stream writes
        them without parsing or judging them again)."""
        lines = self._lines
        if not self._validate or not isinstance(lines, list | tuple):
            return None, None
        texts = [_text(item) for item in lines if isinstance(item, str | bytes | bytearray)]
        if len(texts) != len(lines):
            return None, None  # a bad item: reported in order as the stream reaches it
        parsed = [parse_line(text) for text in texts]
        _scheduler, condition, guard = self._parts
        verdict = judge_stream(parsed, firmware=condition.firmware, state=guard.modal_state())
        if verdict.profiles_disagree:  # judged per profile: only one refuses; learn which
            return _LEARN_FIRMWARE, None
        if verdict.restart is None:
            return None, _Judged(parsed, verdict.judged_from)
        number, line, why = verdict.restart
        error = MotionChainError(line, f"{why}; nothing of the stream was sent")
        return LineResult(number, line, (), error), None

    def __aiter__(self) -> AsyncIterator[LineResult]:
        return self._take()

    def __await__(self) -> Generator[Any, None, StreamResult]:
        return self.run().__await__()

    async def run(self) -> StreamResult:
        """Run the stream to its end and return its :class:`StreamResult` (as ``await``).

        A coroutine, so it can be given to ``asyncio.create_task()`` or ``asyncio.gather()``.
        """
        results = self._take()
        async with contextlib.aclosing(results):
            async for line_result in results:
                if self._on_progress is not None:
                    maybe = self._on_progress(line_result)
                    if inspect.isawaitable(maybe):
                        await maybe
        return self.result
