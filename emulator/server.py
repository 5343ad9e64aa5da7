"""The virtual Mirobot's pty server: the firmware model on a real pseudo-terminal.

What it models
--------------
- **The serial port.** A pseudo-terminal in raw mode (a new pty is cooked: echo, ICANON,
  ONLCR/ICRNL would translate line endings and echo commands back, so the slave is put in raw
  mode right after ``openpty``). The slave's path is printed as the first line of stdout; clients
  (ours, pyserial, third-party SDKs) open it like ``/dev/ttyUSB0``. ``--link PATH`` adds a
  symlink. The arm is powered on before the path is published: its power-on banner is already in
  the port, where the client's open-time flush discards it (as with an arm switched on before
  the port is opened; ``--reset-on-open`` below prints one for each open). The emulator keeps
  its own slave fd open, so clients can close and reopen the port without EIO, and the robot
  state survives reconnects (a real arm does not reset when the port closes).
- **Reset on open** (``--reset-on-open``): the master is in packet mode (``TIOCPKT``), so it sees
  the ``tcflush(TCIFLUSH)`` that pyserial (and most serial libraries) do when they open a port. That
  flush is taken as "the port was opened" and, with this option, resets the firmware (as ``%``
  does: settings kept, banner reprinted) and discards output still in transit, like an Arduino
  board whose DTR line resets the MCU. DTR itself cannot be seen on a pty: this is the only reset
  on open modelled, and any later input flush by the client resets again.
- **The wire speed** (``--baud N``): input and output are paced at N/10 bytes per second (8N1).
  The kernel buffers ~16 KiB either way, so the pacing is done here: input read from the master is
  queued and released to the firmware at the baud rate, so the firmware's 128-byte receive ring
  overflows exactly as on the arm when a host sends too much. Without ``--baud``, bytes go through
  as fast as they come.
- **A USB-serial adapter's latency timer** (``--usb-latency-ms N``, FTDI chips default to 16 ms):
  output is held until it is N ms old or 62 bytes have accumulated. Off by default.
- **Time.** Simulated time = wall time x ``--time-scale`` (1 by default; 100 makes a 10 s homing
  take 0.1 s; 0 completes every motion instantly: the firmware is run until nothing changes by
  itself after every input line, so a ``?`` written right after a move sees it done). The clock
  can be changed while running (control command ``time-scale X``). The loop sleeps until input
  arrives, output can be written, or the firmware's next internal change is due.
- **Faults** (:mod:`mirobot_emulator.faults`): ``--fault SPEC`` flags and the stdin control
  channel (one command per line, each answered by ``ack <command>`` on stdout, or
  ``error <command>: <reason>``). Data faults act on whole output lines; the server splits the
  firmware's output into lines for them (a line is only sent once its ``\\n`` has been produced).
  A stall holds the output (the firmware keeps running and the output comes out afterwards).
  Timed faults count wall-clock seconds from the moment the port was created.
- **Counters.** The control command ``stats`` is answered ``ack stats NAME=N ...`` with what
  crossed the wire: ``bytes_in``, ``lines_in`` (``\\n`` bytes), ``status_requests_in`` (``?``),
  ``resets_in`` (``%``) received from the client; ``bytes_out`` written to it; the data faults'
  ``oks_seen``, ``dropped_oks``, ``status_lines``, ``corrupted_status``, ``ignored_status``;
  ``split_writes`` and ``ports_opened``. Tests use them to check what a client really sent.
- **Ends of motion.** The control command ``motion-ends`` is answered ``ack motion-ends T ...``
  with the ``time.monotonic()`` instants (oldest first, the last :data:`MOTION_END_HISTORY`) at
  which the firmware's planner went from busy to empty. They are the firmware's simulated end
  instants mapped to wall time through the clock (``wall = anchor + sim / time-scale``, exact
  to the float), not the moments the loop noticed; at ``--time-scale 0`` motion has no duration
  and the instant is when the loop ran it. ``time.monotonic()`` is system-wide on Linux, so
  other processes can compare them with their own readings.
- **Link faults.** ``delay`` holds every output line for a number of wall-clock milliseconds
  (order preserved; the firmware keeps running). ``split-bytes`` writes the output one byte per
  ``write``, and writes the next byte only once the previous one has reached the port and been
  read by the client (watched with ``FIONREAD`` on the emulator's own slave fd), so the client's
  reads return single bytes. That costs some tens of microseconds per byte (the output then
  runs at about 20 KB/s), and a client that does not read holds the output back (the emulator
  keeps serving input meanwhile).

What it does not model
----------------------
- DTR/RTS lines, break conditions, parity or framing errors, hardware or XON/XOFF flow control.
- The exact byte timing inside a USB packet, USB bus scheduling, or the latency of the host's
  tty layer (a pty adds none).
- A power cycle: ``--reset-on-open`` and the ``reset`` fault are soft resets (exactly what ``%``
  does; the settings survive).
- Anything of the firmware itself: see :mod:`mirobot_emulator.firmware`.

An exception raised by the firmware model is logged (with its traceback, on stderr for the CLI)
and the server keeps serving: a client sees a missing reply, not a vanished port.

Only this module (and ``__main__``) does OS calls. It is a plain ``selectors`` loop (no asyncio),
so it can also run in a thread of the process under test (:class:`VirtualMirobot`).
"""

