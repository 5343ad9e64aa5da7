"""Simulated time: the firmware model driven by the wall clock, scaled.

``simulated = sim_anchor + (wall - wall_anchor) * scale``. A scale of 0 makes motion instant: the
firmware is run until nothing changes by itself after every input line, so a ``?`` written right
after a move sees it done. The scale can change while running (the anchors move so that
simulated time stays continuous).
"""

from __future__ import annotations

import itertools
import math
import re
import time
from collections import deque
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .options import FirmwareLike

__all__ = ["MOTION_END_HISTORY", "Simulation"]

MOTION_END_HISTORY = 64  # ends of motion answered to the ``motion-ends`` control command
UART_BIT_TIMES_PER_BYTE = 10.77  # the oracle's UART: 93.5 us a byte at 115200 baud
_LINE_PIECES = re.compile(rb"[^\r\n]*[\r\n]|[^\r\n]+")  # input cut after each line end
_LINE_END_BYTES = b"\r\n"


class Simulation:
    """A firmware model and its clock; ``wall`` arguments are ``time.monotonic()`` readings.

    :attr:`motion_end_walls` keeps the wall-clock instants (oldest first) at which the
    firmware's planner went from busy to empty: the firmware's simulated end instants mapped
    through the clock in force during the run (exact to the float); at scale 0 motion has no
    duration and the instant is when the loop ran it.
    """

    def __init__(
        self, firmware: FirmwareLike, scale: float, wall: float, baud: int | None = None
    ) -> None:
        self.firmware = firmware
        self._scale = scale
        self._baud = baud
        self._wall_anchor = wall
        self._sim_anchor = firmware.now
        self.motion_end_walls: deque[float] = deque(maxlen=MOTION_END_HISTORY)
        self._motion_ends_seen = 0
        self._pace_uart()

    def _pace_uart(self) -> None:
        """Tell the firmware its transmitter's byte time when its output is paced at ``baud``
        and time runs at least as fast as the wall clock (then a ``?`` that arrives while a
        report is being printed is merged into it, as on the arm); else 0: every ``?`` is
        answered (unpaced output leaves at once; below scale 1 a client reads a report later,
        in simulated time, than the arm's output would let it). ``firmware.uart`` is optional."""
        uart = getattr(self.firmware, "uart", None)
        if uart is None:
            return
        paced = self._baud is not None and self._scale >= 1.0
        uart.byte_seconds = UART_BIT_TIMES_PER_BYTE / self._baud if paced and self._baud else 0.0

    @property
    def scale(self) -> float:
        """Simulated seconds per wall second (0: motion completes at once)."""
        return self._scale

    def set_scale(self, scale: float, wall: float) -> None:
        """Change the speed from ``wall`` on; the simulated time so far is kept."""
        self.sync(wall)
        self._sim_anchor = self.firmware.now
        self._wall_anchor = wall
        self._scale = scale
        self._pace_uart()

    def sync(self, wall: float) -> None:
        """Run the firmware up to the simulated time of ``wall`` (scale 0: until idle)."""
        fw = self.firmware
        if self._scale > 0:
            target = self._sim_anchor + (wall - self._wall_anchor) * self._scale
            if target > fw.now:
                fw.advance(target - fw.now)
                self._collect_motion_ends(wall)
        else:
            self.run_to_idle()

    def run_to_idle(self) -> None:
        """Scale 0: run the firmware until nothing changes by itself (motion done)."""
        fw = self.firmware
        if fw.next_deadline() is not None:
            fw.advance(math.inf)  # the firmware's "until nothing changes"; its clock stays finite
            self._collect_motion_ends(time.monotonic())

    def deliver(self, data: bytes, crossed: float | None, wall: float) -> None:
        """Run to ``wall`` with ``data`` fed on the way: at ``crossed`` (when its first byte
        crossed a paced wire), however late the loop woke, so that a loaded machine does not
        squeeze the gaps between paced bytes; else (unpaced) at ``wall``."""
        if data and crossed is not None and crossed < wall:
            self.sync(crossed)
            self.feed(data)
            self.sync(wall)
        else:
            self.sync(wall)
            self.feed(data)

    def feed(self, data: bytes) -> None:
        """Bytes that reached the firmware; at scale 0 each line's motion ends before the next."""
        if not data:
            return
        if self._scale == 0:
            ends = data.count(b"\n") + data.count(b"\r")
            # one line (or none) ending the data: the one piece the pattern would find
            single = ends == 0 or (ends == 1 and data[-1] in _LINE_END_BYTES)
            for piece in (data,) if single else _LINE_PIECES.findall(data):
                self.firmware.receive(piece)
                self.run_to_idle()
        else:
            self.firmware.receive(data)

    def next_wall_deadline(self) -> float | None:
        """Wall-clock time of the firmware's next change by itself (None: none, or scale 0)."""
        if self._scale <= 0:
            return None
        deadline = self.firmware.next_deadline()
        if deadline is None:
            return None
        return self._wall_anchor + (deadline - self._sim_anchor) / self._scale

    def _collect_motion_ends(self, wall: float) -> None:
        """Map the firmware's new ends of motion (simulated) to wall time; ``wall`` is now.

        Called right after each ``advance``, before the anchors can change, so the mapping in
        force during the run is the one used.
        """
        fw = self.firmware
        total = getattr(fw, "motion_ends", None)
        ends = getattr(fw, "motion_end_times", None)  # optional: not part of FirmwareLike
        if ends is None or not isinstance(total, int):
            return
        if total < self._motion_ends_seen:  # a new firmware object
            self._motion_ends_seen = 0
        new = min(total - self._motion_ends_seen, len(ends))
        self._motion_ends_seen = total
        if new <= 0:
            return
        if not self._scale > 0:  # motion has no duration: every end is now
            self.motion_end_walls.extend(itertools.repeat(wall, new))
            return
        for sim in (ends[-1],) if new == 1 else itertools.islice(ends, len(ends) - new, None):
            self.motion_end_walls.append(
                self._wall_anchor + (float(sim) - self._sim_anchor) / self._scale
            )
