"""What the script view knows of a script's lines: the path predicted for each line written,
the lines refused (by the firmware, or by the client before a byte was written), alarms and
resets, as they happen. Pure (numpy): :mod:`~mirobot_async._view.watch` feeds it the
connection's facts and draws it.

The path is predicted line by line as the lines are written (pipelined: ahead of the arm),
each from where the lines before it leave the arm, with the modes and the base offset the
client knows before the line (:func:`~mirobot_async._view.preview.predict_line`). It starts at
the first status that shows the arm at rest with nothing in flight. A refused line moves
nothing: when it was the last line written the path goes on from before it; otherwise (the
lines after it were predicted from its end), and after an alarm, a reset or a line it cannot
predict (a mode or the position unknown), the path stops and starts again at the next such
status. Lines written meanwhile are counted, not drawn.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace
from typing import Final

import numpy as np

from mirobot_async._core.line import ParsedLine
from mirobot_async._core.modal import MotionModes
from mirobot_async._safety.envelope import Envelope
from mirobot_async._safety.paths import FloatArray
from mirobot_async._safety.prediction import MachineState
from mirobot_async._urdf import dh_of
from mirobot_async._view.preview import PathSegment, predict_line
from mirobot_async.kinematics import Joints, forward

__all__ = ["MAX_PATH_POINTS", "Marker", "ScriptEvent", "ScriptLines"]

MAX_PATH_POINTS: Final = 60_000
"""Points of predicted path kept (the oldest lines' paths are dropped beyond)."""
_EVENTS_KEPT: Final = 200
_MARKERS_KEPT: Final = 50
_PENDING_KEPT: Final = 4096
"""Lines awaiting their reply that are remembered (a reset may leave some never answered)."""


@dataclass(frozen=True, slots=True)
class ScriptEvent:
    """Something the page lists: ``t`` seconds after the view opened; ``kind`` is
    ``refused`` (``ok`` but the firmware dropped the motion), ``error`` (an error reply),
    ``not sent`` (refused by the client: nothing written), ``alarm`` or ``reset``."""

    t: float
    kind: str
    text: str


@dataclass(frozen=True, slots=True)
class Marker:
    """A red marker: line ``number`` was refused here (mm, base frame)."""

    number: int
    point: tuple[float, float, float]
    label: str


class ScriptLines:
    """The script's lines as the view follows them (see the module)."""

    def __init__(self, firmware: str, envelope: Envelope | None = None) -> None:
        self.firmware = firmware
        self.model = envelope if envelope is not None else Envelope(dh=dh_of(firmware))
        self.state = MachineState(modes=MotionModes.unknown(), firmware=firmware)
        self.segments: deque[PathSegment] = deque()
        self.points = 0
        self.events: deque[ScriptEvent] = deque(maxlen=_EVENTS_KEPT)
        self.markers: deque[Marker] = deque(maxlen=_MARKERS_KEPT)
        self.count_written = 0
        self.count_answered = 0
        self.count_failed = 0
        """Lines refused or rejected by the firmware, or not sent by the client."""
        self.undrawn = 0
        """Lines written while the path was unknown (not drawn)."""
        self.version = 0
        """Changes whenever something drawn changed (the view redraws then)."""
        self._pending: dict[int, tuple[int, MachineState]] = {}

    @property
    def predicting(self) -> bool:
        """Whether the next line written is drawn (the arm's end position is known)."""
        return self.state.joints is not None

    # ---- the connection's facts -------------------------------------------------------------

    def at_rest(self, joints: Joints) -> None:
        """A status shows the arm at rest at ``joints`` with nothing in flight: the path starts
        there if it was unknown."""
        if self.state.joints is None:
            self.state = replace(self.state, joints=joints, pose=None, parser=None)

    def written(
        self,
        key: int,
        parsed: ParsedLine,
        text: str,
        modes: MotionModes,
        base_offset: tuple[float, float, float] | None,
    ) -> int:
        """Line ``text`` was written (``key`` names it until :meth:`answered`); its number."""
        self.count_written += 1
        number = self.count_written
        offset = (0.0, 0.0, 0.0) if self.firmware == "classic" else base_offset
        before = replace(self.state, modes=modes, base_offset=offset)
        if len(self._pending) >= _PENDING_KEPT:
            self._pending.clear()
        self._pending[key] = (number, before)
        if before.joints is None:
            self.state = before
            if parsed.is_homing:  # homing ends at zero: known again
                self.state = replace(before, joints=(0.0,) * 6, pose=None, parser=None)
            elif parsed.may_move:
                self.undrawn += 1
            return number
        step = predict_line(self.model, number, parsed, text, before)
        self.state = step.state  # a line the model cannot follow (beyond the joints' range):
        # the path stops here; the firmware's reply says what it did
        for segment in step.segments:
            self._add(segment)
        return number

    def answered(
        self, key: int, text: str, t: float, *, refused: str | None = None, error: str | None = None
    ) -> None:
        """Line ``key`` was answered: ``ok`` (``refused``: the firmware's text when it dropped
        the motion anyway) or an error reply (``error``: its text)."""
        number, before = self._pending.pop(key, (0, None))
        self.count_answered += 1
        failure = error if error is not None else refused
        if failure is None:
            return
        self.count_failed += 1
        kind = "error" if error is not None else "refused"
        self.events.append(ScriptEvent(t, kind, f"line {number} `{text}`: {failure}"))
        start = None if before is None else self._tool_point(before)
        if start is not None:
            self.markers.append(Marker(number, start, f"line {number}"))
        if before is not None and number == self.count_written:
            self.state = before  # the last line written moved nothing: the arm ends as before
            self.version += 1
        else:  # lines after it were predicted from where it would have ended
            self.forget()

    def not_sent(self, text: str, reason: str, t: float) -> None:
        """Line ``text`` was refused by the client: nothing of it was written."""
        self.count_failed += 1
        self.events.append(ScriptEvent(t, "not sent", f"`{text}`: {reason}"))
        point = self._tool_point(self.state)
        if point is not None:
            self.markers.append(Marker(self.count_written + 1, point, "not sent"))
        self.version += 1

    def alarm(self, text: str, t: float) -> None:
        self.events.append(ScriptEvent(t, "alarm", text))
        self.forget()

    def reset(self, t: float) -> None:
        self.events.append(ScriptEvent(t, "reset", "the arm reset"))
        self.forget()

    def forget(self) -> None:
        """Where the arm ends is no longer known (until it is seen at rest)."""
        self.state = replace(self.state, joints=None, pose=None, parser=None)
        self.version += 1

    # ---- for drawing ----------------------------------------------------------------------

    def path(self) -> list[PathSegment]:
        """The predicted path kept (oldest first)."""
        return list(self.segments)

    def describe(self, ended: str | None) -> str:
        """The panel's script block (Markdown); ``ended``: how the script ended, if it did."""
        head = "**Script: running**" if ended is None else f"**Script: {ended}**"
        written = self.count_written
        counts = (
            f"{written} line{'' if written == 1 else 's'} written, {self.count_answered} "
            f"answered, {self.count_failed} refused"
            + (f", {self.undrawn} not drawn (position unknown)" if self.undrawn else "")
        )
        shown = list(self.events)[-8:]
        rows = "\n".join(f"- {e.t:.2f} s **{e.kind}**: {e.text}" for e in shown)
        listed = f"**Events ({len(self.events)}):**\n{rows}" if shown else "*No refusals.*"
        return f"{head}  \n{counts}\n\n{listed}"

    # ---- inside -----------------------------------------------------------------------------

    def _add(self, segment: PathSegment) -> None:
        self.segments.append(segment)
        self.points += len(segment.points)
        while self.points > MAX_PATH_POINTS and len(self.segments) > 1:
            self.points -= len(self.segments.popleft().points)
        self.version += 1

    def _tool_point(self, state: MachineState) -> tuple[float, float, float] | None:
        if state.joints is None:
            return None
        point: FloatArray = np.asarray(forward(state.joints, self.model.dh, self.model.tool))
        return (float(point[0]), float(point[1]), float(point[2]))
