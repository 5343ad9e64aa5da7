"""Exit statuses of ``mirobot`` and the one place that maps an exception to one.

0 success; 1 the robot refused or failed (a refused line, an alarm, a locked arm, a timeout, a
lost link), the safety envelope refused a line (``move``, ``run``: the same status), or ``check``
found problems; 2 a usage problem (bad argument, missing file, port that
cannot be opened); 130 interrupted (Ctrl-C or SIGTERM; ``monitor`` exits 0: Ctrl-C is how it
ends). Errors are one line on stderr, ``mirobot: error: ...``, never a traceback.
"""

from __future__ import annotations

import sys
import traceback
from typing import Final

from mirobot_async._cli.plotting import PlottingUnavailableError
from mirobot_async.errors import (
    EnvelopeRefusedError,
    MirobotConnectionError,
    MirobotError,
    MirobotLinkLostError,
    MirobotUsageError,
)

__all__ = [
    "EXIT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_USAGE",
    "PROG",
    "CliError",
    "RobotNotReadyError",
    "exit_status_for",
    "note",
]

PROG: Final = "mirobot"
EXIT_OK: Final = 0
EXIT_FAILED: Final = 1
EXIT_USAGE: Final = 2
EXIT_INTERRUPTED: Final = 130


class CliError(Exception):
    """A usage problem (argument, file, port): printed as one line, exit status 2."""


class RobotNotReadyError(Exception):
    """The arm cannot run the command as it is (e.g. locked): one line, exit status 1.

    Raised by the pre-flight check before a byte of the command is sent.
    """


def note(message: str) -> None:
    """A remark for the user on stderr (never on stdout, which carries the results)."""
    print(f"{PROG}: {message}", file=sys.stderr, flush=True)


def exit_status_for(exc: BaseException, verbose: int) -> tuple[int, str]:
    """The exit status and the one-line message for an exception that ended a command.

    With ``verbose`` an unexpected exception's traceback is printed to stderr first.
    """
    if isinstance(exc, EnvelopeRefusedError):  # a refused command, as run's check of it
        return EXIT_FAILED, str(exc)
    if isinstance(exc, CliError | MirobotUsageError | PlottingUnavailableError):
        return EXIT_USAGE, str(exc)
    if isinstance(exc, RobotNotReadyError):
        return EXIT_FAILED, str(exc)
    if isinstance(exc, MirobotLinkLostError):
        return EXIT_FAILED, f"lost the link to the robot: {exc}"
    if isinstance(exc, MirobotConnectionError):
        return EXIT_USAGE, str(exc)
    if isinstance(exc, MirobotError):
        return EXIT_FAILED, str(exc)
    if verbose:
        traceback.print_exception(exc, file=sys.stderr)
    return EXIT_FAILED, f"unexpected {type(exc).__name__}: {exc} (run with -v for the traceback)"
