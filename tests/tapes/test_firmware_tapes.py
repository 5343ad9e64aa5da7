"""The emulator replays every firmware tape equal: the vendor's classic firmware, recorded.

Each tape of ``firmware/`` is replayed into the emulator's classic model in process, at simulated
time, one byte at its instant (``mirobot_async._tapes.replay``). Every output line is compared
byte for byte; a status line taken while the arm moves may differ by up to
``STATUS_STEP_TOLERANCE`` motor steps of an axis (the firmware's report takes 2-12 ms to compute
under stepper load, which the model does not know); every line's first byte must come within
``INSTANT_TOLERANCE`` of the firmware's. Suspect tapes (simulator artefacts) are compared up to
the artefact. Tapes in ``known.KNOWN_DIFFERENCES`` must still differ, for the reason listed.
"""

from __future__ import annotations

import pytest
from known import KNOWN_DIFFERENCES
from tapes import index, load

from mirobot_async._tapes.artefacts import artefact_instant
from mirobot_async._tapes.replay import replay

TAPE_IDS = sorted(index())


def test_the_firmware_tapes_are_all_there() -> None:
    assert len(TAPE_IDS) == 585
    assert set(KNOWN_DIFFERENCES) <= set(TAPE_IDS), set(KNOWN_DIFFERENCES) - set(TAPE_IDS)


@pytest.mark.parametrize("tape_id", TAPE_IDS)
def test_the_emulator_replays_the_tape_equal(tape_id: str) -> None:
    tape = load(tape_id)
    report = replay(tape, "classic", stop_at=artefact_instant(tape))
    known = KNOWN_DIFFERENCES.get(tape_id)
    if known is None:
        assert report.equal, str(report.difference)
    else:
        assert not report.equal, f"{tape_id} now replays equal: remove it from known.py"
        assert report.lines > 0, f"{tape_id}: nothing compared before the difference"
