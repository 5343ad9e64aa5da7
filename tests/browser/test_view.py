"""``mirobot view`` in a real browser: the page, the 3D arm, the pendant, the program preview."""

from __future__ import annotations

import asyncio
import concurrent.futures
import re
from collections.abc import Callable, Coroutine
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import pytest
from viewpage import Page, ViewProcess, foreground_pixels, mirobot
from waiting import wait_for

from mirobot_async import Mirobot
from mirobot_async._core import validation
from mirobot_async.testing import start_emulator

pytestmark = [pytest.mark.browser, pytest.mark.timeout(240)]

T = TypeVar("T")
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
FLAGGED_PROGRAM = """(a program with a line the check flags)
M21 G90 G21 G1 F2000
X30 Y20 Z10 A0 B-30 C0
X-30 Y10 Z-10 A0 B-20 C0
M21 G90 G1 X400
X0 Y0 Z0 A0 B0 C0
"""


def in_thread(coroutine: Callable[[], Coroutine[Any, Any, T]]) -> T:
    """Run ``coroutine()`` to completion on a loop of its own (Playwright's sync API keeps a
    loop running in the test's thread)."""
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        return pool.submit(asyncio.run, coroutine()).result(timeout=120)


def _red_pixels(canvas: np.ndarray) -> int:
    return int(
        ((canvas[:, :, 0] > 150) & (canvas[:, :, 0] - canvas[:, :, 1:].max(axis=2) > 60)).sum()
    )


def _changed_pixels(a: np.ndarray, b: np.ndarray) -> int:
    return int((np.abs(a - b).max(axis=2) > 40).sum())


def _close(page: Page, view: ViewProcess) -> None:
    assert page.off_machine() == [], "requests left the machine"
    assert view.stop() in (0, 130), "".join(view.stderr)


def test_page_loads_offline_and_shows_the_arm(start_view: Any, open_page: Any) -> None:
    """The page comes from this machine only, and its canvas shows something (the arm on its
    grid), not a blank or single-colour area."""
    view = start_view("--time-scale", "100")
    page = open_page(view.url)
    page.expect_text("State: Idle")
    page.expect_text("J1 0.00")
    canvas = page.wait_for_scene()
    colours = len(np.unique(canvas.reshape(-1, 3), axis=0))
    foreground = foreground_pixels(canvas)
    page.shot("idle")
    assert colours > 50, f"the canvas has {colours} colours"
    assert foreground > 2000, f"only {foreground} pixels differ from the background"
    assert any(url.startswith("ws://127.0.0.1") for url in page.requests), page.requests
    _close(page, view)


def test_the_arm_s_pixels_move_while_it_moves_and_hold_resume_stop(
    start_view: Any, open_page: Any, tmp_path: Path
) -> None:
    """While the virtual arm runs a program (Run button; two slow turns of J1, about 30 s at
    5x real time) the canvas changes; Hold holds it, Resume goes on, Stop (reset) stops it
    (the 2021 arm is then locked: Alarm)."""
    program = tmp_path / "slow.gcode"
    program.write_text("M21 G90 G21 G1 F200\nX-90\nX150\n")
    view = start_view(str(program), "--time-scale", "5")
    page = open_page(view.url)
    page.wait_for_scene()
    page.click("Run program")
    page.expect_text("State: Run")
    first = page.canvas()
    wait_for(lambda: _changed_pixels(first, page.canvas()) > 300, 30, "the arm to move on screen")
    page.shot("running")
    assert "State: Run" in page.page.locator("body").inner_text(), "the program ended early"
    page.click("Hold")
    page.expect_text("State: Hold")
    page.click("Resume")
    page.expect_text("State: Run")
    page.click("Stop (reset)")
    page.expect_text("State: Alarm")
    _close(page, view)


def _status_over_port(port: str) -> tuple[float, ...]:
    async def read() -> tuple[float, ...]:
        async with Mirobot.connect(port) as arm:
            return (await arm.status()).joints

    return in_thread(read)


