"""The tapes the suite replays: the firmware's (``firmware/``, a copy of ../shared/firmware-tapes)
and contributed device tapes (``devices/``), indexed once per test process.

A tape is loaded only when its test runs (:func:`load`): the index reads every header, and each
test parses its own tape's events.
"""

from __future__ import annotations

import functools
from pathlib import Path

from mirobot_async._tapes.format import Tape, TapeText, split_tapes

HERE = Path(__file__).resolve().parent
FIRMWARE_TAPES = HERE / "firmware"
DEVICE_TAPES = HERE / "devices"
SHARED_TAPES = HERE.parents[2] / "shared" / "firmware-tapes"
"""Where new firmware tapes arrive (next to the repository in the workplace and in CI)."""

TAPE_SUFFIXES = (".jsonl", ".jsonl.gz")


def tape_files(folder: Path) -> list[Path]:
    """The tape files of a folder, sorted."""
    return sorted(p for p in folder.iterdir() if p.name.endswith(TAPE_SUFFIXES))


@functools.cache
def index(folder: Path = FIRMWARE_TAPES) -> dict[str, TapeText]:
    """Every tape of the folder's files by id (headers read, events not yet parsed)."""
    found: dict[str, TapeText] = {}
    for path in tape_files(folder):
        for text in split_tapes(path):
            assert text.id not in found, f"tape id {text.id!r} twice ({path})"
            found[text.id] = text
    return found


def load(tape_id: str, folder: Path = FIRMWARE_TAPES) -> Tape:
    """The tape ``tape_id`` with its events."""
    return index(folder)[tape_id].parse()