from __future__ import annotations

import array
import contextlib
import errno
import fcntl
import math
import os
import re
import selectors
import struct
import termios
import time
import tty
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

from .faults import (
    Command,
    Fault,
    FaultFilter,
    FaultSchedule,
    FaultSpecError,
    OutputDelay,
    link_commands,
    parse_command,
)

if TYPE_CHECKING:
    import threading
    from types import TracebackType

__all__ = [
    "EmulatorServer",
    "FirmwareLike",
    "ServerOptions",
    "VirtualMirobot",
    "run_server",
]

TIOCPKT = getattr(termios, "TIOCPKT", 0x5420)
TIOCPKT_FLUSHREAD = getattr(termios, "TIOCPKT_FLUSHREAD", 1)
USB_PACKET_PAYLOAD = 62  # FTDI full-speed packet: 64 bytes, 2 of them modem status
MAX_LOGGED_ERRORS = 5  # tracebacks of firmware-model exceptions written to the log
PACING_GRANULARITY_S = 0.002  # paced bytes are released in chunks of about this duration
# split-bytes: a written byte reaches the slave's input queue asynchronously (the kernel pushes
# the pty's flip buffer from a work queue, usually within microseconds): wait this long at most
# to see it arrive there. Waits poll FIONREAD: busily for SPLIT_SPIN_S (a reading client takes
# a few microseconds per byte, time.sleep costs ~60), then every SPLIT_POLL_S.
SPLIT_LANDING_S = 0.0003
SPLIT_SPIN_S = 0.0003
SPLIT_POLL_S = 0.0001
MOTION_END_HISTORY = 64  # ends of motion answered to the ``motion-ends`` control command
SPLIT_READ_WAIT_S = 0.002  # wait this long for the client to read a byte just written, ...
SPLIT_RETRY_S = 0.001  # ... else look again this much later (from the loop)
SPLIT_BUDGET_S = 0.005  # write bytes for at most this long, then serve input again


class FirmwareLike(Protocol):
    """What the server needs of :class:`mirobot_emulator.firmware.Firmware`."""

    @property
    def now(self) -> float: ...

    def receive(self, data: bytes) -> None: ...

    def advance(self, dt: float) -> None: ...  # dt may be math.inf: until nothing changes

    def read_output(self) -> bytes: ...

    def next_deadline(self) -> float | None: ...

    def reset(self) -> None: ...

    def trigger_hard_limit(self, axis: int = 1) -> None: ...


@dataclass(frozen=True, slots=True)
class ServerOptions:
    """The command-line options of ``mirobot-emulator`` (see ``--help``)."""

    firmware: str = "2021"
    time_scale: float = 1.0
    link: str | None = None
    baud: int | None = None
    reset_on_open: bool = False
    usb_latency_ms: float = 0.0
    seed: int = 0
    faults: tuple[Fault, ...] = field(default_factory=tuple)
    homing_seconds: float | None = None


_OUTPUT_LINES = re.compile(rb"[^\n]*\n")  # output lines, each with its ending
_LINE_PIECES = re.compile(rb"[^\r\n]*[\r\n]|[^\r\n]+")  # input cut after each line end


class _Segment:
    __slots__ = ("data", "offset", "start")

    def __init__(self, start: float, data: bytes) -> None:
        self.start = start  # when the byte at ``offset`` starts its transmission
        self.data = data
        self.offset = 0


