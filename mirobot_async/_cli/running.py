"""Running a ``mirobot`` command: :func:`main` parses the arguments, runs the subcommand (in an
event loop if it talks to an arm, with SIGINT/SIGTERM handled by
:class:`~mirobot_async._cli.session.Interrupts`), and maps its outcome to an exit status."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import inspect
import logging
import os
import sys
from collections.abc import Awaitable, Callable, Iterator, Sequence

from mirobot_async._cli.arguments import build_parser
from mirobot_async._cli.commands import emulator_main
from mirobot_async._cli.exits import (
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    PROG,
    exit_status_for,
)
from mirobot_async._cli.session import Interrupts

__all__ = ["main"]


@contextlib.contextmanager
def _logging_to_stderr(verbose: int) -> Iterator[None]:
    """Log ``mirobot_async`` records to stderr: everything (the wire traffic) with ``-v``, else
    only errors (what went wrong is said once, by the ``mirobot: error:`` line).

    Undone at the end, so that calling :func:`main` in-process leaves logging as it was.
    """
    logger = logging.getLogger("mirobot_async")
    saved = (logger.level, logger.propagate)
    handler = logging.StreamHandler(sys.stderr)
    if verbose:
        handler.setFormatter(logging.Formatter("%(relativeCreated)9.1f ms %(name)s: %(message)s"))
        logger.setLevel(logging.DEBUG)
    else:
        handler.setFormatter(logging.Formatter(f"{PROG}: %(levelname)s: %(message)s"))
        logger.setLevel(logging.ERROR)
    logger.addHandler(handler)
    logger.propagate = False
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(saved[0])
        logger.propagate = saved[1]


def _run_async(
    handler: Callable[[argparse.Namespace], Awaitable[int]], args: argparse.Namespace
) -> tuple[int, bool]:
    """Run an async subcommand; returns (status, interrupted by SIGINT or SIGTERM)."""
    interrupts: list[Interrupts] = []

    async def runner() -> int:
        task = asyncio.current_task()
        assert task is not None
        watch = Interrupts(task)
        interrupts.append(watch)
        with watch.installed():
            return await handler(args)

    def interrupted() -> bool:
        return bool(interrupts) and interrupts[0].signal is not None

    try:
        return asyncio.run(runner()), False
    except (KeyboardInterrupt, asyncio.CancelledError):
        return EXIT_INTERRUPTED, True
    except BaseException:
        if interrupted():  # whatever broke while stopping, the signal was the cause
            return EXIT_INTERRUPTED, True
        raise


def _emulator_argv(argv: Sequence[str]) -> list[str] | None:
    """The emulator's arguments if this is ``mirobot [-v] emulator ...``, else None."""
    for index, arg in enumerate(argv):
        if arg == "emulator":
            return list(argv[index + 1 :])
        if arg not in ("-v", "--verbose", "-vv"):
            return None
    return None


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``mirobot``; returns the exit status."""
    arguments = list(sys.argv[1:] if argv is None else argv)
    emulator_args = _emulator_argv(arguments)
    if emulator_args is not None:
        return emulator_main(emulator_args)
    args = build_parser().parse_args(arguments)
    verbose: int = getattr(args, "verbose", 0)
    with _logging_to_stderr(verbose):
        try:
            return _run_command(args)
        except KeyboardInterrupt:
            return EXIT_INTERRUPTED
        except BrokenPipeError:
            # stdout was closed early (``mirobot monitor | head``): not worth a message.
            with contextlib.suppress(OSError):
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return EXIT_FAILED
        except Exception as exc:
            status, message = exit_status_for(exc, verbose)
            print(f"{PROG}: error: {message}", file=sys.stderr, flush=True)
            return status


def _run_command(args: argparse.Namespace) -> int:
    handler = args.handler
    if not inspect.iscoroutinefunction(handler):
        status: int = handler(args)
        return status
    status, interrupted = _run_async(handler, args)
    if interrupted:  # Ctrl-C is how monitor ends: not a failure
        return EXIT_OK if args.command == "monitor" else EXIT_INTERRUPTED
    return status
