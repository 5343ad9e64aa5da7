"""Helpers of the browser tests: the view process, the page, waiting, the ``mirobot`` command."""

from __future__ import annotations

import base64
import contextlib
import io
import re
import signal
import subprocess
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

import numpy as np
from waiting import wait_for

ARTIFACTS = Path(__file__).parent / "artifacts"
LOCAL_HOSTS = {"127.0.0.1", "localhost", "::1"}
VIEWPORT = {"width": 1100, "height": 700}
SCENE_WIDTH = 650
"""Pixels of the page's width left of the control panel (which is about 420 px wide)."""
UI_TIMEOUT = 60_000
"""Milliseconds the page has for each condition a test waits on."""


@dataclass
class ViewProcess:
    """A running ``mirobot view`` and the page's URL."""

    process: subprocess.Popen[str]
    url: str
    stderr: list[str] = field(default_factory=list)
    drain: threading.Thread | None = None

    def stop(self) -> int:
        """SIGINT (Ctrl-C), as a user ends it; the exit status (killed after 20 s)."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(20)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(10)
        if self.drain is not None:
            self.drain.join(10)
        for pipe in (self.process.stdout, self.process.stderr):
            if pipe is not None:
                pipe.close()
        return self.process.returncode


@dataclass
class Page:
    """A Playwright page on the view, with every URL it asked for."""

    page: Any
    requests: list[str]
    name: str

    def png(self) -> bytes:
        """The page as PNG, through the DevTools protocol (Playwright's own screenshot waits
        for quiet frames, which a page that renders continuously in software rarely has)."""
        cdp = self.page.context.new_cdp_session(self.page)
        try:
            data = cdp.send("Page.captureScreenshot", {"format": "png"})
        finally:
            cdp.detach()
        return base64.b64decode(data["data"])

    def shot(self, label: str) -> Path:
        """Keep a screenshot in the artifacts directory."""
        path = ARTIFACTS / f"{self.name}-{label}.png"
        path.write_bytes(self.png())
        return path

    def canvas(self) -> np.ndarray:
        """The 3D scene as an RGB array: the page left of the control panel."""
        from PIL import Image

        image = np.asarray(Image.open(io.BytesIO(self.png())).convert("RGB")).astype(np.int16)
        return image[:, :SCENE_WIDTH]

    def expect_text(self, text: str | re.Pattern[str], timeout: float = UI_TIMEOUT) -> None:
        from playwright.sync_api import expect

        expect(self.page.locator("body")).to_contain_text(text, timeout=timeout)

    def expect_joint(self, joint: int, value: float) -> None:
        """The status shows ``J<joint>`` within 0.02 deg of ``value`` (the arm moves in whole
        motor steps: a 5 deg jog ends at 4.99 or 5.00)."""
        shown = [f"{value + d:.2f}" for d in (-0.02, -0.01, 0.0, 0.01, 0.02)]
        pattern = rf"J{joint} ({'|'.join(re.escape(v) for v in shown)})\b"
        self.expect_text(re.compile(pattern))

    def wait_for_scene(self) -> np.ndarray:
        """The scene once it is drawn (the arm in front of the background)."""

        def drawn() -> tuple[np.ndarray] | None:
            canvas = self.canvas()
            return (canvas,) if foreground_pixels(canvas) > 2000 else None

        (canvas,) = wait_for(drawn, UI_TIMEOUT / 1000, "the scene to be drawn", every=0.2)
        return canvas

    def click(self, name: str) -> None:
        """Click the button ``name`` (a DOM click event: Playwright's pointer click waits for
        animation frames, which a software-rendered 3D page gives slowly)."""
        self.page.get_by_role("button", name=name, exact=True).dispatch_event("click")

    def off_machine(self) -> list[str]:
        """Requests to anything but this machine (http(s) and ws(s); blob: and data: are local)."""
        out = []
        for url in self.requests:
            parsed = urlparse(url)
            if parsed.scheme in ("blob", "data"):
                continue
            if parsed.hostname not in LOCAL_HOSTS:
                out.append(url)
        return out


def drain(stream: io.TextIOBase, into: list[str]) -> None:
    """Append each line of ``stream`` to ``into`` until it ends (a reader thread's body)."""
    with contextlib.suppress(ValueError, OSError):
        for line in stream:
            into.append(line)


def mirobot(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``mirobot ARGS`` to completion."""
    return subprocess.run(
        [sys.executable, "-m", "mirobot_async", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def foreground_pixels(canvas: np.ndarray) -> int:
    """Pixels that differ clearly from the most common colour (the background)."""
    background = np.median(canvas.reshape(-1, 3), axis=0)
    return int((np.abs(canvas - background).max(axis=2) > 60).sum())