class _Pacer:
    """Bytes through a serial wire: each byte takes 10/baud seconds after the previous one.

    With ``baud=None`` it is a pass-through. Bytes pushed at time t start their transmission at t
    or when the wire is free; :meth:`pop` returns those fully transmitted by ``now``.
    """

    def __init__(self, baud: int | None) -> None:
        self._byte_time = 10.0 / baud if baud else 0.0
        self._chunk = max(1, int(PACING_GRANULARITY_S / self._byte_time)) if baud else 0
        self._segments: deque[_Segment] = deque()
        self._busy_until = -math.inf
        self._direct = bytearray()

    def __len__(self) -> int:
        return len(self._direct) + sum(len(s.data) - s.offset for s in self._segments)

    def push(self, data: bytes, now: float) -> None:
        if not data:
            return
        if not self._byte_time:
            self._direct += data
            return
        start = max(now, self._busy_until)
        self._segments.append(_Segment(start, bytes(data)))
        self._busy_until = start + len(data) * self._byte_time

    def pop(self, now: float) -> bytes:
        if not self._byte_time:
            direct = bytes(self._direct)
            self._direct.clear()
            return direct
        out = bytearray()
        while self._segments:
            seg = self._segments[0]
            ready = int((now - seg.start) / self._byte_time + 1e-6)
            if ready <= 0:
                break
            take = min(ready, len(seg.data) - seg.offset)
            out += seg.data[seg.offset : seg.offset + take]
            if seg.offset + take >= len(seg.data):
                self._segments.popleft()
                continue
            seg.start += take * self._byte_time
            seg.offset += take
            break
        return bytes(out)

    def next_time(self) -> float | None:
        if not self._segments:
            return None
        seg = self._segments[0]
        return seg.start + self._byte_time * min(self._chunk, len(seg.data) - seg.offset)

    def clear(self) -> None:
        self._segments.clear()
        self._direct.clear()
        self._busy_until = -math.inf


class _LatencyBuffer:
    """An FTDI-like latency timer: output waits until it is ``latency`` s old or fills a packet."""

    def __init__(self, latency: float) -> None:
        self._latency = latency
        self._buf = bytearray()
        self._since = 0.0

    def push(self, data: bytes, now: float) -> None:
        if data and not self._buf:
            self._since = now
        self._buf += data

    def pop(self, now: float) -> bytes:
        if self._latency <= 0:
            everything = bytes(self._buf)
            self._buf.clear()
            return everything
        out = bytearray()
        while len(self._buf) >= USB_PACKET_PAYLOAD:
            out += self._buf[:USB_PACKET_PAYLOAD]
            del self._buf[:USB_PACKET_PAYLOAD]
            self._since = now
        if self._buf and now - self._since >= self._latency - 1e-9:
            out += self._buf
            self._buf.clear()
        return bytes(out)

    def next_time(self) -> float | None:
        if self._latency <= 0 or not self._buf:
            return None
        return self._since + self._latency

    def clear(self) -> None:
        self._buf.clear()


def _default_firmware_factory(options: ServerOptions) -> Callable[[], FirmwareLike]:
    def make() -> FirmwareLike:
        # Imported here: the firmware pulls in numpy (kinematics); the pty path is printed first.
        # (importlib keeps the type checker to the FirmwareLike protocol.)
        import importlib

        module = importlib.import_module(".firmware", __package__)
        firmware: FirmwareLike = module.Firmware(
            options.firmware, homing_seconds=options.homing_seconds
        )
        return firmware

    return make


