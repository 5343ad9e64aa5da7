"""The pytest plugin in a user's project (a fresh folder, no configuration of its own): quiet in
tests that use none of its fixtures, the marker checked, the link choice applied."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from mirobot_async.errors import MirobotUsageError
from mirobot_async.testing import _options


def _pytest(folder: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
         "-W", "ignore::DeprecationWarning", *args],
        cwd=folder, capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip


UNRELATED = """
import pytest

def test_plain():
    pass

@pytest.mark.parametrize("n", [1, 2])
def test_parametrised(n):
    pass

async def test_async_without_the_plugin():
    pass
"""


def test_a_project_that_uses_none_of_its_fixtures_sees_nothing_of_it(tmp_path: Path) -> None:
    """The same tests, the same outcomes and ids, with the plugin and without it (``-p no:``)."""
    (tmp_path / "test_unrelated.py").write_text(UNRELATED)
    with_plugin = _pytest(tmp_path, "-rA")
    without = _pytest(tmp_path, "-rA", "-p", "no:mirobot")
    assert "test_async_without_the_plugin" in with_plugin.stdout
    assert with_plugin.returncode == without.returncode
    assert sorted(with_plugin.stdout.splitlines()[:-1]) == sorted(without.stdout.splitlines()[:-1])


def test_the_plugin_module_loads_neither_the_client_nor_the_emulator() -> None:
    """Loaded in every pytest run of a project that installs the package: kept cheap."""
    code = (
        "import sys, mirobot_async.testing\n"
        "heavy = ('asyncio', 'numpy', 'serial', 'mirobot_emulator', 'mirobot_async._client')\n"
        "print(sorted(m for m in heavy if m in sys.modules))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert done.stdout.strip() == "[]"


def test_both_links_run_a_test_once_per_link(tmp_path: Path) -> None:
    (tmp_path / "test_links.py").write_text(
        "def test_port(mirobot_emulator):\n    pass\n\ndef test_other():\n    pass\n"
    )
    done = _pytest(tmp_path, "--collect-only", "--mirobot-link", "both")
    assert done.returncode == 0, done.stdout + done.stderr
    collected = [line for line in done.stdout.splitlines() if "::" in line]
    assert collected == [
        "test_links.py::test_port[pty]",
        "test_links.py::test_port[tcp]",
        "test_links.py::test_other",
    ]


class _Marker:
    def __init__(self, *args: object, **kwargs: object) -> None:
        self.args, self.kwargs = args, kwargs


class _Request:
    """What :func:`_options.settings` reads of a ``pytest.FixtureRequest``."""

    def __init__(self, marker: _Marker | None) -> None:
        options = {"--mirobot-firmware": "2021", "--mirobot-time-scale": 0.0}
        self.config = type("Config", (), {"getoption": staticmethod(options.__getitem__)})()
        self.node = type("Node", (), {"get_closest_marker": staticmethod(lambda name: marker)})()


def test_the_marker_overrides_the_command_line() -> None:
    marker = _Marker(firmware="classic", extra_args=["--baud", "115200"], fresh=1)
    settings = _options.settings(_Request(marker))  # type: ignore[arg-type]
    assert settings == _options.ArmSettings(
        "classic", 0.0, extra_args=("--baud", "115200"), fresh=True
    )
    assert _options.settings(_Request(None)) == _options.ArmSettings("2021", 0.0)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("marker", "message"),
    [
        (_Marker("classic"), "keyword arguments only"),
        (_Marker(profile="classic"), "unknown argument(s) profile"),
    ],
)
def test_a_bad_marker_is_a_usage_error(marker: _Marker, message: str) -> None:
    with pytest.raises(MirobotUsageError, match=message.replace("(", r"\(").replace(")", r"\)")):
        _options.settings(_Request(marker))  # type: ignore[arg-type]
