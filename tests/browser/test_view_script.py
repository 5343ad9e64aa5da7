"""The view of a script's own connection in a real browser, at real time (time scale 1):
``mirobot run --view`` and a blocking script's ``with arm.view():``.

The page shows the motion and the path predicted for what the script writes, and the lines
refused (by the firmware, or before they were written) as they happen; closing the page never
stops the script; the script's end is said on the page.
"""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from viewpage import Page, drain
from waiting import wait_for

pytestmark = [pytest.mark.browser, pytest.mark.timeout(300)]

URL = re.compile(r"mirobot: view: (http://\S+)")

PROGRAM = """\
; three joint moves at 600 deg/min, about 16 s at real time
M21 G90 G1 F600
G1 X40 Y20
G1 X-40 Y10 Z10
G1 X0 Y0 Z0
"""

SCRIPT = """\
import sys
from mirobot_async import MirobotUsageError, MotionRefusedError
from mirobot_async.sync import Mirobot
from mirobot_async.virtual import run_emulator

with run_emulator(firmware="2021", time_scale=1) as emu, Mirobot.connect(emu.url) as arm:
    arm.unlock()
    with arm.view(open_browser=False, wait_for_page=60) as view:
        arm.move_joints(j1=-60, j2=20, speed=1500)
        try:
            arm.send("M21 G90 G0 X170", validate=False)
        except MotionRefusedError as err:
            print("refused:", err, flush=True)
        try:
            arm.send("M21 G90 G0 X170")
        except MirobotUsageError as err:
            print("not sent:", err, flush=True)
        arm.move_joints(j1=0, j2=0, speed=1500)
        print("waiting", flush=True)
        sys.stdin.readline()  # the test says when the script ends
print("done", flush=True)
"""


class Command:
    """A command whose standard output and error are read as they come."""

    def __init__(self, args: list[str], cwd: Path) -> None:
        self.process = subprocess.Popen(
            args,
            cwd=cwd,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.stdout: list[str] = []
        self.stderr: list[str] = []
        self._threads = [
            threading.Thread(target=drain, args=(self.process.stdout, self.stdout)),
            threading.Thread(target=drain, args=(self.process.stderr, self.stderr)),
        ]
        for thread in self._threads:
            thread.start()

    def url(self) -> str:
        def found() -> tuple[str] | None:
            for line in list(self.stderr):
                if match := URL.search(line):
                    return (match.group(1),)
            return None

        (url,) = wait_for(found, 60, "the view's URL on stderr")
        return url

    def wait(self, timeout: float) -> int:
        code = self.process.wait(timeout)
        for thread in self._threads:
            thread.join(10)
        return code

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait(10)
        for thread in self._threads:
            thread.join(10)
        for pipe in (self.process.stdin, self.process.stdout, self.process.stderr):
            if pipe is not None:
                pipe.close()


@pytest.fixture
def command(tmp_path: Path) -> Iterator[Callable[..., Command]]:
    started: list[Command] = []

    def start(*args: str) -> Command:
        started.append(Command([sys.executable, *args], tmp_path))
        return started[-1]

    yield start
    for each in started:
        each.stop()


def _path_pixels(canvas: np.ndarray) -> int:
    """Pixels of the predicted path's joint-move blue (40, 110, 230), as the page renders it
    (about (141, 189, 222))."""
    r, b = canvas[..., 0], canvas[..., 2]
    return int(((b - r > 40) & (b > 150)).sum())


def _red_pixels(canvas: np.ndarray) -> int:
    """Pixels of the refusal markers' red (220, 30, 30), shaded (not the tool's orange)."""
    r, g, b = canvas[..., 0], canvas[..., 1], canvas[..., 2]
    return int(((r > 150) & (r - g > 80) & (np.abs(g - b) < 30)).sum())


def _text(page: Page) -> str:
    return str(page.page.locator("body").inner_text())


def test_run_view_shows_the_program_and_closing_the_page_never_stops_it(
    command: Callable[..., Command], open_page: Any, tmp_path: Path
) -> None:
    (tmp_path / "moves.gcode").write_text(PROGRAM)
    run = command(
        "-m",
        "mirobot_async",
        "run",
        "moves.gcode",
        "--view",
        "--no-browser",
        "--time-scale",
        "1",
        "--unlock",
    )
    url = run.url()
    first = open_page(url)  # the run waits for a page before it moves
    second = open_page(url)
    first.expect_text(re.compile(r"[1-9]\d* lines? written"))
    second.wait_for_scene()

    def path_drawn() -> tuple[int] | None:
        pixels = _path_pixels(second.canvas())
        return (pixels,) if pixels > 200 else None

    try:
        wait_for(path_drawn, 30, "the predicted path to be drawn", every=0.3)
    finally:
        second.shot("running")
    first.page.context.close()  # the page goes away mid-run: the run goes on
    assert run.wait(120) == 0, "".join(run.stderr)
    assert any("Idle" in line for line in run.stdout), run.stdout  # its final status
    second.expect_text("Script: ended")
    second.expect_text(re.compile(r"(\d+) lines written, \1 answered, 0 refused"))
    second.shot("ended")


def test_a_blocking_script_s_view_shows_refusals_as_they_happen_and_its_end(
    command: Callable[..., Command], open_page: Any, tmp_path: Path
) -> None:
    (tmp_path / "script.py").write_text(textwrap.dedent(SCRIPT))
    script = command("script.py")
    page = open_page(script.url())  # the script waits for it (wait_for_page)
    before = _red_pixels(page.wait_for_scene())
    page.expect_text("Soft limit triggered:X")  # the firmware's refusal, as it happened
    page.expect_text(re.compile(r"not sent.*M21 G90 G0 X170"))
    wait_for(lambda: any("waiting" in line for line in script.stdout), 60, "the script's moves")

    def marked() -> tuple[int] | None:
        red = _red_pixels(page.canvas())
        return (red,) if red > before + 30 else None

    try:
        wait_for(marked, 30, "a red marker where the line was refused", every=0.3)
    finally:
        page.shot("refused")
    assert page.off_machine() == []
    assert script.process.stdin is not None
    script.process.stdin.write("\n")
    script.process.stdin.flush()
    page.expect_text("Script: ended")
    assert script.wait(60) == 0, "".join(script.stderr)
    assert "done\n" in script.stdout
    assert any(line.startswith("refused: ") for line in script.stdout)
    assert any(line.startswith("not sent: ") for line in script.stdout)


def test_monitor_view_shows_the_status_it_samples_and_its_end(
    command: Callable[..., Command], open_page: Any
) -> None:
    monitor = command(
        "-m", "mirobot_async", "monitor", "--view", "--no-browser", "--samples", "60",
        "--interval", "0.1", "--time-scale", "1",
    )  # fmt: skip
    page = open_page(monitor.url())
    page.expect_text(re.compile(r"J1 -?\d+\.\d\d"))
    page.expect_text("Script: running")
    page.wait_for_scene()
    assert monitor.wait(60) == 0, "".join(monitor.stderr)
    page.expect_text("Script: ended")
    assert len([line for line in monitor.stdout if "Idle" in line or "Alarm" in line]) >= 10