class EmulatorServer:
    """A firmware model served on a pseudo-terminal.

    ``open()`` creates the pty, powers the firmware on (the banner goes into the port), creates
    the link and returns the slave path, ready to be opened; ``serve()`` runs the
    loop until :meth:`request_stop` (thread- and signal-safe) or a ``close`` fault, and returns
    ``"stopped"`` or ``"closed"``; ``close()`` releases everything (idempotent). Control commands
    come from ``control_fd`` (the CLI passes stdin) and/or :meth:`submit` (thread-safe); each is
    answered by calling ``on_reply`` with ``"ack <command>"`` or ``"error <command>: <reason>"``.
    """

    def __init__(
        self,
        options: ServerOptions,
        *,
        firmware_factory: Callable[[], FirmwareLike] | None = None,
        on_reply: Callable[[str], None] | None = None,
        control_fd: int | None = None,
        log: Callable[[str], None] | None = None,
    ) -> None:
        if options.time_scale < 0 or not math.isfinite(options.time_scale):
            raise ValueError("time_scale must be a finite number >= 0")
        if options.baud is not None and options.baud <= 0:
            raise ValueError("baud must be positive")
        if options.usb_latency_ms < 0:
            raise ValueError("usb_latency_ms must be >= 0")
        self.options = options
        self._factory = firmware_factory or _default_firmware_factory(options)
        self._on_reply = on_reply
        self._control_fd = control_fd
        self._log = log or (lambda message: None)
        self.firmware: FirmwareLike | None = None
        self.path: str | None = None
        self._master = -1
        self._slave = -1
        self._wake_r = -1
        self._wake_w = -1
        self._link_made = False
        self._stop = False
        self._result = "stopped"
        self._commands: deque[tuple[str, Callable[[str], None] | None]] = deque()
        self._control_buf = bytearray()
        # Clock: simulated = sim_anchor + (wall - wall_anchor) * scale.
        self._scale = options.time_scale
        self._wall_anchor = 0.0
        self._sim_anchor = 0.0
        self._start = 0.0
        # Data path: firmware -> lines -> faults -> delay -> stall -> wire pacing -> USB latency
        # -> master (one byte per write with split-bytes).
        self._filter = FaultFilter(options.faults, seed=options.seed)
        self._schedule = FaultSchedule(options.faults)
        self._delay = OutputDelay()
        self._split = False
        self.split_writes = 0  # bytes written one by one (split-bytes)
        self.bytes_in = 0  # bytes received from the client (before pacing and faults)
        self.lines_in = 0  # b"\n" among them
        self.status_requests_in = 0  # b"?" among them
        self.resets_in = 0  # b"%" among them
        self.bytes_out = 0  # bytes written to the client (the power-on banner included)
        self._partial = bytearray()
        self._stalled = bytearray()
        self._stall_until = -math.inf
        self._out_wire = _Pacer(options.baud)
        self._usb = _LatencyBuffer(options.usb_latency_ms / 1000.0)
        self._wbuf = bytearray()
        self._in_wire = _Pacer(options.baud)
        self._master_eio_until = -math.inf
        self.ports_opened = 0  # input flushes seen (a client opening the port)
        self.firmware_errors = 0  # exceptions raised by the firmware model (logged, survived)
        # Ends of motion (wall clock), read from the firmware's motion_end_times after each run.
        self.motion_end_walls: deque[float] = deque(maxlen=MOTION_END_HISTORY)
        self._motion_ends_seen = 0

    # ------------------------------------------------------------------ lifecycle
    def open(self) -> str:
        """Create the port and power the arm on; return the slave's path, ready to be opened.

        The pty is made raw, then put in packet mode; the firmware is built and its power-on
        output (the banner) is written into the port at once, before the path is published: a
        client's open-time flush discards it, as with an arm powered on before the port is opened
        (``--reset-on-open`` prints a fresh one). Then the link is created.
        """
        if self.path is not None:
            return self.path
        master, slave = os.openpty()
        try:
            tty.setraw(slave)  # before packet mode: the termios change must not make a packet
            fcntl.ioctl(master, TIOCPKT, struct.pack("i", 1))
            os.set_blocking(master, False)
            os.set_inheritable(master, False)
            os.set_inheritable(slave, False)
            path = os.ttyname(slave)
        except BaseException:
            os.close(master)
            os.close(slave)
            raise
        self._master, self._slave = master, slave
        self._wake_r, self._wake_w = os.pipe2(os.O_NONBLOCK | os.O_CLOEXEC)
        self.path = path
        if self.firmware is None:
            self.firmware = self._factory()
        now = time.monotonic()
        self._start = self._wall_anchor = now
        self._sim_anchor = self.firmware.now
        # Power-on output: not paced, not delayed, not subject to faults (it happened "before").
        self._partial += self.firmware.read_output()
        end = self._partial.rfind(b"\n") + 1
        self._wbuf += self._partial[:end]
        del self._partial[:end]
        self._write_master()
        for command in link_commands(self.options.faults):  # from now on, not the banner
            self._apply(command, now)
        if self.options.link:
            self._make_link(self.options.link, path)
        return path

    def _make_link(self, link: str, target: str) -> None:
        if os.path.lexists(link) and not os.path.islink(link):
            raise FileExistsError(f"--link {link}: exists and is not a symlink, not replacing it")
        tmp = f"{link}.{os.getpid()}.tmp"
        os.symlink(target, tmp)
        os.replace(tmp, link)  # atomic, replaces a stale link from an earlier run
        self._link_made = True

    def close(self) -> None:
        """Close the pty and the wake pipe, remove the link (only if it still points to us)."""
        if self._link_made and self.options.link:
            self._link_made = False
            try:
                if os.readlink(self.options.link) == self.path:
                    os.unlink(self.options.link)
            except OSError:
                pass
        for name in ("_master", "_slave", "_wake_r", "_wake_w"):
            fd = getattr(self, name)
            if fd >= 0:
                setattr(self, name, -1)
                with contextlib.suppress(OSError):
                    os.close(fd)

    def __enter__(self) -> EmulatorServer:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def request_stop(self) -> None:
        """Make :meth:`serve` return soon. Safe from a signal handler or another thread."""
        self._stop = True
        self._wake()

    def submit(self, command: str, reply: Callable[[str], None] | None = None) -> None:
        """Queue a control command (thread-safe); ``reply`` (or ``on_reply``) gets the answer."""
        self._commands.append((command, reply))
        self._wake()

    def _wake(self) -> None:
        if self._wake_w >= 0:
            with contextlib.suppress(OSError):  # full (already awake) or closed
                os.write(self._wake_w, b"!")

    def _guard(self, func: Callable[..., object], *args: object) -> bool:
        """Call ``func``; if the firmware model raises, log it and keep serving (False)."""
        try:
            func(*args)
        except Exception:
            self._firmware_error()
            return False
        return True

    def _firmware_error(self) -> None:
        import traceback

        self.firmware_errors += 1
        if self.firmware_errors <= MAX_LOGGED_ERRORS:
            self._log("internal error (the emulator keeps serving):\n" + traceback.format_exc())
        elif self.firmware_errors == MAX_LOGGED_ERRORS + 1:
            self._log("more internal errors; not logging them any more")

    # ------------------------------------------------------------------ clock
    def _sim_time(self, wall: float) -> float:
        return self._sim_anchor + (wall - self._wall_anchor) * self._scale

    def _set_scale(self, scale: float, wall: float) -> None:
        fw = self.firmware
        assert fw is not None
        self._sync_clock(wall)
        self._sim_anchor = fw.now
        self._wall_anchor = wall
        self._scale = scale

    def _sync_clock(self, wall: float) -> None:
        fw = self.firmware
        assert fw is not None
        if self._scale > 0:
            target = self._sim_time(wall)
            if target > fw.now:
                fw.advance(target - fw.now)
                self._collect_motion_ends(wall)
        else:
            self._run_to_idle()

    def _run_to_idle(self) -> None:
        """--time-scale 0: run the firmware until nothing changes by itself (motion done)."""
        fw = self.firmware
        assert fw is not None
        if fw.next_deadline() is not None:
            fw.advance(math.inf)  # the firmware's "until nothing changes"; its clock stays finite
            self._collect_motion_ends(time.monotonic())

    def _collect_motion_ends(self, wall: float) -> None:
        """Map the firmware's new ends of motion (simulated) to wall time; ``wall`` is now.

        Called right after each ``advance``, before the clock's anchors can change, so the
        mapping in force during the run is the one used.
        """
        fw = self.firmware
        ends = getattr(fw, "motion_end_times", None)  # optional: not part of FirmwareLike
        total = getattr(fw, "motion_ends", None)
        if ends is None or not isinstance(total, int):
            return
        if total < self._motion_ends_seen:  # a new firmware object
            self._motion_ends_seen = 0
        new = min(total - self._motion_ends_seen, len(ends))
        self._motion_ends_seen = total
        if new <= 0:
            return
        for sim in list(ends)[len(ends) - new :]:
            if self._scale > 0:
                self.motion_end_walls.append(
                    self._wall_anchor + (float(sim) - self._sim_anchor) / self._scale
                )
            else:
                self.motion_end_walls.append(wall)

    # ------------------------------------------------------------------ loop
    def serve(self) -> str:
        """Run until stopped; return ``"stopped"`` or ``"closed"`` (a close fault)."""
        self.open()
        selector = (
            selectors.PollSelector()
            if hasattr(selectors, "PollSelector")
            else (selectors.DefaultSelector())
        )
        try:
            selector.register(self._wake_r, selectors.EVENT_READ, "wake")
            master_events = selectors.EVENT_READ
            selector.register(self._master, master_events, "master")
            if self._control_fd is not None:
                try:
                    selector.register(self._control_fd, selectors.EVENT_READ, "control")
                except (OSError, ValueError) as exc:
                    self._log(f"control channel unavailable: {exc}")
            # A client may have opened the port already (while the firmware was being built):
            # see its open-time flush before the power-on output goes out.
            self._read_master()
            while not self._stop:
                now = time.monotonic()
                self._guard(self._step, now)
                if self._stop or self._master < 0:
                    break
                want = selectors.EVENT_READ if now >= self._master_eio_until else 0
                if self._wbuf and not (self._split and self._slave_unread()):
                    want |= selectors.EVENT_WRITE
                if want != master_events:
                    if master_events and want:
                        selector.modify(self._master, want, "master")
                    elif want:
                        selector.register(self._master, want, "master")
                    else:
                        selector.unregister(self._master)
                    master_events = want
                try:
                    timeout = self._timeout(now)
                except Exception:
                    self._firmware_error()
                    timeout = 0.05  # do not spin on a broken firmware
                for key, events in selector.select(timeout):
                    if key.data == "wake":
                        self._drain_wake()
                    elif key.data == "master":
                        if events & selectors.EVENT_READ:
                            self._read_master()
                        if events & selectors.EVENT_WRITE and self._master >= 0:
                            self._write_master()
                    elif key.data == "control" and not self._read_control():
                        selector.unregister(key.fd)
                    if self._master < 0:
                        break
                while self._commands and not self._stop:
                    text, reply = self._commands.popleft()
                    self._handle_command(text, reply)
        finally:
            selector.close()
        return self._result

    def _step(self, now: float) -> None:
        fw = self.firmware
        assert fw is not None
        for command in self._schedule.due(now - self._start):
            self._log(f"timed fault: {command.text}")
            self._apply(command, now)
            if self._master < 0:
                return
        self._sync_clock(now)
        data = self._in_wire.pop(now)
        if data:
            data = self._filter.input_bytes(data)
            if data and self._scale == 0:
                # Instant motion: each line's motion is over before the next byte arrives, so
                # a "?" written right after a move already sees it done.
                for piece in _LINE_PIECES.findall(data):
                    fw.receive(piece)
                    self._run_to_idle()
            elif data:
                fw.receive(data)
        self._collect_output(now)
        self._flush_output(now)

    def _timeout(self, now: float) -> float | None:
        times: list[float] = []
        fw = self.firmware
        assert fw is not None
        if self._scale > 0:
            deadline = fw.next_deadline()
            if deadline is not None:
                times.append(self._wall_anchor + (deadline - self._sim_anchor) / self._scale)
        for t in (self._in_wire.next_time(), self._out_wire.next_time(), self._usb.next_time()):
            if t is not None:
                times.append(t)
        if self._stalled:
            times.append(self._stall_until)
        delayed = self._delay.next_time()
        if delayed is not None:
            times.append(delayed)
        if self._split and self._wbuf:
            times.append(now + SPLIT_RETRY_S)
        if self._master_eio_until > now:
            times.append(self._master_eio_until)
        due = self._schedule.next_time()
        if due is not None:
            times.append(self._start + due)
        if not times:
            return None
        return max(0.0, min(times) - now)

    # ------------------------------------------------------------------ output path
    def _collect_output(self, now: float) -> None:
        fw = self.firmware
        assert fw is not None
        out = fw.read_output()
        if not out:
            return
        self._partial += out
        end = self._partial.rfind(b"\n")
        if end < 0:
            return
        complete = bytes(self._partial[: end + 1])
        del self._partial[: end + 1]
        for line in _OUTPUT_LINES.findall(complete):
            kept = self._filter.output_line(line)
            if kept:
                self._delay.push(kept, now)

    def _flush_output(self, now: float) -> None:
        released = self._delay.pop(now)
        if released:
            self._stalled += released
        if self._stalled and now >= self._stall_until:
            self._out_wire.push(bytes(self._stalled), now)
            self._stalled.clear()
        wired = self._out_wire.pop(now)
        if wired:
            self._usb.push(wired, now)
        delivered = self._usb.pop(now)
        if delivered:
            self._wbuf += delivered
        if self._wbuf:
            self._write_master()

    def _write_master(self) -> None:
        if self._master < 0 or not self._wbuf:
            return
        if self._split:
            self._write_split()
            return
        written = self._write_some(self._wbuf)
        del self._wbuf[:written]

    def _write_some(self, data: bytes | bytearray) -> int:
        """One ``write`` to the master; returns the number of bytes taken (0: try later)."""
        try:
            written = os.write(self._master, data)
        except BlockingIOError:
            return 0
        except OSError as exc:
            if exc.errno == errno.EIO:  # no slave open: keep the bytes, retry a bit later
                self._master_eio_until = time.monotonic() + 0.05
                return 0
            raise
        self.bytes_out += written
        return written

    def _write_split(self) -> None:
        """split-bytes: one byte per write, the next only once the client has read it.

        Returns after ``SPLIT_BUDGET_S`` (the loop serves input, then calls again) or when the
        client has not read the last byte ``SPLIT_READ_WAIT_S`` after it was written (the loop
        looks again every ``SPLIT_RETRY_S``; a client that does not read costs one ``ioctl``).
        """
        start = -math.inf  # when the last byte landed in the port: none in this call
        deadline = time.monotonic() + SPLIT_BUDGET_S
        while self._wbuf and self._master >= 0:
            if self._slave_unread():  # the client has not read the last byte yet
                waited = time.monotonic() - start
                if waited >= SPLIT_READ_WAIT_S or time.monotonic() >= deadline:
                    return
                if waited >= SPLIT_SPIN_S:
                    time.sleep(SPLIT_POLL_S)
                continue
            if not self._write_some(self._wbuf[:1]):
                return
            del self._wbuf[:1]
            self.split_writes += 1
            # Let the byte reach the slave's input queue before looking whether it was read:
            # otherwise the next byte could join it there and the client read both at once.
            start = time.monotonic()
            landing = start + SPLIT_LANDING_S
            while not self._slave_unread() and time.monotonic() < landing:
                pass
            if time.monotonic() >= deadline:
                return

    def _slave_unread(self) -> int:
        """Bytes waiting in the port for the client to read (0 if unknown)."""
        if self._slave < 0:
            return 0
        count = array.array("i", [0])
        try:
            fcntl.ioctl(self._slave, termios.FIONREAD, count)
        except OSError:
            return 0
        return count[0]

    def _discard_output(self) -> None:
        self._partial.clear()
        self._delay.clear()
        self._stalled.clear()
        self._out_wire.clear()
        self._usb.clear()
        self._wbuf.clear()
        self._in_wire.clear()

    # ------------------------------------------------------------------ input path
    def _read_master(self) -> None:
        try:
            packet = os.read(self._master, 65536)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno == errno.EIO:
                self._master_eio_until = time.monotonic() + 0.05
                return
            raise
        if not packet:
            return
        control, data = packet[0], packet[1:]
        now = time.monotonic()
        if control & TIOCPKT_FLUSHREAD:
            self.ports_opened += 1
            if self.options.reset_on_open:
                fw = self.firmware
                assert fw is not None
                self._log("port opened: reset")
                self._discard_output()
                fw.read_output()  # the reset wipes whatever the firmware had not printed yet
                self._guard(fw.reset)
        if data:
            self.bytes_in += len(data)
            self.lines_in += data.count(b"\n")
            self.status_requests_in += data.count(b"?")
            self.resets_in += data.count(b"%")
            self._in_wire.push(data, now)

    def _drain_wake(self) -> None:
        try:
            while os.read(self._wake_r, 4096):
                pass
        except OSError:
            pass

    # ------------------------------------------------------------------ control channel
    def _read_control(self) -> bool:
        fd = self._control_fd
        assert fd is not None
        try:
            chunk = os.read(fd, 4096)
        except BlockingIOError:
            return True
        except OSError:
            chunk = b""
        if not chunk:
            if self._control_buf.strip():
                self._handle_command(self._control_buf.decode("utf-8", "replace"), None)
            self._control_buf.clear()
            return False  # EOF: stop reading the control channel, keep serving
        self._control_buf += chunk
        while b"\n" in self._control_buf:
            line, _, rest = bytes(self._control_buf).partition(b"\n")
            self._control_buf[:] = rest
            if line.strip():
                self._handle_command(line.decode("utf-8", "replace"), None)
        return True

    def _handle_command(self, text: str, reply: Callable[[str], None] | None) -> None:
        answer = reply or self._on_reply
        words = text.split()
        if words and words[0].lower() == "motion-ends":
            # A query of the server itself (not a fault): see "Ends of motion" above.
            if len(words) > 1:
                if answer:
                    answer(f"error {text.strip()}: motion-ends takes no argument")
                return
            if self.firmware is not None and self._master >= 0:
                self._guard(self._sync_clock, time.monotonic())
            if answer:
                answer(" ".join(["ack motion-ends", *(f"{t:.6f}" for t in self.motion_end_walls)]))
            return
        try:
            command = parse_command(text)
        except FaultSpecError as exc:
            if answer:
                answer(f"error {text.strip()}: {exc}")
            return
        now = time.monotonic()
        if not self._guard(self._apply, command, now):
            if answer:
                answer(f"error {command.text}: the firmware model raised (see stderr)")
            return
        if self._master >= 0:
            self._guard(self._collect_output, now)
        if answer:
            extra = f" {self.stats_text()}" if command.kind == "stats" else ""
            answer(f"ack {command.text}{extra}")

    def stats(self) -> dict[str, int]:
        """The counters answered to the ``stats`` command (see the module docstring)."""
        flt = self._filter
        return {
            "bytes_in": self.bytes_in,
            "lines_in": self.lines_in,
            "status_requests_in": self.status_requests_in,
            "resets_in": self.resets_in,
            "bytes_out": self.bytes_out,
            "oks_seen": flt.oks_seen,
            "dropped_oks": flt.dropped_oks,
            "status_lines": flt.status_lines_seen,
            "corrupted_status": flt.corrupted_status_lines,
            "ignored_status": flt.ignored_status_requests,
            "split_writes": self.split_writes,
            "ports_opened": self.ports_opened,
        }

    def stats_text(self) -> str:
        """:meth:`stats` as ``name=value`` words."""
        return " ".join(f"{name}={value}" for name, value in self.stats().items())

    def _apply(self, command: Command, now: float) -> None:
        fw = self.firmware
        assert fw is not None
        if self._filter.apply(command) or command.kind == "stats":
            return
        if command.kind == "stall":
            self._stall_until = max(self._stall_until, now + command.value)
        elif command.kind == "hard-limit":
            self._sync_clock(now)
            fw.trigger_hard_limit(command.count)
        elif command.kind == "reset":
            self._sync_clock(now)
            fw.reset()
        elif command.kind == "time-scale":
            self._set_scale(command.value, now)
        elif command.kind == "delay":
            self._delay.delay = command.value
        elif command.kind == "split-bytes":
            self._split = bool(command.count)
        elif command.kind == "close":
            self._close_link()

    def _close_link(self) -> None:
        """The cable is pulled: close the master (clients see a hangup), then stop serving."""
        self._log("closing the port")
        for name in ("_master", "_slave"):
            fd = getattr(self, name)
            if fd >= 0:
                setattr(self, name, -1)
                os.close(fd)
        self._result = "closed"
        self._stop = True


