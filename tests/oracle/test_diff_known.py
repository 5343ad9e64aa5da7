"""The known-differences list stays honest: every entry names a collected test."""

from __future__ import annotations

import pytest

from .known import KNOWN_DIFFERENCES


def test_known_differences_name_real_tests(request: pytest.FixtureRequest) -> None:
    """Every KNOWN_DIFFERENCES key names a collected test, so a renamed test cannot silently
    keep a stale entry."""
    session = request.session
    names = {f"{item.path.stem}::{item.name}" for item in session.items}
    if not any(name.startswith("test_diff_") for name in names):
        pytest.skip("run together with the test_diff_* modules to check the entries")
    stale = sorted(
        key
        for key in KNOWN_DIFFERENCES
        if key.split("::")[0] in {n.split("::")[0] for n in names} and key not in names
    )
    assert not stale, f"KNOWN_DIFFERENCES entries naming no test: {stale}"
