"""Item 10's programs and their ideal motion time, both pure (no I/O, no event loop).

A program is a list of steps (a Cartesian pose, a joint position or a plain line such as a pump
command), each with the G-code line a script would send for it. Its *motion time* is what the
emulator's own firmware model (the same code the emulator process runs) takes to execute it when
fed by an ideal host: every line written the instant the 128-byte receive ring has room for it,
no wire, no latency. A client's wall time divided by that is its wall/motion ratio.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from mirobot_emulator.firmware import Firmware

from mirobot_async._core import gcode

RX_RING_BYTES = 128
"""The firmware's receive ring: a character-counting host keeps at most this many bytes
unanswered."""

SNAP_MARGIN_S = 2e-9
"""Advance the model slightly past each deadline: the planner snaps block ends within 1 ns and
the firmware model then misses the end of motion (see the report of issue 12's benchmark)."""

Pose6 = tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class Step:
    """One step of a program: ``kind`` is ``"pose"`` (linear Cartesian move to ``values``),
    ``"joints"`` (joint move to ``values``) or ``"line"`` (``line`` sent as is)."""

    kind: str
    line: str
    values: Pose6 | None = None
    speed: float | None = None


@dataclass(frozen=True)
class Program:
    """A program: ``setup`` lines bring the arm to its start (run and waited for first, not
    timed); ``steps`` are the program. ``key`` names it in the table (``a``, ``b``, ``c``)."""

    key: str
    title: str
    setup: tuple[str, ...]
    steps: tuple[Step, ...]

    @property
    def lines(self) -> list[str]:
        return [step.line for step in self.steps]

    @property
    def poses(self) -> list[Pose6] | None:
        """The program as poses for a path call, or None if it has other steps."""
        if all(step.kind == "pose" and step.values is not None for step in self.steps):
            return [step.values for step in self.steps if step.values is not None]
        return None

    @property
    def speed(self) -> float | None:
        speeds = {step.speed for step in self.steps}
        return speeds.pop() if len(speeds) == 1 else None


def _fmt(value: float) -> float:
    return round(value, 3)


def chord_program(
    key: str,
    chords: int,
    shortest: float,
    longest: float,
    radius: float,
    feed: float,
    seed: int,
    center: tuple[float, float, float] = (200.0, 0.0, 150.0),
) -> Program:
    """``chords`` linear moves of ``shortest``..``longest`` mm around a circle at ``feed`` mm/min.

    Cartesian mode (``M20``) is set once by the setup line, which moves to the start; the program
    lines are ``G1 X.. Y.. Z.. A0 B0 C0 F..``. Not ``M20 G90 G1`` on every line: on this
    firmware a line with ``M20`` restarts from where the arm *is* (not from where queued motion
    ends), so a streamed program of such lines zigzags back (the emulator models the oracle).
    """
    rng = random.Random(seed)
    cx, cy, cz = center
    angle = 0.0
    steps = []
    for _ in range(chords):
        chord = rng.uniform(shortest, longest)
        angle += 2 * math.asin(chord / (2 * radius))
        pose: Pose6 = (
            _fmt(cx + radius * math.cos(angle)),
            _fmt(cy + radius * math.sin(angle)),
            cz,
            0.0,
            0.0,
            0.0,
        )
        text = gcode.move_pose(*pose, linear=True, speed=feed).decode("ascii").strip()
        steps.append(Step("pose", text.replace("M20 G90 ", "", 1), pose, feed))
    start = gcode.move_pose(cx + radius, cy, cz, 0, 0, 0, linear=True, speed=feed)
    span = f"{shortest:g} mm" if shortest == longest else f"{shortest:g}-{longest:g} mm"
    title = f"({key}) {chords} `M20 G1` chords of {span} around a circle, F{feed:g}"
    return Program(key, title, (start.decode("ascii").strip(),), tuple(steps))


def pick_and_place(key: str, cycles: int, feed: float = 3000.0) -> Program:
    """A joint-space pick and place: ``cycles`` x (above, gripper open, down, pump on, up, over,
    down, pump off, gripper closed, up), each move a ``M21 G90 G1`` line (what the client's
    ``move_joints`` sends)."""

    def joints(q: Pose6) -> Step:
        text = gcode.move_joints(*q, speed=feed).decode("ascii").strip()
        return Step("joints", text, q, feed)

    def line(data: bytes) -> Step:
        return Step("line", data.decode("ascii").strip())

    above_pick: Pose6 = (15.0, 10.0, 10.0, 0.0, -20.0, 0.0)
    pick: Pose6 = (15.0, 18.0, 12.0, 0.0, -30.0, 0.0)
    above_place: Pose6 = (-15.0, 10.0, 10.0, 0.0, -20.0, 0.0)
    place: Pose6 = (-15.0, 18.0, 12.0, 0.0, -30.0, 10.0)
    steps: list[Step] = []
    for _ in range(cycles):
        steps += [
            joints(above_pick),
            line(gcode.set_gripper(False)),
            joints(pick),
            line(gcode.set_pump(gcode.PUMP_SUCK)),
            joints(above_pick),
            joints(above_place),
            joints(place),
            line(gcode.set_pump(gcode.PUMP_OFF)),
            line(gcode.set_gripper(True)),
            joints(above_place),
        ]
    setup = gcode.move_joints(0, 0, 0, 0, 0, 0, speed=feed).decode("ascii").strip()
    title = f"({key}) joint-space pick and place, {cycles} cycles, pump and gripper lines"
    return Program(key, title, (setup,), tuple(steps))


def full_programs() -> list[Program]:
    """Issue 12's programs (a), (b), (c)."""
    return [
        chord_program("a", 200, 2.0, 5.0, radius=40.0, feed=2000.0, seed=1),
        chord_program("b", 400, 0.5, 0.5, radius=20.0, feed=3000.0, seed=2),
        pick_and_place("c", 2),
    ]


def quick_programs() -> list[Program]:
    """The ``--quick`` variant: 20 chords of (a)."""
    return [chord_program("a20", 20, 2.0, 5.0, radius=40.0, feed=2000.0, seed=1)]


@dataclass(frozen=True)
class IdealRun:
    """The firmware model fed by an ideal host: simulated seconds from the first byte to the end
    of motion, and the times its planner ran empty before the end (starvations of the program
    itself, e.g. lines that wait for motion to finish)."""

    seconds: float
    starvations: int
    stopping_seconds: float = 0.0
    """The same model fed one line at a time, each after the previous motion ended (the best
    a ``wait=True`` loop can do): equal to ``seconds`` when the planner does not blend."""


def _drive(fw: Firmware, lines: list[str], *, stop: bool = False) -> None:
    """Feed ``lines`` with character counting, advancing the model's clock only when waiting
    (``stop``: one line at a time, each after the previous one's motion ended)."""
    if stop:
        for text in lines:
            _drive(fw, [text])
        return
    encoded = [text.encode("ascii") + b"\n" for text in lines]
    unanswered: list[int] = []
    sent = 0
    while True:
        while sent < len(encoded) and sum(unanswered) + len(encoded[sent]) <= RX_RING_BYTES:
            fw.receive(encoded[sent])
            unanswered.append(len(encoded[sent]))
            sent += 1
        for reply in fw.read_output().split(b"\r\n"):
            if reply == b"ok" or reply.startswith(b"error"):
                if reply.startswith(b"error"):
                    raise RuntimeError(f"the firmware model refused a line: {reply!r}")
                unanswered.pop(0)
        if sent < len(encoded) and sum(unanswered) + len(encoded[sent]) <= RX_RING_BYTES:
            continue
        if sent == len(encoded) and not unanswered:
            fw.advance(math.inf)
            return
        deadline = fw.next_deadline()
        if deadline is None:
            raise RuntimeError("the firmware model waits for nothing but lines are unanswered")
        fw.advance(max(0.0, deadline - fw.now) + SNAP_MARGIN_S)


def ideal_run(program: Program, profile: str = "2021") -> IdealRun:
    """Run ``program`` through a fresh firmware model (after ``M50`` and its setup)."""
    fw = Firmware(profile)
    _drive(fw, ["M50", *program.setup])
    start, ends_before = fw.now, fw.motion_ends
    _drive(fw, program.lines)
    end = fw.motion_end_times[-1] if fw.motion_ends > ends_before else start
    stopping = Firmware(profile)
    _drive(stopping, ["M50", *program.setup])
    stop_start = stopping.now
    _drive(stopping, program.lines, stop=True)
    stop_end = stopping.motion_end_times[-1] if stopping.motion_ends else stop_start
    return IdealRun(end - start, max(0, fw.motion_ends - ends_before - 1), stop_end - stop_start)
