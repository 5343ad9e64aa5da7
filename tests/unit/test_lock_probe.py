"""The lock probe (:func:`mirobot_async._core.modal.lock_probe`): a zero-length relative joint
move, then the line that puts the modes back; what the mode tracking (the acceptance module,
the one owner of modes) makes of the two lines is the probe's own ``after``."""

from __future__ import annotations

import pytest

from mirobot_async._core.acceptance import line_fate
from mirobot_async._core.line import parse_line
from mirobot_async._core.modal import HOMED, MotionModes, lock_probe

CASES = [
    (MotionModes(), "M21 G91 X0", "G90"),  # power-on
    (HOMED, "M21 G91 X0", "G90"),  # feed 0, but G0: a zero G0 move is accepted
    (MotionModes.unknown(), "M21 G91 G21 G0 X0", "G90"),
    (MotionModes(cartesian=True, relative=True, motion=1, feed=300.0), "M21 G91 X0", "M20"),
    (MotionModes(cartesian=True, relative=False, motion=1, feed=0.0), "M21 G91 G0 X0", "M20 G90"),
    (MotionModes(relative=True, motion=2, feed=100.0), "M21 G91 G0 X0", None),  # no arc in M21
    (MotionModes(motion=1, feed=None), "M21 G91 G0 X0", "G90"),  # a G1 at an unknown feed
]


@pytest.mark.parametrize(("modes", "line", "restore"), CASES)
@pytest.mark.parametrize("firmware", ["classic", "2021"])
def test_the_probe_leaves_the_modes_it_found(
    modes: MotionModes, line: str, restore: str | None, firmware: str
) -> None:
    probe = lock_probe(modes)
    assert (probe.line, probe.restore) == (line, restore)
    fate = line_fate(parse_line(probe.line), modes, firmware)
    assert fate.accepted is True  # an unlocked arm answers ok (a locked one: ok, dropped)
    after = fate.modes
    if probe.restore is not None:
        fate = line_fate(parse_line(probe.restore), after, firmware)
        assert fate.accepted is True
        after = fate.modes
    assert after == probe.after
    # what was known is kept; what was unknown is known now
    for name in ("cartesian", "relative", "motion", "inches", "feed", "inverse_time"):
        before = getattr(modes, name)
        if before is not None and not (name == "motion" and "G0" in probe.line):
            assert getattr(after, name) == before, name
    assert None not in (after.cartesian, after.relative, after.motion, after.inches)
