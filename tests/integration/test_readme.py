"""README.md's code runs as written: the 15-line example, and the commands it shows."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

README = Path(__file__).resolve().parents[2] / "README.md"


def _python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_example_is_short_and_runs_as_written() -> None:
    example = _python_blocks()[0]
    code_lines = [line for line in example.splitlines() if line.strip()]
    assert len(code_lines) <= 15
    done = subprocess.run(
        [sys.executable, "-c", example], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, done.stderr
    assert "2 lines acknowledged" in done.stdout
    assert "StatusReport(state=<State.IDLE" in done.stdout
    assert done.stderr == ""


def test_readme_test_command_is_the_one_ci_runs() -> None:
    ci = (README.parent / ".ci" / "run").read_text()
    pattern = r"pip install -e '\.\[test\]' && (python -m pytest[^\n`]*)"
    shown = re.search(pattern, README.read_text())
    assert shown is not None
    assert shown.group(1).strip() in ci


def test_the_plugin_example_runs_as_written_in_a_fresh_folder(tmp_path: Path) -> None:
    """README's pytest example in a project with no asyncio configuration of its own."""
    example = next(block for block in _python_blocks() if "mirobot_emulator(firmware" in block)
    (tmp_path / "test_app.py").write_text(
        "import pytest\nfrom mirobot_async import Mirobot\n\n" + example
    )
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
         "-W", "ignore::DeprecationWarning", "test_app.py"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout + done.stderr
    assert "1 passed" in done.stdout


def test_every_install_command_works_from_a_clone() -> None:
    """The package is not on an index: README installs it (and its extras) from the clone."""
    text = README.read_text()
    assert "pip install 'mirobot-async" not in text
    assert "pip install mirobot-async" not in text
    extras = re.findall(r"pip install (?:-e )?'\.\[(\w+)\]'", text)
    pyproject = (README.parent / "pyproject.toml").read_text()
    for extra in extras:
        assert re.search(rf"^{extra} = \[", pyproject, flags=re.M), extra
    assert {"view", "mcp", "test"} <= set(extras)
