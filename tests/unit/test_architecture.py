"""The house rules, checked: small rooms (no module over 600 lines, no class over 400), a pure
sans-IO core, and an emulator that imports nothing of the client but the kinematics."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SOURCES = sorted(
    [*ROOT.joinpath("mirobot_async").rglob("*.py"), *ROOT.joinpath("emulator").rglob("*.py")]
)

# Modules that may not touch asyncio, the OS, the clock or the serial port.
PURE_CLIENT = [
    "errors",
    "events",
    "outgoing",
    "protocol",
    "replies",
    "line",
    "validation",
    "gcode",
    "values",
    "settings",
    "modal",
    "paths",
    "cartesian",
    "prediction",
    "firmware_memory",
    "envelope",
    "kinematics",
]
IMPURE_MODULES = {
    "asyncio",
    "os",
    "time",
    "serial",
    "serial_asyncio",
    "serial_asyncio_fast",
    "socket",
    "selectors",
    "threading",
    "subprocess",
    "signal",
}


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module == "mirobot_async":  # from mirobot_async import kinematics
                names.update(f"mirobot_async.{alias.name}" for alias in node.names)
            else:
                names.add(node.module)
    return names


def _relative_imports(path: Path) -> set[tuple[int, str]]:
    tree = ast.parse(path.read_text())
    return {
        (node.level, node.module or "")
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and node.level > 0
    }


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_module_and_classes_are_small(path: Path) -> None:
    lines = path.read_text().count("\n")
    assert lines <= 600, f"{path.name}: {lines} lines"
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ClassDef):
            size = (node.end_lineno or node.lineno) - node.lineno + 1
            assert size <= 400, f"class {node.name}: {size} lines"


@pytest.mark.parametrize("name", PURE_CLIENT)
def test_sans_io_core_is_pure(name: str) -> None:
    imported = {module.split(".")[0] for module in _imports(ROOT / "mirobot_async" / f"{name}.py")}
    assert not imported & IMPURE_MODULES


EMULATOR_PURE = sorted(
    [
        *ROOT.joinpath("emulator", "firmware").glob("*.py"),
        *ROOT.joinpath("emulator", "motion").glob("*.py"),
        *ROOT.joinpath("emulator", "bus").glob("*.py"),
    ]
)


@pytest.mark.parametrize("path", EMULATOR_PURE, ids=lambda p: str(p.relative_to(ROOT)))
def test_emulator_model_is_pure(path: Path) -> None:
    imported = {module.split(".")[0] for module in _imports(path)}
    assert not imported & IMPURE_MODULES


@pytest.mark.parametrize(
    "path", sorted(ROOT.joinpath("emulator").rglob("*.py")), ids=lambda p: str(p.relative_to(ROOT))
)
def test_emulator_imports_only_the_kinematics_of_the_client(path: Path) -> None:
    client = {m for m in _imports(path) if m.split(".")[0] == "mirobot_async"}
    assert client <= {"mirobot_async.kinematics", "mirobot_async.errors"}, client
    # ... and never climbs out of its own package with a relative import
    depth = len(path.relative_to(ROOT / "emulator").parts)
    assert all(level < depth + 1 for level, _ in _relative_imports(path))
