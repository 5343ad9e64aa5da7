"""Browser tests of ``mirobot view``: Debian's Chromium, headless, driven by Playwright's Python
package (never ``playwright install``: the system browser at :data:`CHROMIUM`).

Each test starts ``mirobot view`` as a subprocess (``--no-browser``), reads the page's URL from
its first line of output, opens it and records every request the page makes; the test fails if
one goes anywhere but this machine. Screenshots are kept in ``tests/browser/artifacts/`` (ignored
by git). Without Chromium or Playwright the tests skip with one line saying so;
``MIROBOT_REQUIRE_BROWSER=1`` (CI) turns that skip into a failure.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from viewpage import ARTIFACTS, UI_TIMEOUT, VIEWPORT, Page, ViewProcess, drain

CHROMIUM = os.environ.get("MIROBOT_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
START_TIMEOUT = 60.0
"""Seconds for ``mirobot view`` to print its URL (an embedded arm homes first)."""


def _missing() -> str | None:
    if not Path(CHROMIUM).exists():
        return f"no Chromium at {CHROMIUM} (apt-get install chromium)"
    try:
        import playwright.sync_api  # noqa: F401
        import viser  # noqa: F401
        import yourdfpy  # noqa: F401
    except ImportError as err:
        return f"{err.name} is not installed (pip install -e '.[test,view]')"
    return None


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    """One headless Chromium for the session."""
    why = _missing()
    if why is not None:
        if os.environ.get("MIROBOT_REQUIRE_BROWSER") == "1":
            pytest.fail(f"MIROBOT_REQUIRE_BROWSER=1 but {why}")
        pytest.skip(why)
    from playwright.sync_api import sync_playwright

    ARTIFACTS.mkdir(exist_ok=True)
    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            yield chromium
        finally:
            chromium.close()


@pytest.fixture
def start_view(tmp_path: Path) -> Iterator[Callable[..., ViewProcess]]:
    """``start_view(*args)``: ``mirobot view ARGS --no-browser`` in ``tmp_path`` (so an export
    lands there), stopped at the end of the test."""
    started: list[ViewProcess] = []

    def start(*args: str) -> ViewProcess:
        command = [sys.executable, "-m", "mirobot_async", "view", *args, "--no-browser"]
        process = subprocess.Popen(
            command,
            cwd=tmp_path,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            stdin=subprocess.DEVNULL,
        )
        view = ViewProcess(process, "")
        started.append(view)
        assert process.stderr is not None and process.stdout is not None
        view.drain = threading.Thread(target=drain, args=(process.stderr, view.stderr))
        view.drain.start()
        first: list[str] = []
        reader = threading.Thread(target=lambda: first.append(process.stdout.readline()))  # type: ignore[union-attr]
        reader.start()
        reader.join(START_TIMEOUT)
        assert first and first[0].startswith("http://"), (first, "".join(view.stderr))
        view.url = first[0].strip()
        return view

    yield start
    for view in started:
        view.stop()


@pytest.fixture
def open_page(browser: Any, request: pytest.FixtureRequest) -> Iterator[Callable[[str], Page]]:
    """``open_page(url)``: a new page at ``url``, its requests recorded, closed at the end."""
    contexts: list[Any] = []

    def open_(url: str) -> Page:
        context = browser.new_context(viewport=VIEWPORT)
        contexts.append(context)
        page = context.new_page()
        page.set_default_timeout(UI_TIMEOUT)
        requests: list[str] = []
        page.on("request", lambda r: requests.append(r.url))
        page.on("websocket", lambda ws: requests.append(ws.url))
        page.goto(url)
        name = request.node.name.replace("[", "-").replace("]", "")
        wrapped = Page(page, requests, name)
        wrapped.expect_text("State:")
        return wrapped

    yield open_
    for context in contexts:
        context.close()


@pytest.fixture
def emulator_pty() -> Iterator[str]:
    """A ``mirobot-emulator`` on a pty (time-scale 100): its port, for ``--port``."""
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "mirobot_emulator",
            "--time-scale",
            "100",
            "--firmware",
            "2021",
            "--exit-on-stdin-eof",
        ],
        stdout=subprocess.PIPE,
        stdin=subprocess.PIPE,
        text=True,
    )
    assert process.stdout is not None
    port = process.stdout.readline().strip()
    assert port.startswith("/dev/"), port
    try:
        yield port
    finally:
        process.terminate()
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(10)
        process.stdout.close()
        if process.stdin is not None:
            process.stdin.close()
