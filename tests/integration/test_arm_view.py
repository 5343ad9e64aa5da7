"""``arm.view()``: the 3D view on the script's own connection, over a real link (the page
itself is driven in Chromium by tests/browser/test_view_script.py).

The view only watches: the script's calls get the outcomes they get without it, the page is
behind the run's secret, and the view hears every line written, refused by the firmware, or
refused before it was written.
"""

from __future__ import annotations

import asyncio
import importlib.util
import urllib.error
import urllib.request
from typing import Any

import pytest
from waiting import wait_until

from mirobot_async import (
    ArmView,
    InvalidLineError,
    Mirobot,
    MirobotUsageError,
    MotionRefusedError,
)

pytestmark = pytest.mark.timeout(60)


def _get(url: str) -> int:
    try:
        with urllib.request.urlopen(url, timeout=10) as response:
            return int(response.status)
    except urllib.error.HTTPError as err:
        return err.code


async def test_the_view_hears_every_line_and_changes_no_outcome(
    ready_arm: Mirobot, capsys: pytest.CaptureFixture[str]
) -> None:
    arm = ready_arm
    async with arm.view(open_browser=False) as view:
        assert isinstance(view, ArmView)
        assert f"mirobot: view: {view.url}" in capsys.readouterr().err
        assert view.url.startswith("http://127.0.0.1:") and "?token=" in view.url
        assert await asyncio.to_thread(_get, view.url) == 200
        assert await asyncio.to_thread(_get, view.url.split("?")[0]) == 403  # no secret
        await arm.move_joints(j1=10, speed=2000)
        with pytest.raises(MotionRefusedError):  # the firmware drops it, as without a view
            await arm.send("M21 G90 G0 X170", validate=False)
        with pytest.raises(InvalidLineError):  # refused before a byte: nothing written
            await arm.send("M21 G90 G0 X170")
        result = await arm.stream(["M21 G90 G0 X0 Y5", "G0 X5"], wait=True)
        assert result.ok, result
        lines = view._lines
        assert lines is not None
        # the move, the refused line, two streamed lines and the stream's G4 P0 (wait=True);
        # the view takes them in at its next redraw (never in the middle of writing a line)
        await wait_until(lambda: lines.count_answered == 5, 10, "the view to take in 5 replies")
        assert lines.count_written == 5
        kinds = [(e.kind, e.text) for e in lines.events]
        assert kinds[0][0] == "refused" and "Soft limit" in kinds[0][1]
        assert kinds[1][0] == "not sent" and "M21 G90 G0 X170" in kinds[1][1]
        assert len(kinds) == 2
        assert [m.label for m in lines.markers] == ["line 2", "not sent"]
        assert lines.path(), "the path of the lines written is predicted"
    assert view.clients == 0
    await arm.move_joints(j1=0, speed=2000)  # the connection goes on after the view


async def test_the_view_refuses_a_remote_address_and_says_what_is_missing(
    ready_arm: Mirobot, monkeypatch: pytest.MonkeyPatch
) -> None:
    with pytest.raises(MirobotUsageError, match="allow_remote=True"):
        ready_arm.view(host="0.0.0.0")
    real = importlib.util.find_spec

    def without_viser(name: str, *args: Any) -> Any:
        return None if name == "viser" else real(name, *args)

    monkeypatch.setattr(importlib.util, "find_spec", without_viser)
    with pytest.raises(MirobotUsageError, match=r"pip install 'mirobot-async\[view\]'"):
        ready_arm.view()


def test_the_blocking_facade_enters_the_view_as_a_plain_block(emu: Any) -> None:
    from mirobot_async.sync import Mirobot as BlockingMirobot

    with BlockingMirobot.connect(emu.url) as arm:
        arm.unlock()
        with arm.view(open_browser=False) as view:
            assert isinstance(view, ArmView)
            assert _get(view.url) == 200
            arm.move_joints(j1=5, speed=2000)
            assert view.clients == 0
        arm.move_joints(j1=0, speed=2000)


async def test_cancelled_while_waiting_for_a_page_the_view_stops_its_server(
    ready_arm: Mirobot,
) -> None:
    import threading

    before = {t.ident for t in threading.enumerate()}
    view = ready_arm.view(open_browser=False, wait_for_page=30)
    entering = asyncio.ensure_future(view.__aenter__())
    await wait_until(lambda: "?token=" in (view._url or ""), 30, "the view to serve its page")
    entering.cancel()
    with pytest.raises(asyncio.CancelledError):
        await entering
    assert view._server is None  # stopped: nobody can open the page any more
    await wait_until(
        lambda: {t.ident for t in threading.enumerate()} <= before, 10, "viser's threads to end"
    )
