"""The parser's modal state (GRBL's ``gc_state`` plus the Mirobot's M20/M21 mode and PWMs)."""

from __future__ import annotations

from dataclasses import dataclass

from .. import settings as cfg
from ..motion import Vec7

Pose = tuple[float, float, float, float, float, float]

_MOTION_WORDS = {0: "G0", 1: "G1", 2: "G2", 3: "G3", 5: "G5", 80: "G80"}


@dataclass
class ModalState:
    """Modal groups, feed, PWMs and the coordinate mode; :meth:`init` is GRBL's ``gc_init``."""

    motion: int = 0
    plane: int = 17
    units: int = 21
    distance: int = 90
    feed_mode: int = 94
    coord_select: int = 54
    spindle: int = 5
    coolant: int = 9
    feed: float = 200.0
    pump_pwm: float = 0.0
    valve_pwm: float = 0.0
    cart_mode: bool = False
    cart: Pose = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    """The last commanded Cartesian pose (``M20`` ``G91`` increments add to it)."""
    g92: Vec7 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    """The ``G92`` offset (axis-word order; cleared by a reset)."""
    joints: Vec7 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    """The parser's own position (GRBL's ``gc_state.position``, not rounded to steps): where the
    last accepted move ends; ``M21``/``M20`` and resets set it to the machine position."""

    def init(self, *, feed: float, joints: Vec7, pose: Pose) -> None:
        """GRBL ``gc_init`` plus the Mirobot defaults (G0, G90, M21, PWM 0), ``feed``, and the
        position synchronised to the machine's ``joints`` (``pose`` their FK)."""
        self.motion = 0
        self.plane = 17
        self.units = 21
        self.distance = 90
        self.feed_mode = 94
        self.coord_select = 54
        self.spindle = 5
        self.coolant = 9
        self.feed = feed
        self.pump_pwm = 0.0
        self.valve_pwm = 0.0
        self.cart_mode = False
        self.cart = pose
        self.joints = joints
        self.g92 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def program_end(self) -> None:
        """M2 / M30: GRBL resets these modal groups (motion becomes G1)."""
        self.motion = 1
        self.plane = 17
        self.distance = 90
        self.feed_mode = 94
        self.coord_select = 54
        self.spindle = 5
        self.coolant = 9

    def report(self) -> str:
        """``$G`` (GRBL 0.9j ``report_gcode_modes``)."""
        parts = [
            _MOTION_WORDS[self.motion],
            f"G{self.coord_select}",
            f"G{self.plane}",
            f"G{self.units}",
            f"G{self.distance}",
            f"G{self.feed_mode}",
            "M0",
            f"M{self.spindle}",
            f"M{self.coolant}",
            "T0",
            f"F{cfg.grbl_float(self.feed, 0)}",
            f"S{cfg.grbl_float(self.pump_pwm, 0)}",
        ]
        return "[" + " ".join(parts) + "]"
