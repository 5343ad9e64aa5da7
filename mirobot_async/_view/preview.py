"""The tool path of a G-code program, predicted before anything is sent (``mirobot view``).

Each line goes through the same two checks the arm's commands use: the validation of ``mirobot
check`` (:func:`~mirobot_async._core.validation.check_program`: lines the firmware rejects or reads
otherwise) and the envelope's prediction (:func:`~mirobot_async._safety.prediction.predict`, with
an open envelope of the profile's geometry when none is given). The path is drawn as the arm runs
it: joint-space moves (``M21``, ``M20 G0``) as the forward kinematics of the linear joint
interpolation, Cartesian paths (``M20 G1``/``G2``/``G3``/``G5``) as the straight line, arc or
gate, after the rapid joint move to the firmware's IK branch when the prediction has one.
A line the validation flags is rejected by the firmware and moves nothing; a line the envelope
refuses is flagged too; a line without a prediction (position unknown) ends the drawing until a
later line states a position again. Pure module (numpy).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Final

import numpy as np

from mirobot_async._core import validation
from mirobot_async._core.line import ParsedLine, parse_line
from mirobot_async._core.modal import MotionModes, modes_of
from mirobot_async._safety.envelope import Envelope
from mirobot_async._safety.paths import (
    FloatArray,
    arc_plan,
    arc_samples,
    as_pose,
    line_samples,
    line_samples_needed,
)
from mirobot_async._safety.prediction import MachineState, Prediction, predict
from mirobot_async._urdf import dh_of
from mirobot_async.kinematics import Joints, Pose, forward, forward_many

__all__ = [
    "PATH_COLOURS",
    "REFUSED_COLOUR",
    "FlaggedLine",
    "LineStep",
    "PathSegment",
    "ProgramPreview",
    "predict_line",
    "preview_program",
]

_ZERO: Joints = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True, slots=True)
class FlaggedLine:
    """A line ``check`` (or the envelope) refuses: its 1-based number, text and the reason."""

    number: int
    text: str
    message: str


PATH_COLOURS: Final = {
    "joint": (40, 110, 230),
    "cartesian": (20, 160, 80),
    "snap": (150, 150, 150),
}
"""How the views draw each kind of :class:`PathSegment` (blue, green, grey; RGB)."""
REFUSED_COLOUR: Final = (220, 30, 30)
"""How the views mark a line refused or flagged (red)."""


@dataclass(frozen=True, slots=True)
class PathSegment:
    """The tool point's path (``(N, 3)`` mm, base frame) of one line; ``kind``: ``joint``
    (joint-space move), ``snap`` (the rapid move to the IK branch) or ``cartesian``."""

    number: int
    points: FloatArray
    kind: str


@dataclass(frozen=True, slots=True)
class ProgramPreview:
    """What a program will do: its path, its flagged lines, where the drawing stopped."""

    segments: list[PathSegment] = field(default_factory=list)
    flagged: list[FlaggedLine] = field(default_factory=list)
    unknown: list[FlaggedLine] = field(default_factory=list)
    """Lines after which the position is unknown (not flagged: the arm runs them)."""
    end_joints: Joints | None = None

    @property
    def flagged_numbers(self) -> list[int]:
        return sorted({f.number for f in self.flagged})

    def points(self) -> FloatArray:
        """Every path point in order (``(N, 3)`` mm), for bounds and pictures."""
        if not self.segments:
            return np.zeros((0, 3))
        return np.concatenate([s.points for s in self.segments])


def preview_program(
    lines: Sequence[str],
    *,
    firmware: str = "2021",
    start: Joints = _ZERO,
    envelope: Envelope | None = None,
    base_offset: tuple[float, float, float] | None = (0.0, 0.0, 0.0),
    gate_lift: float | None = None,
) -> ProgramPreview:
    """Predict ``lines`` (raw file lines, numbered from 1) from joints ``start`` (the arm at rest
    after homing: zeros). ``base_offset``/``gate_lift``: the 2021 settings ``$41..$43``/``$49``
    when known (a homed factory arm has a zero offset)."""
    problems: dict[int, list[str]] = {}
    for number, message in validation.check_program(lines, firmware=firmware):
        problems.setdefault(number, []).append(message)
    model = envelope if envelope is not None else Envelope(dh=dh_of(firmware))
    state = MachineState(
        modes=MotionModes(),
        joints=start,
        base_offset=(0.0, 0.0, 0.0) if firmware == "classic" else base_offset,
        gate_lift=None if firmware == "classic" else gate_lift,
        firmware=firmware,
    )
    out = ProgramPreview()
    for number, raw in enumerate(lines, start=1):
        parsed = parse_line(raw)
        if parsed.kind == "empty":
            continue
        text = raw.strip()
        if number in problems:  # the firmware rejects the line: it moves nothing
            out.flagged.append(FlaggedLine(number, text, "; ".join(problems[number])))
            continue
        step = predict_line(model, number, parsed, text, state)
        out.segments.extend(step.segments)
        if step.unpredicted is not None:
            if envelope is not None:
                out.flagged.append(step.unpredicted)
            elif state.joints is not None:
                out.unknown.append(step.unpredicted)
        state = step.state
    return replace(out, end_joints=state.joints)


@dataclass(frozen=True, slots=True)
class LineStep:
    """One line predicted: the path it draws, the machine after it, and, when the prediction
    failed (the position or a mode unknown, the envelope refuses), why (then ``state`` has no
    position: the path is not drawn until a later line states one)."""

    segments: list[PathSegment]
    state: MachineState
    unpredicted: FlaggedLine | None = None


def predict_line(
    model: Envelope, number: int, parsed: ParsedLine, text: str, state: MachineState
) -> LineStep:
    """Predict one line (numbered ``number``) from ``state`` with ``model``'s geometry: the
    step of :func:`preview_program`, and of the view that follows a script's lines."""
    result = predict(model, parsed, state, what=f"line {number}")
    if not isinstance(result, Prediction):
        gone = replace(state, joints=None, pose=None)
        return LineStep([], gone, FlaggedLine(number, text, result.reason))
    after = result.state
    segments: list[PathSegment] = []
    if parsed.is_homing:  # homing ends at zero (the arm waits for Idle there)
        after = replace(after, joints=_ZERO, pose=forward(_ZERO, model.dh, model.tool))
    elif result.moves and state.joints is not None:
        end = after.joints if after.joints is not None else result.model_joints
        if end is not None:
            segments = _segments(model, number, parsed, state, result, end)
            if after.joints is None:
                after = replace(after, joints=end)
    return LineStep(segments, after)


