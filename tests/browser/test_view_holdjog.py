"""Hold to jog in a real browser, at real time (the embedded virtual arm at time scale 1).

The buttons are pressed and let go with the mouse (input events, as a person's). The
release-to-stop latency is measured from the page's release: the ``pointerup`` event's own
time stamp (when the browser took the input, before the page's busy main thread got to it),
to the first status showing the arm stopped (the view prints that instant on stderr, on the
same clock). The holds last 0.8 s plus a fraction of the keep-alive period spread over the
jogs, so releases fall at every point between two keep-alives, as a person's do.

The pages of the latency tests draw the 3D scene at a quarter of its resolution (viser's
``fixedDpr`` setting, :data:`SOFTWARE_RENDER`): this machine's headless Chromium renders WebGL
in software (SwiftShader), where a frame of the moving arm at full resolution costs 50-60 ms of
the page's main thread, and the page's input and timers wait behind it. Measured here (2
cores, 10 jogs each): the release's ``pointerup`` was handled a median 52 ms after the input at
full resolution, 27 ms at half, 14 ms at a quarter (frames 50, 33 and 16.7 ms apart); a GPU
renders the frame in about a millisecond. The panel and its layout are the same.
"""

from __future__ import annotations

import re
import statistics
import time
from pathlib import Path
from typing import Any

import pytest
from viewpage import ARTIFACTS, Page, ViewProcess
from waiting import wait_for

pytestmark = [pytest.mark.browser, pytest.mark.timeout(300)]

STOPPED = re.compile(
    r"hold jog (\S+) ([+-]) \(hold\): stopped (\d+) ms after the (.+?) "
    r"\(at .* stopped at ([0-9.]+)\)"
)
JOGS = 10
KEEPALIVE_PERIOD = 0.5
"""Seconds between the page's keep-alives (``holdjog.KEEPALIVE_HZ``)."""
SOFTWARE_RENDER = "&fixedDpr=0.25"
"""Added to the page's URL: the scene drawn at a quarter of its resolution (see the module)."""

_WATCH = """() => {
  if (window.holdjogReleases) return;
  window.holdjogReleases = [];
  window.addEventListener('pointerup', e => {
    window.holdjogReleases.push([performance.timeOrigin + e.timeStamp, Date.now()]);
  }, true);
}"""
_HIT = """([x, y]) => {
  const button = document.elementFromPoint(x, y)?.closest('button');
  return button ? button.textContent : null;
}"""
_FLOAT = r"(-?[0-9.]+)"
_TOOL = re.compile(rf"Tool: x {_FLOAT}\s+y {_FLOAT}\s+z {_FLOAT}\s+rx {_FLOAT}")


def _joint(page: Page, joint: int) -> float:
    text = page.page.locator("body").inner_text()
    match = re.search(rf"J{joint} {_FLOAT}", text)
    assert match, text
    return float(match.group(1))


def _tool(page: Page) -> tuple[float, ...]:
    """x, y, z, rx of the tool as the page shows them."""
    text = page.page.locator("body").inner_text()
    match = _TOOL.search(text)
    assert match, text
    return tuple(float(v) for v in match.groups())


def _stops(view: ViewProcess, cause: str = "release") -> list[float]:
    """When each jog ended by ``cause`` stopped (epoch s)."""
    found = (STOPPED.search(line) for line in view.stderr)
    return [float(m.group(5)) for m in found if m and m.group(4) == cause]


def _server_latencies(view: ViewProcess) -> list[float]:
    """Seconds from the view receiving each release to the first status showing the stop."""
    found = (STOPPED.search(line) for line in view.stderr)
    return [int(m.group(3)) / 1000 for m in found if m and m.group(4) == "release"]


