"""Differential tests against the firmware oracle: skip (one line) or fail when it is missing,
mark the currently known differences strict-xfail, and give each test a fresh pair."""

from __future__ import annotations

import os
from collections.abc import Generator, Iterator
from pathlib import Path

import pytest

from .harness import Pair, oracle_missing
from .known import KNOWN_DIFFERENCES

MISSING = oracle_missing()
REQUIRE = os.environ.get("MIROBOT_REQUIRE_ORACLE", "") not in ("", "0")

# Without the oracle only test_availability.py is collected: it reports the one skip line (or
# the failure, with MIROBOT_REQUIRE_ORACLE=1).
collect_ignore_glob = ["test_diff_*.py"] if MISSING else []

HERE = Path(__file__).parent

TORN_SWITCH_READ = pytest.mark.flaky(reruns=1, only_rerun=[r"Hard limit", r"Reset to continue"])
"""The simulator's switch model (../shared/firmware-oracle/fwsim.c) reads the firmware's 32-bit
position between 100 us chunks of instructions, possibly between the stepper interrupt's byte
stores: as a joint crosses zero it can read +-65535 steps, press a range switch and make the
firmware print ``ALARM: Hard limit`` that no arm would (seen about once in four suite runs on a
loaded machine). A failure whose text names a hard limit (the harness's transcript, or the
client's ``MirobotAlarmError``), or the ``[Reset to continue]`` that follows it (when the alarm
line was read with an earlier reply), runs once more on a fresh oracle; a genuine difference
fails both times."""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Each test named in KNOWN_DIFFERENCES becomes a strict xfail (an AssertionError only);
    every test gets one rerun for the simulator's torn switch reads (:data:`TORN_SWITCH_READ`)."""
    for item in items:
        if item.path.parent != HERE:
            continue
        item.add_marker(TORN_SWITCH_READ)
        reason = KNOWN_DIFFERENCES.get(f"{item.path.stem}::{item.name}")
        if reason:
            item.add_marker(pytest.mark.xfail(strict=True, reason=reason, raises=AssertionError))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(
    item: pytest.Item, call: pytest.CallInfo[None]
) -> Generator[None, pytest.TestReport, pytest.TestReport]:
    """With ``MIROBOT_ORACLE_REPORT=FILE``, append every difference found (failed or xfailed
    test) to FILE as a markdown section: the raw material of the differences list."""
    report: pytest.TestReport = yield
    target = os.environ.get("MIROBOT_ORACLE_REPORT")
    if target and call.when == "call" and call.excinfo is not None and item.path.parent == HERE:
        known = KNOWN_DIFFERENCES.get(f"{item.path.stem}::{item.name}")
        text = f"### {item.path.stem}::{item.name}\n"
        if known:
            text += f"(known: {known})\n"
        text += "```\n" + str(call.excinfo.value).strip() + "\n```\n\n"
        with open(target, "a", encoding="utf-8") as out:
            out.write(text)
    return report


@pytest.fixture
def pair(tmp_path: Path) -> Iterator[Pair]:
    """The oracle and our emulator, freshly powered on; both stopped after the test."""
    both = Pair.spawn(tmp_path).connect()
    try:
        yield both
    finally:
        both.close()
