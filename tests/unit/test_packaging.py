"""The wheel carries every package of the tree: pyproject lists subpackages by hand (the emulator's
directory is installed under another name), so a new package that is not listed would be missing
from a non-editable install."""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _listed() -> set[str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    return set(config["tool"]["setuptools"]["packages"])


def _on_disk() -> set[str]:
    names: set[str] = set()
    for directory, import_name in (
        ("mirobot_async", "mirobot_async"),
        ("emulator", "mirobot_emulator"),
        ("examples", "mirobot_async._examples"),
    ):
        base = ROOT / directory
        for init in base.rglob("__init__.py"):
            parts = init.parent.relative_to(base).parts
            names.add(".".join((import_name, *parts)))
    return names


def test_every_package_is_listed_in_pyproject() -> None:
    assert _on_disk() == _listed()


def test_license_is_spdx_and_shipped() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert config["project"]["license"] == "MIT"
    assert (ROOT / "LICENSE").read_text().startswith("MIT License")
