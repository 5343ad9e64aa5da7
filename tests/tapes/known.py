"""Firmware tapes on which the emulator is known to differ, each with its reason and evidence.

Key: the tape id; value: why the emulator's classic model differs at the tape's first
difference. Each listed tape must still differ (a fix that makes it equal fails the suite until
its entry goes). Never list field-binary texts here (those are ``mirobot_async._tapes.fieldtexts``),
and never loosen a tolerance instead of listing a tape.
"""

from __future__ import annotations

KNOWN_DIFFERENCES: dict[str, str] = {}