def test_jog_over_port_moves_the_emulator(
    start_view: Any, open_page: Any, emulator_pty: str
) -> None:
    """--port to an emulator on a pty: Home, then "J1 +" (5 deg); the page follows, and the
    emulator itself, read over its port after the view has closed it, stands at J1 = 5."""
    view = start_view("--port", emulator_pty)
    page = open_page(view.url)
    page.expect_text("State: Alarm")  # as the arm is after power-on: used as it is
    page.click("Home")
    page.expect_text("Home: done")
    page.expect_text("State: Idle")
    page.click("J1 +")
    page.expect_joint(1, 5.0)
    page.shot("jogged")
    _close(page, view)
    joints = _status_over_port(emulator_pty)
    assert joints[0] == pytest.approx(5.0, abs=0.02)  # whole motor steps
    assert joints[1:] == pytest.approx((0.0,) * 5, abs=0.01)


def test_jog_moves_the_embedded_arm(start_view: Any, open_page: Any) -> None:
    view = start_view("--time-scale", "100")
    page = open_page(view.url)
    page.expect_text("State: Idle")
    before = page.wait_for_scene()
    page.click("J2 +")
    page.expect_joint(2, 5.0)
    page.click("Z +")  # Cartesian jog: 10 mm up, in a straight line
    page.expect_text("Z +10: done")
    page.click("Pump on")
    page.expect_text("Pump/gripper: pump sucking")
    page.click("Gripper close")
    page.expect_text("Pump/gripper: gripper closed")
    wait_for(lambda: _changed_pixels(before, page.canvas()) > 100, 30, "the jogged arm drawn")
    _close(page, view)


def _run_points(path: Path) -> list[tuple[float, ...]]:
    """Drive a virtual arm through the exported program one point at a time: the joints where
    it stands after each point."""
    lines = [line for line in path.read_text().splitlines() if not line.startswith("(")]

    async def drive() -> list[tuple[float, ...]]:
        reached: list[tuple[float, ...]] = []
        async with start_emulator(time_scale=100) as url, Mirobot.connect(url) as arm:
            await arm.home()
            await arm.stream([lines[0]], wait=True)
            for line in lines[1:]:
                result = await arm.stream([line], wait=True)
                assert not result.errors, result.errors
                reached.append((await arm.status(fresh=True)).joints)
        return reached

    return in_thread(drive)


