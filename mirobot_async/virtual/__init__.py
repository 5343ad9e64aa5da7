"""The virtual Mirobot: the emulator's firmware model, served in this process or as a process.

::

    from mirobot_async import Mirobot
    from mirobot_async.virtual import start_emulator

    async with start_emulator(firmware="classic", time_scale=100) as url:
        async with Mirobot.connect(url) as arm:
            await arm.home()

Two ways to run it, one arm:

* **In this process** (:class:`InProcessArm`, or ``start_emulator(in_process=True)``): the pure
  firmware model in the caller's event loop behind the client's transport seam, connected as
  ``virtual://N``. Milliseconds per connection; no serial pacing, faults or control channel. The
  ``mirobot`` commands given no ``--port`` run it, and so do most of the client's own tests.
* **As a process** (:func:`start_emulator`, :class:`EmulatorProcess`; without asyncio
  :func:`run_emulator`, :class:`SyncEmulatorProcess`): ``python -m mirobot_emulator`` (the
  ``mirobot-emulator`` command) on a fresh pseudo-terminal, or with ``listen="tcp"`` on a loopback
  TCP port (``socket://...``; the default where there are no ptys, or everywhere with
  ``MIROBOT_TEST_LINK=tcp``). ``mirobot view`` given no port runs it, and so does the twin of
  ``mirobot mcp --dry-run``; any serial client can open its port. The handle's
  ``await .control("drop-ok")`` arms the emulator's faults (it returns the emulator's ``ack``
  line); ``.kill()`` pulls the cable abruptly; ``.renew(...)`` makes it a new arm in
  milliseconds. :func:`emulator_command` is its command line. The process is stopped when the
  block ends (SIGTERM, then SIGKILL if it does not exit within a few seconds), also when the
  block is cancelled.

The pytest plugin (:mod:`mirobot_async.testing`) hands these out as fixtures. Names are imported
on first use, so importing this module costs no asyncio, subprocess or firmware model.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mirobot_async.virtual._control import EmulatorError, emulator_command
    from mirobot_async.virtual._in_process import InProcessArm
    from mirobot_async.virtual._process import EmulatorProcess, start_emulator
    from mirobot_async.virtual._sync import SyncEmulatorProcess, run_emulator

__all__ = [
    "EmulatorError",
    "EmulatorProcess",
    "InProcessArm",
    "SyncEmulatorProcess",
    "emulator_command",
    "run_emulator",
    "start_emulator",
]

_HOMES = {
    "EmulatorError": "_control",
    "emulator_command": "_control",
    "InProcessArm": "_in_process",  # loads the client's wire module
    "EmulatorProcess": "_process",  # asyncio
    "start_emulator": "_process",
    "SyncEmulatorProcess": "_sync",  # subprocess, threads
    "run_emulator": "_sync",
}


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{home}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
