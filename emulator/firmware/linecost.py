"""How long the firmware takes to parse and plan one received line (simulated seconds).

Measured on the oracle (the classic firmware on a simulated 16 MHz ATmega2560, ``-s 0`` with
``-l`` logs; bursts of identical lines already in the receive ring, ``ok`` to ``ok``):

==========================  ======  ========
line (bytes with ``\\n``)    gap ms  model ms
==========================  ======  ========
``G90`` / ``M21`` (4)        0.40    0.40
``G90 G21 G17 G94`` (16)     1.60    1.60
``G90`` + 16 spaces (20)     2.00    2.00
``X0`` joint mode (3)        0.66    1.43
``X0.1`` joint mode (5)      1.43    1.63
``M20`` (4)                  7.09    7.10
``X0`` Cartesian mode (3)    5.43    6.17
``X0.1`` Cartesian mode (5)  6.43    6.40
``M20 G91 G1 X0.1`` (16)     12.70   12.70
``M20 G90 G1 X.. Y.. Z160``  14.6    14.4
==========================  ======  ========

(``X0`` is a move of nothing: the oracle plans no block, the textual model cannot tell.)
So about 100 us per received byte (spaces too) plus the work of its words: the ``M20`` word
(the parser's position from the machine's, forward kinematics in float), a Cartesian target
(inverse kinematics), a joint target and a planned block. The 2021 firmware is the same code
base on the same MCU (ASSUMED the same costs). The ``ok`` and the next line wait for it; the
realtime bytes act at once, except that a ``?`` is answered right after the line's reply (GRBL
reports between lines).
"""

from __future__ import annotations

import re
from typing import Final

BYTE_SECONDS: Final = 100e-6
"""Per received byte of the line, its line end and ignored bytes included."""

RESYNC_SECONDS: Final = 6.7e-3
"""The ``M20`` word: the parser's position from the machine's (forward kinematics)."""

CARTESIAN_TARGET_SECONDS: Final = 5.1e-3
"""A Cartesian target in a line without ``M20`` (inverse kinematics)."""

CARTESIAN_TARGET_AFTER_RESYNC_SECONDS: Final = 3.6e-3
"""A Cartesian target in a line with ``M20`` (measured: 12.7 ms for ``M20 G91 G1 X0.1``)."""

JOINT_TARGET_SECONDS: Final = 0.36e-3
"""A joint-space target (axis words in joint mode)."""

BLOCK_SECONDS: Final = 0.77e-3
"""Planning a block (a target that moves; ASSUMED for every motion line with axis words)."""

_M20: Final = re.compile(r"M0*20(?![0-9.])")
_M21: Final = re.compile(r"M0*21(?![0-9.])")
_AXIS: Final = re.compile(r"[XYZABC]")
_NON_MOTION: Final = re.compile(r"G0*(?:4|10|28|30|53|92)(?![0-9])")


def line_seconds(text: str, raw: int, cartesian_mode: bool) -> float:
    """Parse time of the filtered line ``text`` that took ``raw`` received bytes, with the
    parser in Cartesian mode (``M20``) or not. A cheap textual estimate, not a second parser:
    a line the parser refuses costs what its words would."""
    seconds = raw * BYTE_SECONDS
    if not text or text[0] == "$":
        return seconds
    resync = _M20.search(text) is not None
    if resync:
        seconds += RESYNC_SECONDS
        cartesian_mode = True
    elif _M21.search(text) is not None:
        cartesian_mode = False
    if _AXIS.search(text) is None or _NON_MOTION.search(text) is not None:
        return seconds
    if cartesian_mode:
        seconds += CARTESIAN_TARGET_AFTER_RESYNC_SECONDS if resync else CARTESIAN_TARGET_SECONDS
    else:
        seconds += JOINT_TARGET_SECONDS
    return seconds + BLOCK_SECONDS
