"""The house rules, checked: small rooms (no module over 600 lines, no class over 400), a pure
sans-IO core, and an emulator that imports nothing of the client but the kinematics."""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SOURCES = sorted(
    [*ROOT.joinpath("mirobot_async").rglob("*.py"), *ROOT.joinpath("emulator").rglob("*.py")]
)

# The layers are directories: the pure core (_core, _safety, and the two public pure modules)
# may not touch asyncio, the OS, the clock or the serial port; each layer imports only the
# layers below it.
PACKAGE = ROOT / "mirobot_async"
PURE = sorted(
    [
        PACKAGE / "errors.py",
        PACKAGE / "kinematics.py",
        *PACKAGE.joinpath("_core").glob("*.py"),
        *PACKAGE.joinpath("_safety").glob("*.py"),
    ]
)
LAYERS = {  # a directory -> the mirobot_async modules and packages it may import
    "_core": {"errors", "_core"},
    "_safety": {"errors", "kinematics", "_core", "_safety"},
    "_client": {"errors", "kinematics", "_core", "_safety", "_client"},
    "_tapes": {"errors", "_tapes"},  # the client only under TYPE_CHECKING or when recording
    "virtual": {"errors", "_client", "virtual"},  # the virtual arm: a product, not a test tool
}
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


@functools.cache
def _tree(path: Path) -> ast.Module:
    """``path`` parsed (once: several rules read each module)."""
    return ast.parse(path.read_text())


def _imports(path: Path) -> set[str]:
    tree = _tree(path)
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
    tree = _tree(path)
    return {
        (node.level, node.module or "")
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and node.level > 0
    }


@pytest.mark.parametrize("path", PURE, ids=lambda p: str(p.relative_to(ROOT)))
def test_sans_io_core_is_pure(path: Path) -> None:
    imported = {module.split(".")[0] for module in _imports(path)}
    assert not imported & IMPURE_MODULES


def _top_level_imports(path: Path) -> set[str]:
    """mirobot_async modules imported at module level (not inside a function or TYPE_CHECKING)."""
    tree = _tree(path)
    names: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            parts = node.module.split(".")
            if parts[0] == "mirobot_async":
                names.update([parts[1]] if len(parts) > 1 else [a.name for a in node.names])
        elif isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == "mirobot_async" and len(parts) > 1:
                    names.add(parts[1])
    return names


@pytest.mark.parametrize(
    "path",
    sorted(p for layer in LAYERS for p in PACKAGE.joinpath(layer).glob("*.py")),
    ids=lambda p: str(p.relative_to(ROOT)),
)
def test_each_layer_imports_only_the_layers_below(path: Path) -> None:
    layer = path.parent.name
    assert _top_level_imports(path) <= LAYERS[layer]


def test_every_module_is_in_a_layer_or_public() -> None:
    """A new module goes into a layer (a private directory) or is one of the few public ones."""
    public = {
        p.relative_to(PACKAGE).as_posix()
        for p in PACKAGE.rglob("*.py")
        if not any(
            part.startswith("_") and part not in ("__init__.py", "__main__.py")
            for part in p.relative_to(PACKAGE).parts
        )
    }
    assert public <= {
        "__init__.py",
        "__main__.py",
        "errors.py",
        "kinematics.py",
        "bus/__init__.py",
        "sync/__init__.py",
        "testing/__init__.py",
        "virtual/__init__.py",
    }, public


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in PACKAGE.rglob("*.py")}


def _imported_modules(name: str, path: Path) -> set[str]:
    """The mirobot_async modules ``name`` imports anywhere: at module level, under
    ``TYPE_CHECKING``, or deferred into a function (a deferred import hides a circle, it does
    not remove it). ``from package import module`` names the module; the parent packages a
    dotted import runs first are not counted (every module would import the root)."""
    found: set[str] = set()
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)]
                module = ".".join([*base, *([node.module] if node.module else [])])
            else:
                module = node.module or ""
            for alias in node.names:
                if f"{module}.{alias.name}" in MODULES:
                    found.add(f"{module}.{alias.name}")
                elif module in MODULES:
                    found.add(module)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names if alias.name in MODULES)
    found.discard(name)
    return found


def _import_circles() -> list[list[str]]:
    """The groups of modules that import each other through a circle (strongly connected
    components of the import graph with more than one module), each sorted."""
    graph = {name: _imported_modules(name, path) for name, path in MODULES.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []

    def visit(module: str) -> None:  # Tarjan
        index[module] = low[module] = len(index)
        stack.append(module)
        for imported in graph[module]:
            if imported not in index:
                visit(imported)
                low[module] = min(low[module], low[imported])
            elif imported in stack:
                low[module] = min(low[module], index[imported])
        if low[module] == index[module]:
            group = []
            while True:
                member = stack.pop()
                group.append(member)
                if member == module:
                    break
            if len(group) > 1:
                circles.append(sorted(group))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    return sorted(circles)


KNOWN_CIRCLES: list[list[str]] = []


def test_no_module_imports_itself_through_a_circle() -> None:
    """A module's imports lead back to it through no chain of imports: the layers are a tree,
    and a circle hidden in a function or under TYPE_CHECKING is still a circle."""
    assert _import_circles() == KNOWN_CIRCLES


def test_the_circle_check_sees_deferred_and_type_checking_imports() -> None:
    # the guard imports Envelope under TYPE_CHECKING and the prediction inside its methods
    imported = _imported_modules("mirobot_async._client.guard", PACKAGE / "_client" / "guard.py")
    assert {"mirobot_async._safety.prediction", "mirobot_async._safety.envelope"} <= imported


def test_nothing_but_the_plugin_imports_the_plugin() -> None:
    """The virtual arm is a product (the CLI, the view, the MCP server run it): no module
    outside ``testing/`` imports ``mirobot_async.testing``, not even inside a function."""
    importers = {
        path.relative_to(PACKAGE).as_posix()
        for path in PACKAGE.rglob("*.py")
        if path.parent.name != "testing"
        and any(m.startswith("mirobot_async.testing") for m in _imports(path))
    }
    assert not importers


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


EMULATOR_PUBLIC = {
    "mirobot_emulator",
    "mirobot_emulator.__main__",
    "mirobot_emulator.bus",
    "mirobot_emulator.firmware",
    "mirobot_emulator.motion",
    "mirobot_emulator.server",
    "mirobot_emulator.server.clock",
    "mirobot_emulator.server.loop",
    "mirobot_emulator.server.options",
    "mirobot_emulator.settings",
}
"""The emulator's entry points: its command, the pure models, the server; the rest is private."""


def test_the_emulator_modules_are_private_but_its_entry_points() -> None:
    public = set()
    for path in ROOT.joinpath("emulator").rglob("*.py"):
        parts = path.relative_to(ROOT / "emulator").with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if not any(part.startswith("_") and part != "__main__" for part in parts):
            public.add(".".join(("mirobot_emulator", *parts)))
    assert public == EMULATOR_PUBLIC


def test_pre_commit_runs_the_ruff_of_the_dev_extra() -> None:
    """One ruff: the hook a contributor runs on commit and the one CI runs agree."""
    import re
    import tomllib

    root = Path(__file__).resolve().parents[2]
    dev = tomllib.loads((root / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    (pin,) = [spec for spec in dev["dev"] if spec.startswith("ruff")]
    hook = re.search(
        r"ruff-pre-commit\n\s+rev: v([\d.]+)", (root / ".pre-commit-config.yaml").read_text()
    )
    assert hook is not None
    assert pin == f"ruff=={hook.group(1)}"
