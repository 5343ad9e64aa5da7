"""Tapes contributed from real arms (``devices/``) replay equal against their family's profile."""

from __future__ import annotations

from known import KNOWN_DIFFERENCES
from tapes import DEVICE_TAPES, tape_files

from mirobot_async._cli.tapes import family_of
from mirobot_async._tapes.format import read_tapes
from mirobot_async._tapes.replay import replay


def test_every_device_tape_replays_equal() -> None:
    assert (DEVICE_TAPES / "README.md").is_file()
    differences = []
    for path in tape_files(DEVICE_TAPES):
        for tape in read_tapes(path):
            report = replay(tape, family_of(tape))
            assert report.lines > 0, f"{path}: {tape.id} compared nothing"
            if not report.equal and tape.id not in KNOWN_DIFFERENCES:
                differences.append(str(report.difference))
    assert not differences, "\n".join(differences)
