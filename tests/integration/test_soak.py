"""The soak (issue 7, section 3): ``benchmarks/soak.py`` run by the test suite.

20,000 lines (times ``MIROBOT_TEST_SCALE`` above 1, for thorough runs) streamed to the emulator
process (time scale 0) over a real pty while the status is polled every 50 ms: every line
acknowledged exactly once and in order (on the client's side and, through the pump PWM in the
status reports, on the firmware's side), nothing pending at the end, RSS growth below 5 MB. The
million-line run is ``python benchmarks/soak.py``. A test of the emulator as a process and its
pty: it runs on the link lanes (``MIROBOT_TEST_LINK=pty|tcp``), not on README's command.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path
from types import ModuleType

import pytest

pytestmark = pytest.mark.timeout(120)  # about 5 s here; generous for a loaded CI machine

SOAK_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "soak.py"
LINES = round(20_000 * max(1.0, float(os.environ.get("MIROBOT_TEST_SCALE", "1"))))


def load_soak() -> ModuleType:
    """Import ``benchmarks/soak.py`` by path (``benchmarks`` is not an installed package)."""
    spec = importlib.util.spec_from_file_location("mirobot_benchmarks_soak", SOAK_PATH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while being created
    spec.loader.exec_module(module)
    return module


soak = load_soak()


def test_pwm_window_check() -> None:
    """The firmware-side order check accepts the window and rejects what lies outside it."""
    matches = soak._pwm_matches
    assert matches(0, 0, 0)  # nothing executed yet: PWM still 0
    assert matches(5, 3, 7)  # line 5 executed last, lines 0..2 acknowledged before the "?"
    assert not matches(9, 3, 7)  # line 9 cannot have run: only 7 lines were acknowledged
    assert not matches(1, 3, 7)  # line 1 is older than the acknowledged lines: out of order
    assert matches(1000 % soak.PWM_VALUES, 1000, 1001)
    assert matches(0, 1001, 1002)  # line 1001 sets PWM 0 again


@pytest.mark.emulator_process
async def test_soak_20k_lines() -> None:
    result = await soak.run_soak(LINES, poll_interval=0.05)
    print(result.report())
    assert result.problems == []
    assert result.acknowledged == LINES
    assert result.statuses > 0
    assert result.status_checked == result.statuses
    assert result.corrupted_statuses == 0
    assert result.pending_count == 0
    assert result.bytes_in_flight == 0
    assert result.rss_growth_mb < 5.0
