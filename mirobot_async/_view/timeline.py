"""What happened, by time: the samples of a run (a trace or a tape) and its events, for
``mirobot view --replay``'s slider.

A :class:`Timeline` holds the status samples the arm reported (time from the first sample, in
seconds: the robot's time for a trace, the tape's clock for a tape) and the events (outputs,
refusals, alarms, holds). At an instant ``t`` the arm is shown as its last report at or before
``t`` (no interpolation: what the arm said, not a guess), the path is the tool positions reported
up to ``t``, the events those seen up to ``t``. Sources: a trace CSV (``mirobot run --trace``,
read by :func:`~mirobot_async._cli.plotting.read_trace`) or a tape (``.jsonl``/``.jsonl.gz``,
read by :func:`~mirobot_async._tapes.format.read_tapes`; its printed status lines parsed with the
client's status parser). Pure module (no viser).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Final

from mirobot_async._core.replies import ReplyKind, classify_line, parse_status
from mirobot_async.errors import MirobotUsageError

if TYPE_CHECKING:
    from mirobot_async._cli.plotting import Trace
    from mirobot_async._tapes.format import Tape

__all__ = ["Event", "Sample", "Timeline", "from_tape", "from_trace", "load_timeline"]

Joints6 = tuple[float, float, float, float, float, float]
_PUMP_WORDS: Final = {
    1000: "suction on",
    500: "blow",
    0: "pump off",
    40: "gripper open",
    60: "gripper closed",
}


@dataclass(frozen=True, slots=True)
class Sample:
    """One status report: seconds from the first, state, joints (deg), rail (mm), tool xyz (mm),
    outputs (PWM 1 and 2; None when the source does not have them)."""

    t: float
    state: str
    joints: Joints6
    rail: float | None
    xyz: tuple[float, float, float]
    pump: int | None = None
    valve: int | None = None


@dataclass(frozen=True, slots=True)
class Event:
    """Something that happened at ``t``: ``output``, ``refusal``, ``alarm`` or ``state``."""

    t: float
    kind: str
    label: str


@dataclass(frozen=True, slots=True)
class Timeline:
    """Samples in time order (at least one) and events in time order."""

    samples: tuple[Sample, ...]
    events: tuple[Event, ...]
    source: str = ""

    def __post_init__(self) -> None:
        if not self.samples:
            raise MirobotUsageError(f"{self.source or 'the run'}: no status samples to replay")
        times = [s.t for s in self.samples]
        if times != sorted(times):
            raise MirobotUsageError(f"{self.source}: samples out of time order")

    @property
    def duration(self) -> float:
        return self.samples[-1].t

    def index_at(self, t: float) -> int:
        """The last sample at or before ``t`` (the first one before it)."""
        return max(bisect.bisect_right([s.t for s in self.samples], t) - 1, 0)

    def sample_at(self, t: float) -> Sample:
        """The arm at ``t``: its last report."""
        return self.samples[self.index_at(t)]

    def path_to(self, t: float) -> list[tuple[float, float, float]]:
        """Tool positions (mm) reported up to ``t`` (the first one at least)."""
        return [s.xyz for s in self.samples[: self.index_at(t) + 1]]

    def events_to(self, t: float) -> list[Event]:
        """Events seen up to ``t``."""
        return [e for e in self.events if e.t <= t]


def from_trace(trace: Trace, source: str = "trace") -> Timeline:
    """A trace's samples and its events (outputs where they took effect, alarms, holds)."""
    if len(trace) == 0:
        raise MirobotUsageError(f"{source}: the trace has no samples")
    samples = tuple(
        Sample(
            trace.seconds[i],
            trace.states[i],
            trace.joints[i],
            None,
            trace.positions[i],
            trace.pumps[i] if i < len(trace.pumps) else None,
            trace.valves[i] if i < len(trace.valves) else None,
        )
        for i in range(len(trace))
    )
    events = tuple(
        Event(e.seconds, "alarm" if e.label == "alarm" else e.kind, e.label)
        for e in sorted(trace.events(), key=lambda e: e.seconds)
    )
    return Timeline(samples, events, source)


def from_tape(tape: Tape, source: str = "tape") -> Timeline:
    """A tape's printed lines: status lines (the client's parser) are the samples; error lines
    are refusals, ``ALARM`` lines alarms; output and state changes come from the statuses."""
    from mirobot_async._tapes.format import Printed

    samples: list[Sample] = []
    events: list[Event] = []
    start: float | None = None
    for event in tape.events:
        if not isinstance(event, Printed) or event.partial:
            continue
        reply = classify_line(event.data)
        if reply.kind not in (ReplyKind.STATUS, ReplyKind.ERROR, ReplyKind.ALARM):
            continue
        if start is None:
            start = event.t
        t = event.t - start
        if reply.kind is ReplyKind.ERROR:
            events.append(Event(t, "refusal", reply.text))
            continue
        if reply.kind is ReplyKind.ALARM:
            events.append(Event(t, "alarm", reply.text or "alarm"))
            continue
        report = parse_status(event.data)
        sample = Sample(
            t,
            report.state.value,
            report.joints,
            report.rail,
            (report.pose[0], report.pose[1], report.pose[2]),
            report.pump_pwm,
            report.valve_pwm,
        )
        if samples:
            before = samples[-1]
            if sample.pump != before.pump and sample.pump is not None:
                events.append(
                    Event(t, "output", _PUMP_WORDS.get(sample.pump, f"PWM1 {sample.pump}"))
                )
            if sample.valve != before.valve:
                events.append(Event(t, "output", f"valve {sample.valve}"))
            if sample.state in ("Alarm", "Hold") and sample.state != before.state:
                kind = "alarm" if sample.state == "Alarm" else "state"  # as from a trace
                events.append(Event(t, kind, sample.state.lower()))
        samples.append(sample)
    if not samples:
        raise MirobotUsageError(f"{source}: no status lines in the tape")
    return Timeline(tuple(samples), tuple(events), source)


def load_timeline(path: str | Path) -> Timeline:
    """A trace CSV (``.csv``) or a tape (``.jsonl``, ``.jsonl.gz``; the first tape in the file
    that has status lines)."""
    name = str(path)
    if name.endswith((".jsonl", ".jsonl.gz")):
        from mirobot_async._tapes.format import read_tapes

        for tape in read_tapes(path):
            try:
                return from_tape(tape, f"{Path(name).name} ({tape.id})")
            except MirobotUsageError:
                continue
        raise MirobotUsageError(f"{name}: no tape with status lines")
    from mirobot_async._cli.plotting import TraceError, read_trace

    try:
        trace = read_trace(path)
    except TraceError as err:
        raise MirobotUsageError(str(err)) from None
    return from_trace(trace, Path(name).name)
