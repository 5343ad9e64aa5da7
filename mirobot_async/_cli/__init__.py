"""The ``mirobot`` command line (also ``python -m mirobot_async``).

Subcommands that talk to an arm take ``--port URL`` (default ``$MIROBOT_PORT``) or ``--auto``
(the one port that answers as a Mirobot); without either they start an embedded virtual
Mirobot (the emulator, on a fresh pseudo-terminal, or a loopback TCP port where there are no
ptys) for the duration of the command, so every command works on a machine with no arm.
``--firmware`` and ``--time-scale`` choose that virtual arm's profile and speed; ``-v`` logs the
wire traffic to stderr. Exit statuses: see
:mod:`mirobot_async._cli.exits`.

Layout (each module imports only the ones below it):

* :mod:`~mirobot_async._cli.running`: :func:`main`, the event loop, signals, exit statuses;
* :mod:`~mirobot_async._cli.arguments`: the argparse parser (number types, option groups);
* :mod:`~mirobot_async._cli.commands`: one ``cmd_*`` function per subcommand;
* :mod:`~mirobot_async._cli.demo`: ``mirobot demo``, the examples shipped with the package;
* :mod:`~mirobot_async._cli.targets`: the KEY=VALUE targets of ``move``;
* :mod:`~mirobot_async._cli.ports`: ``mirobot ports``, listing and probing serial ports (the
  probe is :mod:`mirobot_async._client.ports`, which ``--auto`` and ``Mirobot.connect("auto")``
  use);
* :mod:`~mirobot_async._cli.watching`: ``--view``, the 3D view on the command's connection;
* :mod:`~mirobot_async._cli.session`: opening, preparing and pre-flighting the arm, background
  jobs, stopping safely on SIGINT/SIGTERM;
* :mod:`~mirobot_async._cli.rendering`: status tables, progress bar, live monitor, summaries;
* :mod:`~mirobot_async._cli.programs`: program files (or stdin) and trace files;
* :mod:`~mirobot_async._cli.exits`: exit statuses, :class:`CliError`, the exception mapping.
"""

from __future__ import annotations

from mirobot_async._cli.arguments import build_parser
from mirobot_async._cli.exits import (
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    CliError,
    RobotNotReadyError,
    exit_status_for,
)
from mirobot_async._cli.programs import ProgramLine, read_program
from mirobot_async._cli.rendering import (
    ProgressBar,
    RichProgressBar,
    format_status_line,
    format_status_table,
)
from mirobot_async._cli.running import main
from mirobot_async._cli.session import DEFAULT_TIME_SCALE
from mirobot_async._cli.targets import JOINT_KEYS, POSE_KEYS, parse_assignments

__all__ = [
    "DEFAULT_TIME_SCALE",
    "EXIT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_USAGE",
    "JOINT_KEYS",
    "POSE_KEYS",
    "CliError",
    "ProgramLine",
    "ProgressBar",
    "RichProgressBar",
    "RobotNotReadyError",
    "build_parser",
    "exit_status_for",
    "format_status_line",
    "format_status_table",
    "main",
    "parse_assignments",
    "read_program",
]
