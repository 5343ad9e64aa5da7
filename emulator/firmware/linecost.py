"""How long the firmware takes to parse and plan one received line (simulated seconds).

Measured on the oracle (the classic firmware on a simulated 16 MHz ATmega2560, ``-s 0`` with
``-l`` logs; bursts of identical lines written at once, ``ok`` to ``ok``). Bytes arrive one
every 100 us (:mod:`.wire`), so short lines are paced by the wire and the parse of a line
overlaps the arrival of the next:

===============================  ======  ===========================
line (bytes with ``\\n``)         gap ms  model ms (wire, parse)
===============================  ======  ===========================
``G90`` / ``M21`` (4)             0.40    0.40 (wire; parse 0.20)
``G90 G21 G17 G94`` (16)          1.60    1.60 (wire)
``G90`` + 16 spaces (20)          2.00    2.00 (wire)
``M21 G91 G1 X0.1`` (16)          1.54    1.60 (wire; parse 1.45)
``X0.1`` joint mode (5)           1.43    1.45
``X0`` joint mode (3)             0.66    1.45 (a move of nothing)
``M20`` (4)                       7.09    7.00
``X0.1`` Cartesian mode (5)       6.43    7.30
``X250.000 Y0.000`` Cartesian     7.3     7.30
``M20 G91 G1 X0.1`` (16)          12.70   14.10
``M20 G90 G1 X.. Y.. Z160`` (33)  14.6    14.10
===============================  ======  ===========================

The work is in the words: the ``M20`` word (the parser's position from the machine's, forward
kinematics in float), a Cartesian target (inverse kinematics: slower for general poses than
near the start pose, the model takes the general case), a joint target, a planned block. The
2021 firmware is the same code base on the same MCU (ASSUMED the same costs). The line's
effects, its ``ok`` and the next line wait for it; a ``?`` meanwhile is answered right after
the line's reply (GRBL reports between lines), or, when it came before the line's wait for
queued motion (:data:`WAIT_POINT_SECONDS`), at that wait, before the queued blocks start
(``Idle``: GRBL reports before it starts a cycle); the other realtime bytes act at once.
"""

from __future__ import annotations

import functools
import re
from typing import Final

LINE_SECONDS: Final = 0.2e-3
"""Any line (``G90`` lines come one per 0.4 ms, as fast as their bytes)."""

RESYNC_SECONDS: Final = 6.8e-3
"""The ``M20`` word: the parser's position from the machine's (forward kinematics)."""

WAIT_POINT_SECONDS: Final = LINE_SECONDS
"""A line that waits for queued motion reaches its wait this long after its parse began, before
its target's work (oracle, behind a move: a ``?`` up to 0.1-0.3 ms after the move's ``ok`` finds
the move not started for ``M5``, ``M4 E65``, ``M4 E40 S500``; 1.3 ms after it, the move
runs for ``M21 G90 X5 M3 S1000``, whose whole parse is 1.45 ms here)."""

CARTESIAN_TARGET_SECONDS: Final = 6.3e-3
"""A Cartesian target (inverse kinematics of a general pose)."""

JOINT_TARGET_SECONDS: Final = 0.45e-3
"""A joint-space target (axis words in joint mode)."""

BLOCK_SECONDS: Final = 0.8e-3
"""Planning a block (ASSUMED for every motion line with axis words)."""

_M20: Final = re.compile(r"M0*20(?![0-9.])")
_M21: Final = re.compile(r"M0*21(?![0-9.])")
_AXIS: Final = re.compile(r"[XYZABC]")
_NON_MOTION: Final = re.compile(r"G0*(?:4|10|28|30|53|92)(?![0-9])")


@functools.lru_cache(maxsize=1024)
def line_seconds(text: str, cartesian_mode: bool) -> float:
    """Parse time of the filtered line ``text`` with the parser in Cartesian mode (``M20``) or
    not. A cheap textual estimate, not a second parser: a refused line costs what its words
    would."""
    seconds = LINE_SECONDS
    if not text or text[0] == "$":
        return seconds
    if _M20.search(text) is not None:
        seconds += RESYNC_SECONDS
        cartesian_mode = True
    elif _M21.search(text) is not None:
        cartesian_mode = False
    if _AXIS.search(text) is None or _NON_MOTION.search(text) is not None:
        return seconds
    target = CARTESIAN_TARGET_SECONDS if cartesian_mode else JOINT_TARGET_SECONDS
    return seconds + target + BLOCK_SECONDS
