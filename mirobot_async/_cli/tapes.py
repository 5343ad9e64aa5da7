"""``mirobot replay``: replay tapes against the emulator and say, per tape, equal or where not."""

from __future__ import annotations

import argparse
import json
from typing import Any

from mirobot_async._cli.exits import EXIT_FAILED, EXIT_OK, EXIT_USAGE, note
from mirobot_async._tapes.artefacts import artefact_instant
from mirobot_async._tapes.format import Tape, split_tapes
from mirobot_async._tapes.replay import ReplayReport, replay
from mirobot_async.errors import TapeFormatError

__all__ = ["cmd_replay", "family_of"]

FIRMWARE_TAPE_FAMILY = {"20191228_2": "classic"}
"""The vendor firmware revisions of the firmware's tapes, by the family that runs them."""


def family_of(tape: Tape) -> str:
    """The firmware family a tape was recorded on: its header's ``family`` (recorded tapes) or
    the family of its firmware revision (the firmware's tapes); classic when neither says."""
    family = tape.header.get("family")
    if isinstance(family, str) and family:
        return family
    return FIRMWARE_TAPE_FAMILY.get(str(tape.header.get("firmware", "")), "classic")


def _describe(report: ReplayReport, stop_at: float | None) -> str:
    scope = "" if stop_at is None else f" (compared up to its artefact at {stop_at:.4f})"
    counts = f"{report.lines} lines, {report.statuses} statuses"
    loose = {
        "exact": "",
        "loose": "; instants compared loosely (a recorded tape)",
        "none": "; instants not compared (a virtual arm not at time scale 1)",
    }[report.instants]
    if report.equal:
        return f"equal: {report.tape} [{report.firmware}] {counts}{scope}{loose}"
    return f"DIFFERS: {report.difference} [{report.firmware}] after {counts}{scope}{loose}"


def _as_json(report: ReplayReport, path: str, stop_at: float | None) -> dict[str, Any]:
    record: dict[str, Any] = {
        "file": path,
        "tape": report.tape,
        "firmware": report.firmware,
        "equal": report.equal,
        "lines": report.lines,
        "statuses": report.statuses,
        "instants": report.instants,
        "largest_shift_s": round(report.largest_shift, 7),
        "largest_status_steps": report.largest_steps,
    }
    if stop_at is not None:
        record["compared_until"] = stop_at
    difference = report.difference
    if difference is not None:
        record["difference"] = {
            "event": difference.event,
            "firmware": None
            if difference.firmware is None
            else difference.firmware.decode("latin-1"),
            "firmware_t": difference.firmware_t,
            "emulator": None
            if difference.emulator is None
            else difference.emulator.decode("latin-1"),
            "emulator_t": difference.emulator_t,
            "why": difference.why,
            "text": str(difference),
        }
    return record


def cmd_replay(args: argparse.Namespace) -> int:
    """``mirobot replay TAPE...``: exit 0 every tape equal, 1 a difference, 2 a bad tape."""
    equal = differ = 0
    for path in args.tapes:
        try:
            texts = split_tapes(path)
            tapes = [text.parse() for text in texts]
        except TapeFormatError as err:
            note(str(err))
            return EXIT_USAGE
        for tape in tapes:
            stop_at = artefact_instant(tape)
            report = replay(tape, args.firmware or family_of(tape), stop_at=stop_at)
            equal += report.equal
            differ += not report.equal
            if args.json:
                print(json.dumps(_as_json(report, str(path), stop_at)), flush=True)
            else:
                print(_describe(report, stop_at), flush=True)
    if not args.json:
        note(f"{equal} equal, {differ} differ")
    return EXIT_OK if differ == 0 else EXIT_FAILED
