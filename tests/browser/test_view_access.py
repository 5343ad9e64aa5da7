"""Who may open ``mirobot view`` and what the page may do: the secret and the origin checked at
the websocket's handshake, the export folder, a lost link, no jog behind a program, ``--run``
only once a browser shows the scene."""

from __future__ import annotations

import http.server
import re
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import pytest
from viewpage import Page, ViewProcess, mirobot
from waiting import wait_for

pytestmark = [pytest.mark.browser, pytest.mark.timeout(240)]

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
WATCH = 5.0
"""Seconds a client that draws nothing is watched for the program not starting (the square
runs in about 1 s at time scale 100, and started as soon as the page had sent its camera)."""

PROBE = """async (url) => await new Promise((resolve) => {
    const socket = new WebSocket(url, ["viser-v" + VERSION]);
    socket.onopen = () => { socket.close(); resolve("open"); };
    socket.onerror = () => resolve("refused");
    setTimeout(() => resolve("no answer"), 20000);
})"""
"""Opens a websocket to ``url`` as viser's client does; how it went."""


def _probe(page: Any, url: str) -> str:
    import viser

    return str(page.evaluate(PROBE.replace("VERSION", repr(viser.__version__)), url))


def _ws_url(view: ViewProcess, *, token: bool = False) -> str:
    parts = urlsplit(view.url)
    return f"ws://{parts.netloc}/" + (f"?{parts.query}" if token else "")


