"""The control channel: commands in, one answer line per command out.

Commands are the fault commands of :mod:`mirobot_emulator.faults` (``drop-ok``, ``stall``,
``reset``, ``close``, ``time-scale``, ``stats``...) and the server's own queries
(:data:`QUERIES`). Each is answered ``ack <command>[ <result>]`` or ``error <command>: <reason>``.
The CLI reads them from stdin in a thread (:class:`ControlReader`: portable, no selector on a
pipe); :meth:`EmulatorServer.submit <mirobot_emulator.server.EmulatorServer.submit>` takes them
from any thread.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable

__all__ = ["QUERIES", "ControlReader"]

QUERIES = frozenset({"motion-ends"})
"""Commands that ask the server something and change nothing (answered with their result)."""


class ControlReader:
    """Reads control commands from a file descriptor (one per line) in a daemon thread.

    Each non-blank line is handed to ``submit``; at end of file the thread ends (the server keeps
    serving). The thread blocks in ``read`` and is not joined: it ends with the process.
    """

    def __init__(self, fd: int, submit: Callable[[str], None]) -> None:
        self._fd = fd
        self._submit = submit
        self._thread = threading.Thread(target=self._run, name="mirobot-emulator-control")
        self._thread.daemon = True

    def start(self) -> None:
        """Start reading."""
        self._thread.start()

    def _run(self) -> None:
        buffer = b""
        while True:
            try:
                chunk = os.read(self._fd, 4096)
            except InterruptedError:
                continue
            except OSError:
                chunk = b""
            if not chunk:
                if buffer.strip():
                    self._submit(buffer.decode("utf-8", "replace"))
                return
            buffer += chunk
            *lines, buffer = buffer.split(b"\n")
            for line in lines:
                if line.strip():
                    self._submit(line.decode("utf-8", "replace"))
