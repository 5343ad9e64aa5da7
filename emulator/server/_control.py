"""The control channel: commands in, one answer line per command out.

Commands are the fault commands of :mod:`mirobot_emulator._faults` (``drop-ok``, ``stall``,
``reset``, ``close``, ``time-scale``, ``stats``...), the server's own queries (:data:`QUERIES`)
and :data:`RENEW`. Each is answered ``ack <command>[ <result>]`` or ``error <command>: <reason>``.
The CLI reads them from stdin in a thread (:class:`ControlReader`: portable, no selector on a
pipe); :meth:`EmulatorServer.submit <mirobot_emulator.server.EmulatorServer.submit>` takes them
from any thread.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .._faults import FaultFilter
    from ._link import InputPath, OutputPath

__all__ = [
    "QUERIES",
    "RENEW",
    "ControlReader",
    "answer_query",
    "planner_counters",
    "wire_counters",
]

QUERIES = frozenset({"motion-ends", "starvations"})
"""Commands that ask the server something and change nothing (answered with their result):

``motion-ends``  ``ack motion-ends T ...``: the wall-clock ends of motion, oldest first;
``starvations``  ``ack starvations N``: the times the firmware's planner stood still for want
                 of blocks, then more came (lines arrived too late to blend); the planner's other
                 counters are in ``stats``.
"""

RENEW = "renew"
"""``renew ARGS...``: become what a new process started with the options ARGS would be (a new
port, a fresh power-on, no faults armed, counters at zero; ``--listen``, ``--link`` and
``--exit-on-stdin-eof`` cannot change). ARGS are shell-quoted. Answered ``ack renew ARGS
url=ADDRESS`` with the new port's address (see
:meth:`EmulatorServer.renew <mirobot_emulator.server.EmulatorServer.renew>`)."""


def planner_counters(firmware: object) -> dict[str, int]:
    """The planner's public counters, if the firmware model exposes its planner (else empty).

    ``starvations`` (stopped for want of blocks, then more came), ``run_outs`` (ran empty at
    all) and ``starved_ms`` (simulated milliseconds stood still in starvations, rounded).
    """
    planner = getattr(firmware, "planner", None)
    starvations = getattr(planner, "starvations", None)
    if not isinstance(starvations, int):
        return {}
    counters = {"starvations": starvations}
    run_outs = getattr(planner, "run_outs", None)
    if isinstance(run_outs, int):
        counters["run_outs"] = run_outs
    starved = getattr(planner, "starved_seconds", None)
    if isinstance(starved, int | float):
        counters["starved_ms"] = round(starved * 1000)
    return counters


def wire_counters(
    fault_filter: FaultFilter,
    link_in: InputPath,
    link_out: OutputPath,
    *,
    ports_opened: int,
    refused_clients: int,
    firmware: object,
) -> dict[str, int]:
    """The counters of the ``stats`` command: what crossed the wire, what the faults did, what
    the buffers held, and the firmware's lost bytes and planner counters (when it has them)."""
    counters = {
        "bytes_in": link_in.bytes_in,
        "lines_in": link_in.lines_in,
        "status_requests_in": link_in.status_requests_in,
        "resets_in": link_in.resets_in,
        "bytes_out": link_out.bytes_out,
        "oks_seen": fault_filter.oks_seen,
        "dropped_oks": fault_filter.dropped_oks,
        "status_lines": fault_filter.status_lines_seen,
        "corrupted_status": fault_filter.corrupted_status_lines,
        "ignored_status": fault_filter.ignored_status_requests,
        "split_writes": link_out.split_writes,
        "ports_opened": ports_opened,
        "refused_clients": refused_clients,
        "input_held": link_in.held(),
        "input_held_max": link_in.held_max,
        "output_held": link_out.held(),
        "output_held_max": link_out.held_max,
    }
    rx_lost = getattr(firmware, "rx_lost", None)
    if isinstance(rx_lost, int):
        counters["rx_lost"] = rx_lost
    counters.update(planner_counters(firmware))
    return counters


def answer_query(words: list[str], motion_end_walls: Iterable[float], firmware: object) -> str:
    """The answer line to a query (``words[0]`` in :data:`QUERIES`)."""
    kind, text = words[0].lower(), " ".join(words)
    if len(words) > 1:
        return f"error {text}: {kind} takes no argument"
    if kind == "motion-ends":
        return " ".join(["ack motion-ends", *(f"{t:.6f}" for t in motion_end_walls)])
    counters = planner_counters(firmware)
    if "starvations" not in counters:
        return f"error {text}: this firmware model does not count its planner's starvations"
    return f"ack starvations {counters['starvations']}"


class ControlReader:
    """Reads control commands from a file descriptor (one per line) in a daemon thread.

    Each non-blank line is handed to ``submit``; at end of file the thread calls ``on_eof`` (if
    given: e.g. stop the server, whose owner has gone) and ends; else the server keeps serving.
    The thread blocks in ``read`` and is not joined: it ends with the process.
    """

    def __init__(
        self,
        fd: int,
        submit: Callable[[str], None],
        on_eof: Callable[[], None] | None = None,
    ) -> None:
        self._fd = fd
        self._submit = submit
        self._on_eof = on_eof
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
                if self._on_eof is not None:
                    self._on_eof()
                return
            buffer += chunk
            *lines, buffer = buffer.split(b"\n")
            for line in lines:
                if line.strip():
                    self._submit(line.decode("utf-8", "replace"))
