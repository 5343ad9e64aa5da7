"""A stream judged whole before its first byte (:func:`judge_stream`): the chaining rule of
:func:`~mirobot_async._core.validation.first_restart` and every line's
:func:`~mirobot_async._core.validation.validate_line` verdict, decided in one walk of the lines."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from mirobot_async._core.line import ParsedLine
from mirobot_async._core.validation import (
    ModalState,
    _problems,
    first_restart,
    may_differ_by_profile,
)
from mirobot_async._core.values import check_firmware

__all__ = ["StreamVerdict", "judge_stream"]


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
    current = ModalState(state.cartesian, state.relative, state.motion, state.chain)
    judged: list[ModalState | None] = []
    for index, parsed in enumerate(lines, start=1):
        if firmware is None and may_differ_by_profile(parsed, current):
            each = [first_restart(lines, firmware=p, state=state) for p in ("classic", "2021")]
            return StreamVerdict(each[0], (each[0] is None) != (each[1] is None))
        before = ModalState(current.cartesian, current.relative, current.motion, current.chain)
        problems, chain = _problems(parsed, profile, current)
        if chain is not None:
            return StreamVerdict((index, parsed.source.strip() or parsed.text, chain))
        judged.append(None if problems else before)
    return StreamVerdict(None, judged_from=tuple(judged))
