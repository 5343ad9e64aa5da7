"""The pytest plugin's ``--mirobot-link oracle`` in a user's own suite: the ``mirobot_emulator``
fixture is then the vendor's firmware (a test drives it like an arm), and a test that needs what
only the emulator has (its faults, its control channel) is skipped with the reason."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from mirobot_async.testing import EmulatorError
from mirobot_async.testing._oracle import oracle_command

USER_SUITE = """
    import pytest
    from mirobot_async import Mirobot

    @pytest.mark.mirobot_emulator(firmware="classic")
    async def test_my_app(mirobot_emulator, mirobot_link):
        assert mirobot_link == "oracle"
        async with Mirobot.connect(mirobot_emulator) as arm:
            await arm.unlock()
            report = await arm.move_joints(j1=10)
            assert abs(report.joints[0] - 10) < 0.05

    @pytest.mark.mirobot_emulator(firmware="classic", extra_args=["--fault", "drop-ok:1"])
    def test_needs_a_fault(mirobot_emulator):
        raise AssertionError("not to be run on the oracle")

    @pytest.mark.mirobot_emulator(firmware="classic")
    def test_needs_the_control_channel(mirobot_emulator_process):
        mirobot_emulator_process.control("stats")
        raise AssertionError("not to be run on the oracle")
"""


def test_a_user_suite_on_the_oracle_link(tmp_path: Path) -> None:
    try:
        oracle_command(0)
    except EmulatorError as missing:
        if os.environ.get("MIROBOT_REQUIRE_ORACLE") == "1":
            raise
        pytest.skip(str(missing))
    (tmp_path / "test_user.py").write_text(textwrap.dedent(USER_SUITE))
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider",
         "--mirobot-link", "oracle", "-o", "asyncio_mode=auto", "test_user.py"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout + done.stderr
    assert "1 passed, 2 skipped" in done.stdout, done.stdout
    assert "the firmware oracle has no emulator options (--fault drop-ok:1)" in done.stdout
    assert "needs the emulator's control channel ('stats')" in done.stdout
