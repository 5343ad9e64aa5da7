"""Is the firmware oracle there? Without it the differential tests are not collected, and this
is the one skip line that says how to enable them (a failure with MIROBOT_REQUIRE_ORACLE=1)."""

from __future__ import annotations

import pytest

from .conftest import MISSING, REQUIRE


def test_oracle_available() -> None:
    if MISSING:
        if REQUIRE:
            pytest.fail(f"MIROBOT_REQUIRE_ORACLE is set but the {MISSING}")
        pytest.skip(MISSING)
