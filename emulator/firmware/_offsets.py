"""Work coordinates (GRBL 0.9j as the oracle runs it): ``G54..G59`` offsets set by ``G10 L2`` /
``G10 L20``, the ``G92`` offset, the ``G28``/``G30`` positions (``G28.1``/``G30.1``) and ``$#``.

Everything is indexed like the axis words ``X Y Z A B C D`` (:data:`scanner.AXIS_WORDS`): joints
J1..J6 and the rail in ``M21``, pose components in ``M20``. ASSUMED: the offsets add to absolute
targets in both modes, as GRBL adds them before the Mirobot's kinematics.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Final

from ..motion import Vec7
from ..settings import grbl_float
from ._scanner import AXIS_WORDS

ZERO7: Final[Vec7] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
_REPORT_ORDER: Final = "ABCDXYZ"  # $# prints the firmware's axis order a..g


def _zeros() -> dict[int, Vec7]:
    return {n: ZERO7 for n in range(54, 60)}


@dataclass
class WorkOffsets:
    """The stored coordinate data (GRBL keeps it in EEPROM: it survives a reset)."""

    systems: dict[int, Vec7] = field(default_factory=_zeros)
    g28: Vec7 = ZERO7
    g30: Vec7 = ZERO7

    def report(self, g92: Vec7) -> list[str]:
        """The lines of ``$#`` (the tool length offset and the probe are always zero)."""

        def row(values: Vec7) -> str:
            return ",".join(
                grbl_float(values[AXIS_WORDS.index(letter)]) for letter in _REPORT_ORDER
            )

        lines = [f"[G{n}:{row(self.systems[n])}]" for n in range(54, 60)]
        lines += [f"[G28:{row(self.g28)}]", f"[G30:{row(self.g30)}]", f"[G92:{row(g92)}]"]
        zeros = row(ZERO7)
        return [*lines, "[TLO:0.000]", f"[PRB:{zeros}:0]"]


def with_values(base: Vec7, values: dict[int, float]) -> Vec7:
    """``base`` with the components ``values`` (index -> value) replaced."""
    out = list(base)
    for k, v in values.items():
        out[k] = v
    return (out[0], out[1], out[2], out[3], out[4], out[5], out[6])