def _press(page: Page, name: str) -> None:
    """Put the mouse on the button ``name`` (scrolled into view) and press it."""
    button = page.page.get_by_role("button", name=name, exact=True)
    button.evaluate("b => b.scrollIntoView({block: 'center'})")
    box = button.bounding_box()
    assert box is not None, name
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    assert page.page.evaluate(_HIT, [x, y]) == name  # nothing else under the mouse
    page.page.evaluate(_WATCH)
    page.page.mouse.move(x, y)
    page.page.mouse.down()


def _release(page: Page) -> tuple[float, float]:
    """Let go of the mouse: the page's release, as the ``pointerup`` event's time stamp and
    as the instant its handler ran (epoch s)."""
    count = int(page.page.evaluate("window.holdjogReleases.length"))
    page.page.mouse.up()
    stamp, handled = wait_for(
        lambda: (
            r[count] if len(r := page.page.evaluate("window.holdjogReleases")) > count else None
        ),
        20,
        "the page's pointerup",
    )
    return float(stamp) / 1000.0, float(handled) / 1000.0


def _hold(page: Page, name: str, seconds: float) -> tuple[float, float]:
    """Press ``name``, hold it ``seconds``, let go: :func:`_release`'s instants."""
    _press(page, name)
    time.sleep(seconds)  # the button held this long (the jog's length)
    return _release(page)


def _hold_seconds(number: int) -> float:
    """Jog ``number``'s hold: 0.8 s and a fraction of the keep-alive period (spread evenly
    over the jogs: 0, 0.37, 0.24, ... of it)."""
    return 0.8 + (number * 0.37 * KEEPALIVE_PERIOD / 0.5) % KEEPALIVE_PERIOD


def _next_stop(view: ViewProcess, number: int) -> float:
    def stop_of() -> tuple[float] | None:
        stops = _stops(view)
        return (stops[number],) if len(stops) > number else None

    (stopped,) = wait_for(stop_of, 20, "the view to report the jog stopped")
    return stopped


def test_hold_to_jog_moves_while_held_and_stops_soon_after_release(
    start_view: Any, open_page: Any
) -> None:
    view = start_view("--time-scale", "1")
    page = open_page(view.url + SOFTWARE_RENDER)
    page.expect_text("State: Idle")
    page.wait_for_scene()  # the page's first seconds (meshes decoded) stall its timers
    latencies, handled = [], []
    for number in range(JOGS):
        name = "J1 + (hold)" if number % 2 == 0 else "J1 - (hold)"
        before = _joint(page, 1)
        seconds = _hold_seconds(number)
        released, seen = _hold(page, name, seconds)
        stopped = _next_stop(view, number)
        latencies.append(stopped - released)
        handled.append(stopped - seen)
        page.expect_text(f"{name}: stopped at")
        moved = _joint(page, 1) - before
        assert abs(moved) > 0.5 * seconds, f"{name} moved {moved} deg in {seconds} s"  # ~2 deg/s
        assert (moved > 0) == name.startswith("J1 +")
    page.shot("held")
    served = _server_latencies(view)
    text = _report("joints (J1)", latencies, handled, served)
    (ARTIFACTS / "holdjog-latency.txt").write_text(text + "\n")
    print(text)
    # the aim is under 100 ms for every jog; a release that comes within the page's 50 ms
    # message throttle after a keep-alive waits for it (longer while the page renders in
    # software), so the median is held to the aim and each jog to a bound a loaded
    # machine keeps
    assert statistics.median(latencies) < 0.1, text
    assert max(latencies) < 0.5, text
    assert view.stop() in (0, 130), "".join(view.stderr)