@pytest.fixture
def other_origin(tmp_path: Path) -> Iterator[str]:
    """A page served from another local port (another origin on this machine)."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "index.html").write_text("<html><body>another page on this machine</body></html>")

    class Handler(http.server.SimpleHTTPRequestHandler):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, directory=str(site), **kwargs)

        def log_message(self, *args: Any) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()
        thread.join(10)


def _close(page: Page, view: ViewProcess) -> None:
    assert page.off_machine() == [], "requests left the machine"
    assert view.stop() in (0, 130), "".join(view.stderr)


def test_only_the_printed_url_s_page_connects(
    start_view: Any, open_page: Any, browser: Any, other_origin: str, tmp_path: Path
) -> None:
    """The printed URL carries a secret; the page it opens connects (and a websocket opened by
    that page connects). A page of another origin in the same browser, which has the secret's
    cookie (cookies do not tell ports apart), cannot connect: not from another local port, not
    from a ``file://`` page, not even with the secret in the websocket's URL. The right origin
    without the secret cannot either: the page is refused and so is its websocket."""
    view = start_view("--time-scale", "100")
    assert re.fullmatch(r"http://127\.0\.0\.1:\d+/\?token=[\w-]{20,}", view.url), view.url
    page = open_page(view.url)
    page.expect_text("State: Idle")
    assert _probe(page.page, _ws_url(view)) == "open"  # the probe itself works

    context = page.page.context  # same browser context: the cookie is there
    other = context.new_page()
    other.goto(other_origin)
    assert _probe(other, _ws_url(view)) == "refused"
    assert _probe(other, _ws_url(view, token=True)) == "refused"
    local = tmp_path / "local.html"
    local.write_text("<html><body>a file on disk</body></html>")
    other.goto(local.as_uri())
    assert _probe(other, _ws_url(view, token=True)) == "refused"

    fresh = browser.new_context()  # no cookie
    try:
        stranger = fresh.new_page()
        origin = view.url.partition("?")[0]
        response = stranger.goto(origin)
        assert response is not None and response.status == 403
        assert "printed" in stranger.locator("body").inner_text()
        assert _probe(stranger, _ws_url(view)) == "refused"
        response = stranger.goto(origin + "?token=not-the-secret")
        assert response is not None and response.status == 403
    finally:
        fresh.close()
    refusals = "".join(view.stderr)
    assert "Origin 'null'" in refusals and "Origin 'http://127.0.0.1:" in refusals, refusals
    page.expect_text("State: Idle")  # the printed URL's page still works
    _close(page, view)


def test_a_listen_address_off_this_machine_needs_allow_remote(tmp_path: Path) -> None:
    refused = mirobot("view", "--listen", "0.0.0.0:0", "--no-browser", cwd=tmp_path)
    assert refused.returncode == 2, refused.stderr
    assert "--allow-remote" in refused.stderr
    assert refused.stdout == ""  # nothing served


def test_export_never_overwrites_a_file_unasked(
    start_view: Any, open_page: Any, tmp_path: Path
) -> None:
    """Export writes into the folder fixed at start; a file already there is kept and the
    page says how to replace it (the Overwrite box; the name rules and the box are tested in
    tests/unit/test_view_export.py)."""
    kept = tmp_path / "taught.gcode"
    kept.write_text("(the user's own file)\n")
    view = start_view("--time-scale", "100")
    page = open_page(view.url)
    page.expect_text("State: Idle")
    page.click("Record point")
    page.expect_text("Recorded point 1")
    page.click("Export")
    page.expect_text("taught.gcode exists")
    page.expect_text("tick Overwrite")
    assert kept.read_text() == "(the user's own file)\n"
    _close(page, view)


def test_a_lost_link_is_said_on_the_page_and_the_command_exits_1(
    start_view: Any, open_page: Any
) -> None:
    emulator = subprocess.Popen(
        [sys.executable, "-m", "mirobot_emulator", "--time-scale", "100", "--firmware", "2021"],
        stdout=subprocess.PIPE,
        stdin=subprocess.PIPE,
        text=True,
    )
    try:
        assert emulator.stdout is not None
        port = emulator.stdout.readline().strip()
        view = start_view("--port", port)
        page = open_page(view.url)
        page.expect_text("State: Alarm")
        emulator.kill()  # the link drops (a cable pulled)
        emulator.wait(10)
        page.expect_text("LINK LOST")
        page.shot("link-lost")
        assert view.process.wait(30) == 1
        view.stop()
        assert "lost the link" in "".join(view.stderr)
    finally:
        if emulator.poll() is None:
            emulator.kill()
            emulator.wait(10)
        for pipe in (emulator.stdout, emulator.stdin):
            if pipe is not None:
                pipe.close()


def test_no_jog_and_no_second_run_while_a_program_runs(
    start_view: Any, open_page: Any, tmp_path: Path
) -> None:
    """While a program runs (held here, so that it still runs when the clicks arrive), "J1 +"
    and a second "Run program" are refused, with the reason on the page; nothing of them runs
    after the program (the next command finds J1 where the program left it)."""
    program = tmp_path / "slow.gcode"
    program.write_text("M21 G90 G21 G1 F300\nX-20\nX0\n")  # 8 s at time scale 1
    view = start_view(str(program), "--time-scale", "1")
    page = open_page(view.url)
    page.expect_text("State: Idle")
    page.click("Run program")
    page.expect_text("State: Run")
    page.click("Hold")  # the program stays running, however slow the machine is
    page.expect_text("State: Hold")
    page.click("J1 +")
    page.expect_text("J1 +5 deg: refused, a program is running")  # the notice line
    page.click("Run program")
    page.expect_text("Run program: refused, a program is running")
    page.click("Resume")
    page.expect_text("slow.gcode: 3 lines done")
    page.click("Pump on")  # queued behind anything still waiting
    page.expect_text("Pump/gripper: pump sucking")
    page.expect_joint(1, 0.0)
    page.click("J1 +")  # after the program, jogs work again
    page.expect_joint(1, 5.0)
    _close(page, view)


def _viser_messages(frame: bytes) -> list[dict[str, Any]]:
    import msgspec
    import zstandard

    size = int.from_bytes(frame[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(frame[16 : 16 + size])
    return list(msgspec.msgpack.decode(inner)["messages"])


def test_run_starts_once_a_browser_shows_the_scene(start_view: Any, open_page: Any) -> None:
    """``--run``: a client that connects and sends its camera but draws nothing (a page whose
    scene is not on screen yet) is asked for a frame, and the program does not start; it
    starts once a real browser shows the arm."""
    import msgspec
    import viser
    from websockets.sync.client import connect

    view = start_view(str(EXAMPLES / "square.gcode"), "--run", "--time-scale", "100")
    parts = urlsplit(view.url)
    token = parts.query.partition("=")[2]
    camera = {
        "type": "ViewerCameraMessage",
        "wxyz": [1.0, 0.0, 0.0, 0.0],
        "position": [0.4, -0.4, 0.3],
        "fov": 1.0,
        "near": 0.01,
        "far": 100.0,
        "image_height": 700,
        "image_width": 650,
        "look_at": [0.1, 0.0, 0.1],
        "up_direction": [0.0, 0.0, 1.0],
    }
    texts: list[str] = []
    asked = False
    with connect(
        f"ws://{parts.netloc}/",
        origin=f"http://{parts.netloc}",  # type: ignore[arg-type]
        additional_headers={"Cookie": f"mirobot-view-{parts.port}={token}"},
        subprotocols=[f"viser-v{viser.__version__}"],  # type: ignore[list-item]
    ) as socket:
        socket.send(msgspec.msgpack.encode(camera))
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            try:
                frame = socket.recv(timeout=deadline - time.monotonic())
            except TimeoutError:
                break
            assert isinstance(frame, bytes)
            for message in _viser_messages(frame):
                if message["type"] == "GetRenderRequestMessage" and not asked:
                    asked = True  # watched for 5 s more: the program would start at once
                    deadline = time.monotonic() + WATCH
                texts.append(str(message.get("updates", {}).get("_markdown", "")))
    assert asked, "the view never asked the page for a frame"
    shown = "\n".join(texts)
    assert "acknowledged" not in shown and "lines done" not in shown, shown
    assert "a browser shows the scene" not in "".join(view.stderr)
    page = open_page(view.url)
    page.expect_text("square.gcode: ")
    page.expect_text("lines done")
    wait_for(
        lambda: "a browser shows the scene" in "".join(view.stderr) or None,
        30,
        "the view to say it started",
    )
    _close(page, view)
