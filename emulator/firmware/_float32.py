"""The AVR's single-precision numbers where the status report shows them.

The firmware computes in 32-bit IEEE floats (avr-gcc's ``float`` and ``double``). Two places
decide the last printed digit, both checked against the oracle as a black box (3568 status
lines of random joint moves, every angle byte-equal):

* a status angle is its motor step count divided by the steps-per-degree setting, both as
  float32, the quotient rounded to float32 (:func:`step_angle`);
* a number is printed by scaling its float32 magnitude by 100, then by 10, then adding 0.5,
  each step rounded to float32, and cutting the fraction (:func:`print_float`). So
  ``-64.94149780...`` (``-1443`` steps at 22.22) prints ``-64.942``, not ``-64.941``.

The pose is the forward kinematics of the float32 angles computed in double precision, then
rounded to float32 and printed as above. A float32 evaluation of our own FK formula (closed
form, or the modified-DH matrix chain, several orders of operations) agrees *less* often with
the oracle than double precision does (7-9 % of poses differ in one last digit against 7.5 %),
because the firmware's own order of operations is not known: about one pose in thirteen still
differs from the oracle in one last digit.
"""

from __future__ import annotations

import math
import struct
from typing import Final

_SINGLE: Final = struct.Struct("<f")


def single(value: float) -> float:
    """``value`` rounded to the nearest float32 (ties to even), as a Python float.

    A product, quotient, sum or difference of two float32 values computed in double precision
    and then rounded here is the correctly rounded float32 result (53 >= 2 * 24 + 2 bits).
    """
    if not math.isfinite(value) or abs(value) >= 3.4028235677973366e38:
        return value
    unpacked: float = _SINGLE.unpack(_SINGLE.pack(value))[0]
    return unpacked


def step_angle(steps: int, per_unit: float) -> float:
    """The firmware's angle (degrees, rail mm) of ``steps`` motor steps: float32 division."""
    return single(single(float(steps)) / single(per_unit))


def print_float(value: float, decimals: int = 3) -> str:
    """GRBL's number printing on the AVR: float32 magnitude scaled by powers of ten (by 100
    while two or more places remain, then by 10), plus 0.5, truncated; ``-`` when below zero."""
    if not math.isfinite(value):
        return "nan" if value != value else ("-inf" if value < 0 else "inf")
    n = single(abs(value))
    left = decimals
    while left >= 2:
        n = single(n * 100.0)
        left -= 2
    if left:
        n = single(n * 10.0)
    n = single(n + 0.5)
    scaled = int(n)
    if not decimals:
        return f"{'-' if value < 0 else ''}{scaled}."
    whole, frac = divmod(scaled, 10**decimals)
    return f"{'-' if value < 0 else ''}{whole}.{frac:0{decimals}d}"
