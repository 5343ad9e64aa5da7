"""The test lanes stay apart: README's test command (the default testpaths) never collects the
real-time tests, CI runs them and the oracle link as lanes of their own, and the oracle link
refuses, before any process starts, what only the emulator can be."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from mirobot_async.testing import EmulatorPool
from mirobot_async.testing._control import LINK_ENV, OracleUnsupportedError, default_link, link_args
from mirobot_async.testing._oracle import beyond_the_wire

ROOT = Path(__file__).resolve().parents[2]


def test_the_default_testpaths_leave_the_realtime_lane_out() -> None:
    options = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    assert "tests/realtime" not in options["testpaths"]
    assert all(not path.startswith("tests/realtime") for path in options["testpaths"])
    assert any(marker.startswith("realtime:") for marker in options["markers"])


def test_ci_runs_the_realtime_and_oracle_lanes() -> None:
    ci = (ROOT / ".ci" / "run").read_text()
    assert "MIROBOT_TEST_LINK=oracle python -m pytest" in ci
    assert any(
        "python -m pytest" in line and line.rstrip().endswith("tests/realtime")
        for line in ci.splitlines()
    )


def test_the_oracle_link_is_a_link_choice(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(LINK_ENV, "oracle")
    assert default_link() == "oracle"
    assert link_args(None) == []  # an emulator started directly then serves a pty


@pytest.mark.parametrize(
    ("firmware", "extra_args", "words"),
    [("2021", (), "classic firmware"), ("classic", ("--fault", "drop-ok:1"), "drop-ok:1")],
)
def test_the_oracle_refuses_what_only_the_emulator_is(
    firmware: str, extra_args: tuple[str, ...], words: str
) -> None:
    with EmulatorPool(link="oracle") as pool:
        with pytest.raises(OracleUnsupportedError, match=words):
            pool.acquire(firmware, 0.0, extra_args=extra_args)
        assert pool.started == 0  # refused before any process starts


def test_the_arms_own_link_options_are_the_oracle_as_it_is() -> None:
    assert beyond_the_wire(["--baud", "115200", "--usb-latency-ms", "16"]) == []
    assert beyond_the_wire(["--baud=115200"]) == []
    assert beyond_the_wire(["--baud", "9600"]) == ["--baud", "9600"]
    assert beyond_the_wire(["--reset-on-open", "--baud", "115200"]) == ["--reset-on-open"]
