"""The test lanes stay apart: README's test command (the default testpaths) never collects the
real-time tests, CI runs them as a lane of their own, and a session's link is a pty or TCP."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from mirobot_async.errors import MirobotUsageError
from mirobot_async.virtual._control import LINK_ENV, default_link, link_args

ROOT = Path(__file__).resolve().parents[2]


def test_the_default_testpaths_leave_the_realtime_lane_out() -> None:
    options = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    assert "tests/realtime" not in options["testpaths"]
    assert all(not path.startswith("tests/realtime") for path in options["testpaths"])
    assert any(marker.startswith("realtime:") for marker in options["markers"])


def test_ci_runs_the_realtime_lane() -> None:
    ci = (ROOT / ".ci" / "run").read_text()
    assert any(
        "python -m pytest" in line and line.rstrip().endswith("tests/realtime")
        for line in ci.splitlines()
    )


@pytest.mark.parametrize(("link", "args"), [("pty", []), ("tcp", ["--listen", "127.0.0.1:0"])])
def test_the_session_link_is_a_pty_or_tcp(
    monkeypatch: pytest.MonkeyPatch, link: str, args: list[str]
) -> None:
    monkeypatch.setenv(LINK_ENV, link.upper())
    assert default_link() == link
    assert link_args(None) == args


def test_any_other_session_link_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(LINK_ENV, "serial")
    with pytest.raises(MirobotUsageError, match="must be 'pty' or 'tcp'"):
        default_link()
