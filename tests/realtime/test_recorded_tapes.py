"""A virtual arm's tape recorded at the arm's own speed replays equal, instants included.

At time scale 1 the in-process arm's clock is the wall clock, so the replay compares the
instants of what it printed (loosely: within a second, the arm's clock loop wakes when the host
lets it); faster than real time only the bytes and their order are compared
(tests/integration/test_recording.py).
"""

from __future__ import annotations

from pathlib import Path

from mirobot_async import Mirobot
from mirobot_async._tapes.format import read_tapes
from mirobot_async._tapes.replay import replay
from mirobot_async.virtual import InProcessArm


async def test_a_tape_recorded_at_real_time_replays_equal_with_its_instants(
    profile: str, tmp_path: Path
) -> None:
    path = tmp_path / "session.jsonl"
    with InProcessArm(profile, time_scale=1.0) as virtual:
        async with Mirobot.connect(virtual.url, record=path) as arm:
            await arm.unlock()
            await arm.move_joints(j1=4, j2=2, speed=1200)  # 0.2 s of motion
            await arm.set_pump(1000)
            await arm.status()
    [tape] = read_tapes(path)
    assert tape.header["time_scale"] == 1.0 and tape.header["clock"] == "simulated"
    report = replay(tape, profile)
    assert report.equal, str(report.difference)
    assert report.instants == "loose" and report.lines > 5
    assert abs(report.largest_shift) < 0.25, report.largest_shift  # well within the tolerance
