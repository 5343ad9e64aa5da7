"""The virtual Mirobot's server: the firmware model on a real serial-like port.

What it models
--------------
- **The serial port**, as a pseudo-terminal (:mod:`._pty_port`, POSIX) or, with ``--listen
  HOST:PORT``, a TCP socket (:mod:`._tcp_port`, every platform; ``socket://HOST:PORT`` for
  pyserial and our client). The address is printed as the first line of stdout; clients (ours,
  pyserial, third-party SDKs) open it like ``/dev/ttyUSB0``. ``--link PATH`` adds a symlink to
  the pty. The arm is powered on before the address is published: its power-on banner is already
  in the pty, where the client's open-time flush discards it (on TCP it is lost: nobody was
  connected), as with an arm switched on before the port is opened. The robot's state survives
  reconnects (a real arm does not reset when the port closes). TCP serves one client at a time;
  a second connection is told the port is busy and closed.
- **Reset on open** (``--reset-on-open``): when a client opens the port, the firmware is reset
  (as ``%`` does: settings kept, banner reprinted) and output still in transit is discarded,
  like an Arduino board whose DTR line resets the MCU. On TCP a connection is an open; on a pty
  an open is seen as the client's configuration of the port (see :mod:`._pty_port`): later input
  flushes (the vendor's newer SDK flushes before each status poll) do not reset.
- **The wire speed** (``--baud N``): input and output are paced at N/10 bytes per second (8N1),
  so the firmware's 128-byte receive ring overflows exactly as on the arm when a host sends too
  much. Without ``--baud``, bytes go through as fast as they come.
- **Bounded buffers** (:mod:`._link`): at most 4 KiB in transit to the firmware, and no input is
  taken while 64 KiB of output wait for the client; a client that writes faster than that, or
  writes ``?`` and never reads, is blocked by the OS as by a real port.
- **A USB-serial adapter's latency timer** (``--usb-latency-ms N``, FTDI chips default to 16 ms):
  output is held until it is N ms old or 62 bytes have accumulated. Off by default.
- **Time** (:mod:`.clock`). Simulated time = wall time x ``--time-scale`` (1 by default; 100
  makes a 10 s homing take 0.1 s; 0 completes every motion instantly). The clock can be changed
  while running (control command ``time-scale X``).
- **Faults** (:mod:`mirobot_emulator._faults`): ``--fault SPEC`` flags and the control channel
  (stdin, one command per line, each answered by ``ack <command>`` on stdout, or ``error
  <command>: <reason>``). Data faults act on whole output lines. A stall holds the output (the
  firmware keeps running and the output comes out afterwards). Timed faults count wall-clock
  seconds from the moment the port was created. ``delay`` holds every output line a number of
  milliseconds (order preserved). ``split-bytes`` writes the output one byte per ``write``; on
  a pty the next byte only once the client has read the previous one (watched with
  ``FIONREAD`` on the emulator's own slave fd: the client's reads return single bytes, the
  output then runs at about 20 KB/s, and a client that does not read holds it back); on TCP,
  bytes 0.2 ms apart (reads usually, not always, return one byte).
- **Counters.** The control command ``stats`` is answered ``ack stats NAME=N ...`` with what
  crossed the wire: ``bytes_in``, ``lines_in`` (``\\n`` bytes), ``status_requests_in`` (``?``),
  ``resets_in`` (``%``) received from the client; ``bytes_out`` written to it; the data faults'
  ``oks_seen``, ``dropped_oks``, ``status_lines``, ``corrupted_status``, ``ignored_status``;
  ``split_writes``, ``ports_opened``, ``refused_clients`` (TCP); the buffers' ``input_held``,
  ``input_held_max``, ``output_held``, ``output_held_max`` (bytes now and at most); and the
  firmware's ``rx_lost`` (bytes its receive ring lost). Tests use them to check what a client
  really sent.
- **Renewal.** The control command ``renew ARGS...`` (ARGS: this command line's options but
  ``--listen``, ``--link`` and ``--exit-on-stdin-eof``, shell-quoted) makes the server what a
  new process started with ARGS would be: a new port (a new pty, or a new socket on the same
  ``--listen`` address; a connected client and every byte in flight both ways are dropped), a
  freshly powered-on firmware model, the faults of ARGS only, counters at zero. Answered
  ``ack renew ARGS url=ADDRESS``. Test fixtures use it to reuse one process for many tests
  (:class:`mirobot_async.testing.EmulatorPool`).
- **Ends of motion.** The control command ``motion-ends`` is answered ``ack motion-ends T ...``
  with the ``time.monotonic()`` instants (oldest first, the last 64) at which the firmware's
  planner went from busy to empty, mapped from simulated to wall time exactly.
  ``time.monotonic()`` is system-wide on Linux, so other processes can compare them with their
  own readings.

What it does not model
----------------------
- DTR/RTS lines, break conditions, parity or framing errors, hardware or XON/XOFF flow control.
- The exact byte timing inside a USB packet, USB bus scheduling, or the latency of the host's
  tty layer (a pty adds none) or of TCP.
- A power cycle: ``--reset-on-open`` and the ``reset`` fault are soft resets (exactly what ``%``
  does; the settings survive).
- Anything of the firmware itself: see :mod:`mirobot_emulator.firmware`.

An exception raised by the firmware model is logged (with its traceback, on stderr for the CLI)
and the server keeps serving: a client sees a missing reply, not a vanished port.

Layout: :mod:`.options` (options, the firmware protocol), :mod:`._port` with :mod:`._pty_port`
and :mod:`._tcp_port`, :mod:`.clock` (simulated time), :mod:`._pacing` (baud, USB latency),
:mod:`._link` (both directions, bounded), :mod:`._control` (the control channel), :mod:`.loop`
(:class:`EmulatorServer`) and :mod:`._background` (:class:`VirtualMirobot`). Only this package
(and ``__main__``) does OS calls.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ._background import VirtualMirobot
    from .loop import EmulatorServer
    from .options import FirmwareLike, ServerOptions, parse_listen

__all__ = ["EmulatorServer", "FirmwareLike", "ServerOptions", "VirtualMirobot", "parse_listen"]

_LAZY = {
    "VirtualMirobot": "._background",
    "EmulatorServer": ".loop",
    "FirmwareLike": ".options",
    "ServerOptions": ".options",
    "parse_listen": ".options",
}
"""Imported on first use, so that the in-process arm, which needs only :mod:`.clock`, does not
import the ports, the event loop and the faults (tens of milliseconds)."""


def __getattr__(name: str) -> Any:
    module_name = _LAZY.get(name)
    if module_name is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module_name, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
