"""Where a suspect firmware tape stops being evidence.

The firmware's tapes were recorded in a simulator with two known artefacts (their README): a torn
read of a 32-bit position that pressed a range switch no arm would, and an EEPROM model that keeps
bytes a real erase clears. A tape whose header names one (``suspect``) is compared up to it.
"""

from __future__ import annotations

from mirobot_async._tapes.format import Marker, Printed, Tape

EEPROM_ARTEFACT = b"error: EEPROM read fail"


def artefact_instant(tape: Tape) -> float | None:
    """Where a suspect tape stops being evidence (its README: compare up to the artefact): the
    torn switch read, or the line the simulator's EEPROM model made the firmware print."""
    if tape.suspect is None:
        return None
    for event in tape.events:
        torn = isinstance(event, Marker) and event.kind == "switch" and event.fields.get("torn")
        if tape.suspect == "torn-switch-read" and torn:
            return event.t - 1e-7
        eeprom = isinstance(event, Printed) and event.data.startswith(EEPROM_ARTEFACT)
        if tape.suspect == "eeprom-write-model" and eeprom and isinstance(event, Printed):
            return event.start - 1e-7
    return 0.0  # an artefact of an unknown kind: nothing on the tape is evidence
