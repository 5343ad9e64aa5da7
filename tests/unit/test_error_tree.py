"""One exception tree: every error class the package defines lives in ``errors.py`` and derives
from ``MirobotError`` (the CLI's exit signals and private control-flow exceptions aside)."""

from __future__ import annotations

import ast
from pathlib import Path

import mirobot_async.errors as errors

PACKAGE = Path(errors.__file__).parent
# Control flow inside the client and the command line, never raised to a caller of the library.
INTERNAL = {
    "_Refuse",
    "StreamStopped",
    "LoopStopped",
    "CliError",
    "RobotNotReadyError",
    "TraceError",
    "PlottingUnavailableError",
    "_ViewError",  # shown on the page, never raised to a caller
}


def test_every_error_class_is_defined_in_errors_py() -> None:
    outside = []
    for path in PACKAGE.rglob("*.py"):
        if path.name == "errors.py" and path.parent == PACKAGE:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef) and node.name not in INTERNAL:
                bases = {getattr(b, "id", getattr(b, "attr", "")) for b in node.bases}
                if any(b.endswith(("Error", "Exception")) for b in bases):
                    outside.append(f"{path.relative_to(PACKAGE)}: {node.name}")
    assert not outside


def test_every_public_error_derives_from_mirobot_error() -> None:
    for name in errors.__all__:
        value = getattr(errors, name)
        if isinstance(value, type) and issubclass(value, BaseException):
            assert issubclass(value, errors.MirobotError), name