def run_server(
    options: ServerOptions,
    *,
    on_path: Callable[[str], None] | None = None,
    on_reply: Callable[[str], None] | None = None,
    control_fd: int | None = None,
    log: Callable[[str], None] | None = None,
    install_signal_handlers: bool = False,
) -> str:
    """Open the pty, report its path through ``on_path``, serve until stopped; return the reason.

    With ``install_signal_handlers`` (main thread only), SIGINT and SIGTERM stop the server
    cleanly. The link, if any, is removed on return.
    """
    server = EmulatorServer(options, on_reply=on_reply, control_fd=control_fd, log=log)
    try:
        path = server.open()
        if install_signal_handlers:
            import signal

            def stop(signum: int, frame: object) -> None:
                server.request_stop()

            signal.signal(signal.SIGINT, stop)
            signal.signal(signal.SIGTERM, stop)
        if on_path:
            on_path(path)
        return server.serve()
    finally:
        server.close()


class VirtualMirobot:
    """A virtual Mirobot served from a background thread of this process.

    ::

        with VirtualMirobot(ServerOptions(firmware="classic", time_scale=0)) as robot:
            port = serial.Serial(robot.path, 115200)
            robot.command("drop-ok 1")

    The firmware runs in the server thread: read :attr:`firmware` only for a quick look.
    """

    def __init__(
        self,
        options: ServerOptions | None = None,
        *,
        firmware_factory: Callable[[], FirmwareLike] | None = None,
    ) -> None:
        self.options = options or ServerOptions()
        self._server = EmulatorServer(self.options, firmware_factory=firmware_factory)
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self.result: str | None = None

    @property
    def path(self) -> str:
        assert self._server.path is not None, "not started"
        return self._server.path

    @property
    def firmware(self) -> FirmwareLike | None:
        return self._server.firmware

    @property
    def server(self) -> EmulatorServer:
        """The server (its counters: ``split_writes``, ``ports_opened``, ``firmware_errors``)."""
        return self._server

    def start(self) -> str:
        import threading

        path = self._server.open()  # builds the firmware: errors surface in the caller
        self._thread = threading.Thread(target=self._run, name="mirobot-emulator", daemon=True)
        self._thread.start()
        return path

    def _run(self) -> None:
        try:
            self.result = self._server.serve()
        except BaseException as exc:  # reported by stop()
            self._error = exc

    def command(self, text: str, timeout: float = 5.0) -> str:
        """Run a control command in the server thread; return its answer (``ack ...``)."""
        import threading

        done = threading.Event()
        answers: list[str] = []

        def reply(answer: str) -> None:
            answers.append(answer)
            done.set()

        self._server.submit(text, reply)
        if not done.wait(timeout):
            raise TimeoutError(f"no answer to {text!r} within {timeout} s")
        return answers[0]

    def stop(self, timeout: float = 5.0) -> None:
        self._server.request_stop()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
        self._server.close()
        if self._error is not None:
            error, self._error = self._error, None
            raise error

    def __enter__(self) -> VirtualMirobot:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
