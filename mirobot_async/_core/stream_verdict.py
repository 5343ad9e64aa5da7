"""A stream judged whole before its first byte (:func:`judge_stream`): the chaining rule of
:func:`first_restart` and every line's
:func:`~mirobot_async._core.validation.validate_line` verdict, decided in one walk of the lines."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from mirobot_async._core.line import ParsedLine, parse_line
from mirobot_async._core.validation import (
    ModalState,
    _follow,
    _problems,
    may_differ_by_profile,
)
from mirobot_async._core.values import check_firmware

__all__ = ["StreamVerdict", "first_restart", "judge_stream"]


@dataclass(frozen=True, slots=True)
class StreamVerdict:
    """A program (its lines parsed) judged whole before its first byte is streamed."""

    restart: tuple[int, str, str] | None
    """The first line (number, text, why and the fix) that would restart from where the moving
    arm is (:func:`first_restart`), or ``None``."""
    profiles_disagree: bool = False
    """The profile is not known and only one of them finds such a line: learn it first."""
    judged_from: tuple[ModalState | None, ...] = ()
    """Per line, the modal state from which it was found free of problems (written from an
    equal state it need not be judged again: a verdict is a function of the line, the profile
    and that state); ``None``, or a missing entry: judge it when it is written."""


def judge_stream(
    lines: Sequence[ParsedLine], *, firmware: str | None, state: ModalState
) -> StreamVerdict:
    """:func:`first_restart` for a stream about to start (on both profiles when ``firmware``
    is ``None``), with each line's :func:`validate_line` verdict decided on the way. One walk
    of the lines, unless the profile is unknown and a line may be judged otherwise on the
    other one (:func:`may_differ_by_profile`): then one :func:`first_restart` per profile and
    nothing decided ahead. ``state`` is not changed."""
    profile = check_firmware(firmware) if firmware is not None else "classic"
    current = state.copy()
    judged: list[ModalState | None] = []
    for index, parsed in enumerate(lines, start=1):
        if firmware is None and may_differ_by_profile(parsed, current):
            each = [first_restart(lines, firmware=p, state=state) for p in ("classic", "2021")]
            return StreamVerdict(each[0], (each[0] is None) != (each[1] is None))
        before = current.copy()
        problems, chain = _problems(parsed, profile, current)
        if chain is not None:
            return StreamVerdict((index, parsed.source.strip() or parsed.text, chain))
        judged.append(None if problems else before)
    return StreamVerdict(None, judged_from=tuple(judged))


def first_restart(
    lines: Iterable[str | bytes | ParsedLine], *, firmware: str | None, state: ModalState
) -> tuple[int, str, str] | None:
    """The first of ``lines`` (1-based number, text, why and the fix) that, streamed from
    ``state``, would end elsewhere than sent one at a time after the arm stopped (its
    ``M20``/``M21`` restarts from where the moving arm is:
    :class:`~mirobot_async._core.modal.Chaining`), or ``None``. Other problems are not judged here.
    ``firmware=None``: a line counts only if it does on both profiles. ``state`` is not changed.
    Lines already parsed (:class:`ParsedLine`) are not parsed again; each other line is parsed
    once for both profiles."""
    profiles = (check_firmware(firmware),) if firmware is not None else ("classic", "2021")
    items = iter(lines)
    parsed_lines: list[ParsedLine] = []  # parsed so far (the next profile reads them again)

    def parsed_at(index: int) -> ParsedLine | None:
        while len(parsed_lines) <= index:
            line = next(items, None)
            if line is None:
                return None
            parsed_lines.append(line if isinstance(line, ParsedLine) else parse_line(line))
        return parsed_lines[index]

    found: tuple[int, str, str] | None = None
    for profile in profiles:
        current = state.copy()
        first = None
        index = 0
        while (parsed := parsed_at(index)) is not None:
            index += 1
            chain = _follow(parsed, profile, current)
            if chain is not None:
                first = (index, parsed.source.strip() or parsed.text, chain)
                break
        if first is None:
            return None  # a line counts only if it does on every profile
        found = first if found is None else found
    return found
