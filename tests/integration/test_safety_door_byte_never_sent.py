"""A line with ``@`` anywhere (a comment too) is refused by ``send()``, ``stream()`` and
``mirobot check`` before a byte is written: the firmware would take ``@`` at once and stop
reading lines until ``~``, and the replies would no longer belong to their lines."""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from mirobot_async import Mirobot, MirobotUsageError

Cli = Callable[..., subprocess.CompletedProcess[str]]


async def test_send_and_stream_refuse_it_and_write_nothing(ready_arm: Mirobot) -> None:
    arm = ready_arm
    sent = arm.stats.bytes_sent
    with pytest.raises(MirobotUsageError, match="'@'"):
        await arm.send("G4 P0 (@ note)")
    with pytest.raises(MirobotUsageError, match="'@'"):
        await arm.send("G4 P0 (@ note)", validate=False)
    result = await arm.stream(["M3 S10 ; mail me@home", "M3 S20"])
    assert [failed.number for failed in result.errors] == [1]
    assert isinstance(result.errors[0].error, MirobotUsageError)
    assert arm.stats.bytes_sent == sent
    # in step: the next line gets its own reply
    assert await arm.send("M3 S30") == ()
    assert (await arm.status()).pump_pwm == 30


def test_check_reports_it(cli: Cli, tmp_path: Path) -> None:
    program = tmp_path / "door.gcode"
    program.write_text("M21 G90\nG0 X1 @\n")
    proc = cli("check", str(program))
    assert proc.returncode == 1
    assert f"{program}:2:" in proc.stdout and "'@'" in proc.stdout