def _joint_points(model: Envelope, start: Sequence[float], end: Sequence[float]) -> FloatArray:
    steps = model.joint_path_steps(list(start), list(end))
    t = np.linspace(0.0, 1.0, steps + 1)
    a, b = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    q = a[None, :] + t[:, None] * (b - a)[None, :]
    return forward_many(q, model.dh, model.tool)[:, :3]


def _segments(
    model: Envelope,
    number: int,
    parsed: object,
    before: MachineState,
    result: Prediction,
    end: Joints,
) -> list[PathSegment]:
    """The path of one predicted move (see the module docstring)."""
    assert before.joints is not None
    modes = modes_of(result.line, before.modes)
    if not modes.cartesian or modes.motion in (0, None):
        return [PathSegment(number, _joint_points(model, before.joints, end), "joint")]
    out = []
    start_joints = before.joints
    if result.snap is not None:
        out.append(PathSegment(number, _joint_points(model, start_joints, result.snap), "snap"))
    start_pose: Pose = (
        before.pose if before.pose is not None else forward(start_joints, model.dh, model.tool)
    )
    target = result.state.pose
    if target is None:
        return out
    step = model.path_step_mm
    pieces: list[FloatArray] = []
    if modes.motion == 1:
        pieces.append(
            line_samples(start_pose, target, int(line_samples_needed(start_pose, target, step)))
        )
    elif modes.motion in (2, 3):
        radius = result.line.value("R")
        if radius is not None:
            plan = arc_plan(start_pose, target, radius, modes.motion == 2, step)
            if not isinstance(plan, str):
                pieces.append(arc_samples(plan, start_pose, target, int(plan.intervals)))
    elif modes.motion == 5 and before.gate_lift is not None:
        top = max(start_pose[2], target[2]) + before.gate_lift
        up = as_pose((*start_pose[:2], top, *start_pose[3:]))
        over = as_pose((*target[:2], top, *target[3:]))
        for a, b in ((start_pose, up), (up, over), (over, target)):
            pieces.append(line_samples(a, b, int(line_samples_needed(a, b, step))))
    if pieces:
        out.append(PathSegment(number, np.concatenate(pieces)[:, :3], "cartesian"))
    return out
