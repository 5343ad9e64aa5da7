"""``--view`` of ``mirobot run`` and ``mirobot monitor``: the 3D view on the command's own
connection (:meth:`mirobot_async.Mirobot.view`), for as long as the command talks to the arm."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import AsyncIterator
from typing import TYPE_CHECKING, Final

from mirobot_async._cli.exits import CliError, note
from mirobot_async.errors import MirobotUsageError

if TYPE_CHECKING:
    from mirobot_async._client.client import Mirobot

__all__ = ["PAGE_WAIT", "watched"]

PAGE_WAIT: Final = 60.0
"""Seconds ``run --view`` waits for a page before it moves the arm (then it runs anyway)."""


@contextlib.asynccontextmanager
async def watched(
    arm: Mirobot, args: argparse.Namespace, *, wait_for_page: bool
) -> AsyncIterator[None]:
    """With ``--view``: the view is open inside (its URL on stderr, opened in a browser unless
    ``--no-browser``); ``wait_for_page``: first wait, at most :data:`PAGE_WAIT` s, for a page
    to connect (a short program would end before anyone watched). Without it: nothing."""
    if not getattr(args, "view", False):
        yield
        return
    try:
        view = arm.view(
            open_browser=not args.no_browser, wait_for_page=PAGE_WAIT if wait_for_page else None
        )
    except MirobotUsageError as err:
        raise CliError(str(err)) from None
    if wait_for_page:
        note(f"--view: waits for the page to connect before moving (at most {PAGE_WAIT:g} s)")
    async with view:
        yield