def test_teach_three_points_export_check_and_run(
    start_view: Any, open_page: Any, tmp_path: Path
) -> None:
    view = start_view("--time-scale", "100")
    page = open_page(view.url)
    page.expect_text("State: Idle")
    for number, (jog, joint, value) in enumerate(
        (("J1 +", 1, 5.0), ("J2 +", 2, 5.0), ("J3 -", 3, -5.0)), start=1
    ):
        page.click(jog)
        page.expect_joint(joint, value)
        page.click("Record point")
        page.expect_text(f"Recorded point {number}")
    page.click("Export")
    page.expect_text("Wrote taught.gcode (3 points)")
    page.shot("taught")
    _close(page, view)
    program = tmp_path / "taught.gcode"
    text = program.read_text()
    lines = text.splitlines()
    assert sum(1 for line in lines if re.match(r"M2[01]\b", line)) == 1, text  # modes once
    assert validation.check_program(lines) == []
    checked = mirobot("check", str(program), cwd=tmp_path)
    assert checked.returncode == 0, checked.stdout + checked.stderr
    taught = [tuple(float(word[1:]) for word in line.split()) for line in lines if line[0] == "X"]
    targets = [(5, 0, 0, 0, 0, 0), (5, 5, 0, 0, 0, 0), (5, 5, -5, 0, 0, 0)]
    assert len(taught) == 3
    for point, target in zip(taught, targets, strict=True):
        assert point[:6] == pytest.approx(target, abs=0.02)
        assert point[6:] in ((), (0.0,))  # the 2021 status has the rail (D0)
    for reached, point in zip(_run_points(program), taught, strict=True):
        assert reached == pytest.approx(point[:6], abs=0.006)  # within a motor step
    ran = mirobot("run", str(program), "--time-scale", "100", cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    assert re.search(r"-4\.99|-5\.0", ran.stdout), ran.stdout


def test_flagged_line_is_shown_and_nothing_is_sent(
    start_view: Any, open_page: Any, tmp_path: Path
) -> None:
    program = tmp_path / "flagged.gcode"
    program.write_text(FLAGGED_PROGRAM)
    view = start_view(str(program), "--time-scale", "100")
    page = open_page(view.url)
    page.expect_text("Flagged lines (1)")
    page.expect_text("line 5: M21 G90 G1 X400")
    page.wait_for_scene()
    wait_for(lambda: _red_pixels(page.canvas()) > 20, 60, "the red marker of line 5")
    page.click("Run program")
    page.expect_text("nothing was sent")
    page.expect_text("J1 0.00")
    page.shot("flagged")
    _close(page, view)
    assert any("flagged.gcode:5:" in line for line in view.stderr)


def test_envelope_refuses_a_jog(start_view: Any, open_page: Any, tmp_path: Path) -> None:
    """The envelope's box is drawn and applies to every jog: J3 + would take the tool below
    z = 225 mm; it is refused with nothing sent and the arm stays."""
    fence = tmp_path / "fence.toml"
    fence.write_text("[box]\nz = [225, 400]\n")
    view = start_view("--time-scale", "100", "--envelope", str(fence))
    page = open_page(view.url)
    page.expect_text("State: Idle")
    page.click("J3 +")
    page.expect_text("envelope")
    page.expect_text("J3 0.00")
    page.shot("envelope")
    _close(page, view)


def test_run_option_streams_the_program_once_the_page_is_open(
    start_view: Any, open_page: Any
) -> None:
    """``--run``: the program starts when the first browser connects; the progress bar and
    the message say when it is done, and the arm ends where the program ends."""
    view = start_view(str(EXAMPLES / "square.gcode"), "--run", "--time-scale", "100")
    page = open_page(view.url)
    page.expect_text("square.gcode: ")
    page.expect_text("lines done")
    page.expect_text("State: Idle")
    page.shot("ran")
    _close(page, view)


def test_replay_a_trace_scrubs_pose_path_and_events(
    start_view: Any, open_page: Any, tmp_path: Path
) -> None:
    program = tmp_path / "pick.gcode"
    program.write_text(
        "M21 G90 G21 G1 F2000\nX30 Y20 Z0 A0 B0 C0\nM3 S1000\nG4 P0.3\n"
        "X-30 Y30 Z-10 A0 B0 C0\nM3 S0\nX0 Y0 Z0 A0 B0 C0\n"
    )
    ran = mirobot("run", str(program), "--time-scale", "5", "--trace", "run.csv", cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    view = start_view("--replay", "run.csv")
    page = open_page(view.url)
    page.expect_text("Replay of run.csv")
    page.expect_text("At 0.00 s")
    start = page.wait_for_scene()
    page.shot("replay-start")
    page.click("End")
    page.expect_text(re.compile(r"Events so far \(2\)"))
    page.expect_text("pump off")
    page.click("Prev event")
    page.expect_text(re.compile(r"Events so far \(1\)"))
    page.expect_text("suction on")
    page.click("Next event")
    page.expect_text(re.compile(r"Events so far \(2\)"))
    page.click("Start")
    page.expect_text("At 0.00 s")
    page.click("Play")  # the slider runs by itself, at real time
    page.expect_text(re.compile(r"At [1-9]\.\d\d s"))
    page.click("Pause")
    wait_for(
        lambda: (np.abs(page.canvas() - start).max(axis=2) > 60).sum() > 300 or None,
        60,
        "the arm and its path to be drawn elsewhere than at the start",
        every=0.5,
    )
    page.shot("replay-scrubbed")
    _close(page, view)


def _final(text: str) -> tuple[tuple[float, ...], str]:
    """The joints and the pwm line of the status ``mirobot run`` prints at the end."""
    joints = re.search(r"^joints\s+(.*)$", text, re.M)
    pwm = re.search(r"^pwm\s+(.*)$", text, re.M)
    assert joints and pwm, text
    return tuple(float(v) for v in joints[1].split()[:6]), pwm[1].strip()


def test_teach_a_program_with_actions_play_export_check_and_run_the_same(
    start_view: Any, open_page: Any, tmp_path: Path
) -> None:
    view = start_view("--time-scale", "100")
    page = open_page(view.url)
    page.expect_text("State: Idle")
    page.click("J1 +")
    page.expect_joint(1, 5.0)
    page.click("Record point")
    page.expect_text("Recorded point 1")
    page.click("+ pump on")
    page.click("+ dwell")
    page.expect_text("dwell 1 s")
    page.click("J2 +")
    page.expect_joint(2, 5.0)
    page.click("Record point")
    page.expect_text("Recorded point 4")
    page.click("+ speed")
    page.expect_text("speed 1000 deg/min")
    page.click("J3 -")
    page.expect_joint(3, -5.0)
    page.click("Record point")
    page.expect_text("Recorded point 6")
    page.click("+ pump blow")
    page.click("+ gripper open")  # added, moved up, back down, deleted: 7 rows are left
    page.expect_text("gripper open")
    page.click("Up")
    page.expect_text(re.compile(r"7\s*gripper open\s*8\s*pump blow"))  # the table's cells
    page.click("Down")
    page.expect_text(re.compile(r"7\s*pump blow\s*8\s*gripper open"))
    page.click("Delete")
    page.expect_text(re.compile(r"7\s*pump blow\s*Row #"))
    page.page.get_by_label("Loops").fill("2")
    page.click("J1 +")  # away from the first point: Play goes there slowly first
    page.expect_joint(1, 10.0)
    page.shot("teach-table")
    page.click("Play")
    page.expect_text("Played 7 rows x 2")
    page.expect_text("pump blowing")
    page.expect_joint(1, 5.0)
    page.expect_joint(3, -5.0)
    page.click("Export")
    page.expect_text("Wrote taught.gcode (3 points, 4 actions)")
    page.click("Delete")
    page.click("Import")
    page.expect_text("Imported taught.gcode: 7 rows")
    _close(page, view)
    program = tmp_path / "taught.gcode"
    lines = program.read_text().splitlines()
    assert lines[1:] == [
        "M21 G90 G21 G1 F2000",
        *lines[2:3],
        "M3 S1000",
        "G4 P1",
        *lines[5:6],
        "F1000",
        *lines[7:8],
        "M3 S500",
    ]
    checked = mirobot("check", str(program), cwd=tmp_path)
    assert checked.returncode == 0, checked.stdout + checked.stderr
    ran = mirobot("run", str(program), "--time-scale", "100", cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    joints, pwm = _final(ran.stdout)
    assert joints == pytest.approx((5, 5, -5, 0, 0, 0), abs=0.02)  # where Play ended
    assert pwm.startswith("pump 500"), pwm  # blowing, as Play left it


def test_replay_a_recorded_tape_shows_its_alarm(start_view: Any, open_page: Any) -> None:
    tape = Path(__file__).parents[1] / "tapes" / "firmware" / "integration-oracle-link.jsonl.gz"
    view = start_view("--replay", str(tape))
    page = open_page(view.url)
    page.expect_text("Replay of integration-oracle-link.jsonl.gz")
    page.wait_for_scene()
    page.click("Next event")
    page.expect_text(re.compile(r"alarm\s*: Abort during cycle"))
    page.click("End")
    page.expect_text(re.compile(r"Events so far \(2\)"))
    page.shot("replay-tape")
    _close(page, view)
