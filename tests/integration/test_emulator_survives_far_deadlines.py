"""The emulator keeps serving whatever deadline the firmware model or a fault sets: a dwell of
days (``G4 P3000000``), a feed of 0.0001, a stall of 1e12 s. Its loop wakes again at most every
``LONGEST_WAIT_S`` instead of handing ``select()`` a timeout it cannot take (the process used to
die with ``OverflowError``). Real time (time scale 1): these deadlines are wall-clock ones."""

from __future__ import annotations

import contextlib

import pytest

from mirobot_async import Mirobot, MirobotConnectionError, MirobotTimeoutError, State
from mirobot_async.testing import EmulatorProcess

# the emulator as a process and its links: run on the link lanes (MIROBOT_TEST_LINK=pty|tcp)
pytestmark = pytest.mark.emulator_process


@pytest.mark.parametrize(("line", "state"), [("G4 P3000000", None), ("G1 X10 F0.0001", State.RUN)])
async def test_a_far_motion_deadline_keeps_the_emulator_serving(
    line: str, state: State | None
) -> None:
    async with await EmulatorProcess.start("2021", 1.0) as emu, Mirobot.connect(emu.url) as arm:
        await arm.unlock()
        with contextlib.suppress(MirobotTimeoutError):  # the dwell's ok is days away
            await arm.send(line, validate=False, timeout=0.5)
        report = await arm.status(timeout=5)  # answered: the server loop went on
        assert state is None or report.state is state
        assert emu.returncode is None
        await arm.reset()  # the dwell or the crawl ends; the link is in step again
        assert (await arm.status()).state in (State.IDLE, State.ALARM)


@pytest.mark.parametrize("seconds", ["1e12", "1e300"])
async def test_a_stall_of_ages_keeps_the_emulator_serving(seconds: str) -> None:
    async with await EmulatorProcess.start(
        "2021", 1.0, extra_args=["--fault", f"stall:0:{seconds}"]
    ) as emu:
        # the banner and the status wait behind the stall: the loop's next deadline is its end
        with pytest.raises(MirobotConnectionError, match="no Mirobot answered"):
            async with Mirobot.connect(emu.url, timeout=0.5):
                pass
        assert (await emu.control("motion-ends")).startswith("ack motion-ends")
        assert emu.returncode is None
