"""The firmware's own transmitter, as far as the status report needs it: when a ``?`` is merged.

GRBL prints a status report from its main loop into a small transmit ring and forgets a ``?``
that arrives before that report has been handed to the ring (its request flag is cleared when
the report is done). So a ``?`` that arrives while a report is still being produced gets no
report of its own (oracle, at rest: ``?`` + 124 filtered bytes + ``?`` (12.5 ms) answers one
report of 175 bytes, + 125 bytes two; with a report of 193 bytes the second ``?`` is merged up
to 15.1 ms and answered from 15.2 ms).

Model: a report sampled at ``t`` starts its first byte after :func:`report_compute_seconds`
(or when the bytes already waiting are out, if later), takes :attr:`Transmitter.byte_seconds`
a byte, and its production ends :data:`REPORT_MERGE_TAIL` before its last byte is sent (the
ring still holds that much). The constants put both of the oracle's boundaries above within
the probes' 0.1 ms steps.
ASSUMED: while the arm moves the oracle takes longer before the first byte (2-12 ms, growing
with the step rate: its stepper interrupt takes the processor), so its window is wider than
this one (14-16 ms measured at 30 deg/s); the model does not know that load.

Off (``byte_seconds`` 0, the default) the output leaves at once and every ``?`` is answered:
the right behaviour when the emulator's output is not paced at the arm's baud rate, and at time
scale 0, where simulated time does not pass between two requests.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Final

from ._reports import status_line

if TYPE_CHECKING:
    from ._machine import Machine

ORACLE_BYTE_SECONDS: Final = 93.5e-6
"""The oracle's UART: 93.5 us a byte at 115200 baud (its ``-l`` log), 10.77 bit times."""

REPORT_COMPUTE_AT_REST: Final = 1.62e-3
"""From the sampling of a 175-byte report to its first byte (oracle, ``M50\\n?`` at rest)."""

REPORT_COMPUTE_PER_BYTE: Final = 0.049e-3
"""More compute for a longer report (more digits printed; the oracle's log shows 2.41 ms for a
193-byte one, the merge boundary fits 2.50 ms)."""

REPORT_MERGE_TAIL: Final = 5.40e-3
"""The report is handed to the transmit ring this long before its last byte is sent."""


def report_compute_seconds(length: int) -> float:
    """Seconds from sampling a report of ``length`` bytes (with CR LF) to its first byte."""
    return max(0.0, REPORT_COMPUTE_AT_REST + (length - 175) * REPORT_COMPUTE_PER_BYTE)


class Transmitter:
    """When the bytes the firmware printed leave its UART, and until when a ``?`` is merged."""

    def __init__(self) -> None:
        self.byte_seconds = 0.0
        """Seconds a byte (0: off, every ``?`` answered)."""
        self._free_at = 0.0  # when every byte printed so far has been sent
        self._report_until = 0.0  # a "?" arriving before this is merged into the last report
        self.seen = 0
        """Bytes printed since power-on that the transmitter has queued."""

    def sync(self, printed: int, now: float) -> None:
        """``printed`` bytes since power-on (``Machine.printed``): the new ones were printed at
        ``now`` and queue behind the earlier ones."""
        count = printed - self.seen
        if count:
            self.seen = printed
            if self.byte_seconds:
                self._free_at = max(self._free_at, now) + count * self.byte_seconds

    def print_report(self, m: Machine, now: float, state: str | None = None) -> None:
        """Print the status report of ``m`` sampled at ``now`` (``state``: its state word, else
        the machine's) and time it."""
        self.sync(m.printed, now)
        line = status_line(m, state)
        m.emit(line)
        self.seen = m.printed
        self.report(len(line) + 2, now)

    def report_before_start(self, m: Machine, now: float) -> float:
        """The report a ``?`` during a parse asked for (``m.report_before_start``), printed now
        (none in a critical alarm); seconds until it is produced, which the main loop waits."""
        m.report_before_start = None
        if m.critical:
            return 0.0
        self.print_report(m, now)
        return self.production_left(now)

    def production_left(self, now: float) -> float:
        """Seconds from ``now`` until the last report has been handed to the transmit ring
        (its production blocks the firmware's main loop until then); 0 when unpaced."""
        return max(0.0, self._report_until - now) if self.byte_seconds else 0.0

    def merges(self, now: float) -> bool:
        """Whether a ``?`` arriving at ``now`` is merged into the report being produced."""
        return now < self._report_until

    def report(self, length: int, now: float) -> None:
        """A report of ``length`` bytes (with CR LF) was sampled and printed at ``now``."""
        if not self.byte_seconds:
            return
        start = max(now + report_compute_seconds(length), self._free_at)
        self._free_at = start + length * self.byte_seconds
        self._report_until = self._free_at - REPORT_MERGE_TAIL

    def reset(self) -> None:
        """A soft reset: no report is being produced any more."""
        self._report_until = 0.0