def test_cartesian_hold_jog_moves_the_tool_and_stops_at_the_envelope(
    start_view: Any, open_page: Any, tmp_path: Path
) -> None:
    """X + and X - move the tool along x while held, y and z stay, and it stands still after
    the release; held into the envelope's edge the jog ends there with the reason on the
    page, and X - then moves back from where the arm is."""
    fence = tmp_path / "fence.toml"
    fence.write_text("[box]\nx = [150, 203]\n")  # the tool starts at x 198.67 after homing
    view = start_view("--time-scale", "1", "--envelope", str(fence))
    page = open_page(view.url + SOFTWARE_RENDER)
    page.expect_text("State: Idle")
    page.wait_for_scene()
    latencies, handled = [], []
    for number, name in enumerate(("X - (hold)", "X + (hold)", "X - (hold)", "X + (hold)")):
        before = _tool(page)
        released, seen = _hold(page, name, _hold_seconds(number))
        stopped = _next_stop(view, number)
        latencies.append(stopped - released)
        handled.append(stopped - seen)
        page.expect_text(f"{name}: stopped at")
        page.expect_text("State: Idle")  # a status after the stop is shown
        after = _tool(page)
        moved = after[0] - before[0]
        assert abs(moved) > 0.5, f"{name} moved the tool {moved} mm"  # about 2.6 mm/s here
        assert (moved > 0) == (name == "X + (hold)")
        assert abs(after[1] - before[1]) < 0.1 and abs(after[2] - before[2]) < 0.1, (
            before,
            after,
        )
        time.sleep(0.5)  # the measurement window: the tool must not move during it
        assert _tool(page) == after, "the tool moved after the jog stopped"
    text = _report("Cartesian (X)", latencies, handled, _server_latencies(view))
    (ARTIFACTS / "holdjog-latency-cartesian.txt").write_text(text + "\n")
    print(text)
    assert statistics.median(latencies) < 0.1, text
    assert max(latencies) < 0.5, text
    # held into the envelope's edge: it ends there by itself, said on the page
    _press(page, "X + (hold)")
    page.expect_text("X + (hold): stopped (refused at the edge:", timeout=30_000)
    edge = _tool(page)[0]
    assert 201.5 < edge <= 203.0, edge
    _release(page)
    back = _tool(page)[0]
    _hold(page, "X - (hold)", 0.8)
    page.expect_text("X - (hold): stopped at")
    assert _tool(page)[0] < back - 0.5
    page.shot("cartesian")
    assert view.stop() in (0, 130), "".join(view.stderr)


def test_closing_the_page_mid_jog_stops_the_arm(
    start_view: Any, open_page: Any, browser: Any
) -> None:
    """The page goes away while a jog button is held (no release is ever sent): the arm
    stops, and stands still."""
    view = start_view("--time-scale", "1")
    page = open_page(view.url)
    page.expect_text("State: Idle")
    _press(page, "J2 + (hold)")
    time.sleep(0.6)  # the button held this long (the jog's length), not a settling delay
    closed = time.time()
    page.page.context.close()
    (stopped,) = wait_for(
        lambda: (s[0],) if (s := _stops(view, "page closed") + _stops(view, "watchdog")) else None,
        20,
        "the jog to stop",
    )
    assert stopped - closed < 1.5
    again = open_page(view.url)
    again.expect_text("State: Idle")
    first = _joint(again, 2)
    assert 0.5 < first < 3.0, first  # about 2 deg/s for 0.6 s, and no further
    time.sleep(1.0)  # the measurement window: the arm must not move during it
    assert _joint(again, 2) == first
    assert view.stop() in (0, 130), "".join(view.stderr)


def _report(what: str, latencies: list[float], handled: list[float], served: list[float]) -> str:
    return (
        f"hold-jog release-to-stop, {what}, {len(latencies)} jogs at time scale 1 (the machine: "
        "2 cores, headless Chromium rendering WebGL in software): from the page's release "
        f"event {_summary(latencies)}; from the page handling it {_summary(handled)}; from the "
        f"view receiving it {_summary(served)}"
    )


def _summary(values: list[float]) -> str:
    shown = ", ".join(f"{v * 1000:.0f}" for v in values)
    return (
        f"median {statistics.median(values) * 1000:.0f} ms, max {max(values) * 1000:.0f} ms "
        f"({shown})"
    )
