"""One raw line against an envelope, from a given position and modes, for the envelope's unit
tests: the prediction the client's guard makes before each line it writes
(:func:`mirobot_async._safety.prediction.predict`), reduced to its verdict."""

from __future__ import annotations

from collections.abc import Sequence

from mirobot_async import Envelope
from mirobot_async._core.modal import LineCheck, MotionModes
from mirobot_async._safety.envelope import _joints6, _pose6, _real
from mirobot_async._safety.prediction import MachineState, Prediction, predict


def check_envelope_line(
    envelope: Envelope,
    line: str | bytes,
    current_joints: Sequence[float] | None,
    current_pose: Sequence[float] | None = None,
    modes: MotionModes | None = None,
    *,
    current_rail: float | None = None,
    what: str | None = None,
    base_offset: tuple[float, float, float] | None = (0.0, 0.0, 0.0),
    gate_lift: float | None = None,
    firmware: str | None = "2021",
) -> LineCheck:
    """The modes after ``line`` and its target; raises ``MirobotUsageError`` when the envelope
    refuses it or cannot predict it (``current_pose`` defaults to the forward kinematics of
    ``current_joints``; ``modes`` to the power-on ones)."""
    joints = None if current_joints is None else _joints6(current_joints, "current joints")
    pose = None if current_pose is None else _pose6(current_pose, "current pose")
    rail = None if current_rail is None else _real(current_rail, "current rail")
    state = MachineState(
        MotionModes() if modes is None else modes,
        joints,
        pose,
        rail,
        base_offset,
        gate_lift,
        firmware,
    )
    result = predict(envelope, line, state, what=what)
    if not isinstance(result, Prediction):
        raise result.error()
    after = result.state
    return LineCheck(
        after.modes, result.moves, after.joints, after.pose, after.rail, after.base_offset
    )
