"""Program files and trace files of the command line: reading G-code (a file or ``-`` for
standard input) into numbered commands, and opening a trace CSV with a usage error on failure."""

from __future__ import annotations

import contextlib
import sys
from dataclasses import dataclass
from typing import Final

from mirobot_async._cli.exits import CliError, note
from mirobot_async._cli.plotting import TraceError, TraceWriter

__all__ = ["STDIN", "ProgramLine", "open_trace", "program_name", "read_lines", "read_program"]

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


def read_lines(path: str) -> list[str]:
    """The lines of a text file, or of standard input for ``-`` (latin-1, so that any byte is
    reported by ``check``, not a decode error). Raises :class:`CliError` if it cannot be read."""
    if path == STDIN:
        if sys.stdin.isatty():
            note("reading the program from the terminal: end it with Ctrl-D (Ctrl-Z on Windows)")
        data = sys.stdin.buffer.read() if hasattr(sys.stdin, "buffer") else sys.stdin.read()
        text = data.decode("latin-1") if isinstance(data, bytes) else data
        return text.splitlines()
    try:
        with open(path, encoding="latin-1", newline=None) as file:
            return file.read().splitlines()
    except FileNotFoundError:
        raise CliError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise CliError(f"{path}: is a directory, not a G-code file") from None
    except OSError as err:
        raise CliError(f"cannot read {path}: {err.strerror or err}") from None


def read_program(path: str) -> list[ProgramLine]:
    """The commands of a G-code file (``-``: standard input): comments and blank lines dropped,
    line numbers kept."""
    program = []
    for number, raw in enumerate(read_lines(path), start=1):
        text = strip_comments(raw)
        if text:
            program.append(ProgramLine(number, text))
    return program


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
