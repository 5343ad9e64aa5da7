"""Program files and trace files of the command line: reading G-code (a file or ``-`` for
standard input) into numbered commands, and opening a trace CSV with a usage error on failure."""

from __future__ import annotations

import contextlib
import sys
from dataclasses import dataclass
from typing import Final

from mirobot_async._cli.exits import CliError, note
from mirobot_async._cli.plotting import TraceError, TraceWriter
from mirobot_async._core.modal import MotionModes
from mirobot_async._core.validation import check_program

__all__ = [
    "STDIN",
    "ProgramLine",
    "decode_program",
    "open_trace",
    "program_name",
    "program_of",
    "program_problems",
    "read_lines",
    "read_program",
    "split_lines",
]

STDIN: Final = "-"
"""The file name that means standard input (``mirobot run -``)."""


@dataclass(frozen=True, slots=True)
class ProgramLine:
    """A command of a program file: its 1-based line number and the text to send."""

    number: int
    text: str


def strip_comments(line: str) -> str:
    """The line without ``( ... )`` and ``; ...`` comments and surrounding space."""
    out: list[str] = []
    in_parentheses = False
    for char in line:
        if in_parentheses:
            in_parentheses = char != ")"
            continue
        if char == ";":
            break
        if char == "(":
            in_parentheses = True
            continue
        out.append(char)
    return " ".join("".join(out).split())


def program_name(path: str) -> str:
    """How messages name the program: the path, or ``<stdin>`` for ``-``."""
    return "<stdin>" if path == STDIN else path


def split_lines(text: str) -> list[str]:
    """``text`` cut at ``\n``, ``\r\n`` and ``\r`` only (not at the other breaks
    :meth:`str.splitlines` knows: U+0085, U+000B, U+000C, U+001C..U+001E, U+2028...); a final line
    end ends the last line."""
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    if lines[-1] == "":
        lines.pop()
    return lines


def decode_program(data: bytes, name: str) -> str:
    """The text of a program file read as UTF-8 (a byte order mark is skipped); raises
    :class:`CliError` naming the line and the first byte that is not UTF-8."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        line = len(split_lines(data[: err.start].decode("utf-8", "replace") + "x"))
        raise CliError(
            f"{name}:{line}: byte 0x{data[err.start]:02x} is not UTF-8 text; save the program "
            "as UTF-8 (G-code itself is ASCII)"
        ) from None


def read_lines(path: str) -> list[str]:
    """The lines of a UTF-8 text file, or of standard input for ``-`` (cut at ``\n``, ``\r\n``
    and ``\r`` only). Raises :class:`CliError` if it cannot be read or is not UTF-8."""
    name = program_name(path)
    if path == STDIN:
        if sys.stdin.isatty():
            note("reading the program from the terminal: end it with Ctrl-D (Ctrl-Z on Windows)")
        data = sys.stdin.buffer.read() if hasattr(sys.stdin, "buffer") else sys.stdin.read()
        text = decode_program(data, name) if isinstance(data, bytes) else data
        return split_lines(text)
    try:
        with open(path, "rb") as file:
            data = file.read()
    except FileNotFoundError:
        raise CliError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise CliError(f"{path}: is a directory, not a G-code file") from None
    except OSError as err:
        raise CliError(f"cannot read {path}: {err.strerror or err}") from None
    return split_lines(decode_program(data, name))


def program_of(lines: list[str]) -> list[ProgramLine]:
    """The commands of a program's lines: comments and blank lines dropped, line numbers
    kept. Each command is the text ``run`` sends."""
    program = []
    for number, raw in enumerate(lines, start=1):
        text = strip_comments(raw)
        if text:
            program.append(ProgramLine(number, text))
    return program


def read_program(path: str) -> list[ProgramLine]:
    """The commands of a G-code file (``-``: standard input): see :func:`program_of`."""
    return program_of(read_lines(path))


def program_problems(
    program: list[ProgramLine], firmware: str, start: MotionModes | None = None
) -> list[tuple[ProgramLine, str]]:
    """The one validation of a program, for ``check`` and ``run`` alike: each command as ``run``
    sends it (comments removed, so what is only in a comment is never judged), through
    :func:`~mirobot_async._core.validation.check_program` (modal state carried from ``start``,
    the modes the program starts from: power-on by default, ``HOMED`` after ``--home``), and
    its Cartesian targets through the firmware's inverse kinematics where the program gives
    their six coordinates (:func:`~mirobot_async._safety.reach.unreachable_targets`)."""
    from mirobot_async._safety.reach import unreachable_targets  # numpy: when it is needed

    texts = [line.text for line in program]
    found = check_program(texts, firmware=firmware, start=start)
    found += unreachable_targets(texts, firmware=firmware, start=start)
    found.sort(key=lambda problem: problem[0])  # (stable: a line's own problems first)
    return [(program[index - 1], message) for index, message in found]


def open_trace(
    path: str | None, *, append: bool, time_scale: float | None = None
) -> contextlib.AbstractContextManager[TraceWriter | None]:
    """A :class:`TraceWriter` for ``path`` (None: no trace); :class:`CliError` if it cannot be
    opened. ``time_scale`` is the virtual arm's speed (None: a real arm)."""
    if path is None:
        return contextlib.nullcontext()
    try:
        return TraceWriter(path, append=append, time_scale=time_scale)
    except TraceError as err:
        raise CliError(str(err)) from None
