"""``mirobot demo``: the example programs that ship with the package, run on the embedded arm.

The examples are the package ``mirobot_async._examples`` of an installed copy (the source
checkout's ``examples/`` directory, mapped to that name by pyproject), so a user who installed
from an index has something to run. A G-code example runs as ``mirobot run`` would run it (the
embedded virtual Mirobot is homed first); a script runs in a child Python process, given
``--port`` as its argument when one is named.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import importlib.resources
import sys
from pathlib import Path
from typing import Final

from mirobot_async._cli.exits import CliError, note

__all__ = ["DEFAULT_EXAMPLE", "cmd_demo", "example_files", "find_example"]

DEFAULT_EXAMPLE: Final = "pick_and_place"
"""What ``mirobot demo`` runs without a name."""
_SUFFIXES: Final = (".gcode", ".py")
_SCRIPT_STOP_TIMEOUT: Final = 5.0


def _examples_dir() -> Path | None:
    """The directory of the examples: the installed package, else the source checkout's."""
    try:
        files = importlib.resources.files("mirobot_async._examples")
    except ModuleNotFoundError:
        files = None
    if files is not None and isinstance(files, Path) and files.is_dir():
        return files
    import mirobot_async

    checkout = Path(mirobot_async.__file__).resolve().parent.parent / "examples"
    return checkout if checkout.is_dir() else None


def example_files() -> dict[str, Path]:
    """Every example by name (file name without its suffix), sorted."""
    directory = _examples_dir()
    if directory is None:
        return {}
    found = [
        path
        for path in directory.iterdir()
        if path.suffix in _SUFFIXES and not path.name.startswith("_")
    ]
    return {path.stem: path for path in sorted(found)}


def find_example(name: str) -> Path:
    """The example called ``name`` (with or without its suffix); :class:`CliError` listing the
    examples if there is none."""
    examples = example_files()
    if not examples:
        raise CliError("no examples found: this installation of mirobot-async lacks them")
    stem = name.removesuffix(".gcode").removesuffix(".py")
    path = examples.get(stem)
    if path is None or (name != stem and path.name != name):
        raise CliError(f"no example called {name!r}; the examples are: {', '.join(examples)}")
    return path


def _first_line(path: Path) -> str:
    """A one-line description: the script's docstring or the program's first comment."""
    for raw in path.read_text(encoding="utf-8", errors="replace").splitlines():
        text = raw.strip().strip('"').strip()
        if path.suffix == ".gcode":
            text = text.lstrip(";( ").rstrip(") ")
        if text:
            return text
    return ""


def list_examples() -> int:
    """Print the examples, one a line: name, kind, description."""
    examples = example_files()
    if not examples:
        raise CliError("no examples found: this installation of mirobot-async lacks them")
    width = max(map(len, examples))
    for name, path in examples.items():
        kind = "program" if path.suffix == ".gcode" else "script "
        print(f"{name:<{width}}  {kind}  {_first_line(path)}")
    return 0


async def cmd_demo(args: argparse.Namespace) -> int:
    """``mirobot demo [NAME]``: run an example (``--list`` lists them)."""
    if args.list:
        return list_examples()
    path = find_example(args.name)
    if path.suffix == ".gcode":
        from mirobot_async._cli.commands import cmd_run

        note(f"demo: running the example program {path.name} ({path})")
        args.file = str(path)
        return await cmd_run(args)
    if getattr(args, "record", None) is not None:
        raise CliError(f"--record applies to the G-code examples; {path.name} is a script")
    return await _run_script(path, args.port)


async def _run_script(path: Path, port: str | None) -> int:
    """Run an example script in a child Python; returns its exit status.

    Cancellation (Ctrl-C, SIGTERM) terminates the child and waits for it (killed after
    a few seconds).
    """
    note(f"demo: running the example script {path.name} ({path})")
    command = [sys.executable, str(path), *([port] if port is not None else [])]
    process = await asyncio.create_subprocess_exec(*command, stdin=asyncio.subprocess.DEVNULL)
    try:
        return await process.wait()
    finally:
        if process.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                process.terminate()
            try:
                async with asyncio.timeout(_SCRIPT_STOP_TIMEOUT):
                    await asyncio.shield(process.wait())
            except TimeoutError:
                with contextlib.suppress(ProcessLookupError):
                    process.kill()
                await process.wait()
