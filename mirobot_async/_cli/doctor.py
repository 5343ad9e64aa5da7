"""``mirobot doctor``: probe an arm without moving it, record the probe as a tape, and say where the
arm answers otherwise than the emulator's profile for its family.

The probe: the banner (seen when opening the port resets the arm), ``?``, ``$$``, ``$I``, lines
every firmware refuses without effect, and, when the arm has just powered on (its axes are then
locked) or in an alarm, a zero-length relative joint move that a locked arm refuses and an
unlocked one would not move for. ``--motion`` adds homing and small joint moves, after a prompt
on a terminal.
"""

from __future__ import annotations

import argparse
import datetime
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Final

from mirobot_async._cli.exits import EXIT_FAILED, EXIT_OK, CliError, note
from mirobot_async._cli.session import open_robot
from mirobot_async._cli.tapes import family_of
from mirobot_async._tapes.format import read_tapes
from mirobot_async._tapes.replay import replay, transcript_differences
from mirobot_async.errors import MirobotCommandError, MirobotError

if TYPE_CHECKING:
    from mirobot_async._client.client import Mirobot

__all__ = ["PROBE", "cmd_doctor"]

PROBE: Final = ("?", "$$", "$I", "G99", "M99", "$3")
"""Asked of every arm: a status, the settings, the build line, then three lines every firmware
refuses without effect (an unknown G code, an unknown M code, an unknown ``$`` statement)."""

LOCKED_PROBE: Final = ("M21 G91 X0", "G90")
"""After a power-on (axes locked): a joint move of zero length, refused by a locked arm and moving
nothing on an unlocked one, then absolute distances back (the power-on mode)."""

MOTION: Final = ("$H", "M21 G90 G1 X10 F1000", "M21 G90 G1 X0 Y5 F1000", "M21 G90 G1 Y0 F1000")
"""``--motion``: homing, then J1 to 10 degrees and back, J2 to 5 and back, then a status."""

MOTION_WARNING: Final = (
    "--motion homes the arm and moves J1 by 10 and J2 by 5 degrees: clear its reach first."
)


def _default_tape() -> Path:
    """``mirobot-doctor-<UTC time>.jsonl`` in the current folder, never one that exists."""
    stamp = datetime.datetime.now(datetime.UTC).strftime("%Y%m%d-%H%M%S")
    path = Path(f"mirobot-doctor-{stamp}.jsonl")
    count = 1
    while path.exists():
        count += 1
        path = Path(f"mirobot-doctor-{stamp}-{count}.jsonl")
    return path


def _confirm_motion(args: argparse.Namespace) -> None:
    if args.yes:
        return
    if not sys.stdin.isatty():
        raise CliError(f"{MOTION_WARNING} Not a terminal: pass --yes to go ahead")
    answer = input(f"{MOTION_WARNING} Go ahead? [y/N] ")
    if answer.strip().lower() not in ("y", "yes"):
        raise CliError("doctor --motion: not confirmed; nothing was moved")


async def _ask(arm: Mirobot, line: str, out: list[str]) -> None:
    """One probe line, its outcome noted; a refusal is an answer like any other."""
    try:
        if line == "?":
            status = await arm.status()
            out.append(f"{line} -> {status.state.value}")
            return
        lines = await arm.send(line, validate=False, check_envelope=False)
        out.append(f"{line} -> {len(lines)} line(s), ok")
    except MirobotCommandError as err:
        out.append(f"{line} -> refused: {err}")


async def _probe(arm: Mirobot, args: argparse.Namespace, out: list[str]) -> str | None:
    for line in PROBE:
        await _ask(arm, line, out)
    alarm = arm.last_status is not None and arm.last_status.state.value == "Alarm"
    if arm.banner is not None or alarm:  # just powered on, or locked by an alarm
        for line in LOCKED_PROBE:
            await _ask(arm, line, out)
    else:
        out.append("no power-on banner, no alarm: the locked-move probe was not sent")
    if args.motion:
        for line in MOTION:
            await _ask(arm, line, out)
        await arm.wait_idle()
        await _ask(arm, "?", out)
    return arm.firmware


async def cmd_doctor(args: argparse.Namespace) -> int:
    """``mirobot doctor``: exit 0 the arm answered as the profile does, 1 where it did not."""
    if args.motion:
        _confirm_motion(args)
    path = Path(args.record) if args.record else _default_tape()
    args.record = str(path)
    steps: list[str] = []
    try:
        async with open_robot(args) as arm:
            detected = await _probe(arm, args, steps)
    except MirobotError as err:
        note(f"doctor: the probe stopped: {err}")
        note(f"the tape so far: {path}")
        raise
    for step in steps:
        print(f"  {step}")
    tapes = list(read_tapes(path))
    tape = tapes[-1]
    against = args.against or detected or family_of(tape)
    report = replay(tape, against)
    differences = transcript_differences(report)
    print(f"firmware family: {detected or 'unknown'} ({tape.header.get('family_evidence', '-')})")
    print(f"tape: {path} ({len(tape.events)} events)")
    if report.instants == "loose":
        print("instants compared loosely (a recorded tape's carry the USB latency)")
    elif report.instants == "none":
        print("instants not compared (a virtual arm faster than real time)")
    if not differences:
        print(f"no difference from the emulator's {against} profile")
        return EXIT_OK
    print(f"{len(differences)} difference(s) from the emulator's {against} profile:")
    for difference in differences:
        print(f"  {difference}")
    print(f"attach {path} to a report: docs/tapes.md says how")
    return EXIT_FAILED
