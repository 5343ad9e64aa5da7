"""The serve loop: a firmware model behind a port (pty or TCP), one ``selectors`` loop.

No asyncio and no signals: the loop can run in the main thread of ``mirobot-emulator`` or in a
background thread of the process under test (:class:`~mirobot_emulator.server.VirtualMirobot`).
It sleeps until input arrives, output can be written, a control command comes, or the next
change is due (the firmware's, the wire's, a timed fault's).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import selectors
import shlex
import socket
import sys
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from .._faults import (
    Command,
    FaultFilter,
    FaultSchedule,
    FaultSpecError,
    link_commands,
    parse_command,
)
from ._control import QUERIES, RENEW, ControlReader, answer_query, wire_counters
from ._link import InputPath, OutputPath
from ._port import Arrival, Port
from .clock import Simulation
from .options import FirmwareLike, ServerOptions

__all__ = ["EmulatorServer"]

LANDING_TIMEOUT_S = 0.2  # the power-on output reaches a pty's input queue in microseconds
MAX_LOGGED_ERRORS = 5  # tracebacks of firmware-model exceptions written to the log
# Where a signal handler cannot interrupt select() (Windows), the loop wakes this often to see
# a stop requested from one.
_MAX_SLEEP_S = 0.25 if sys.platform == "win32" else None
# The longest one select() waits: a far deadline (a dwell of days, a feed of 0.0001, a stall of
# years) is reached by waking again, never by a timeout select() cannot take (OverflowError).
LONGEST_WAIT_S = 60.0


def _default_firmware_factory(options: ServerOptions) -> Callable[[], FirmwareLike]:
    def make() -> FirmwareLike:
        # Imported here: the firmware pulls in numpy (kinematics). (importlib keeps the type
        # checker to the FirmwareLike protocol.)
        import importlib

        firmware: FirmwareLike
        if options.bus:  # a bus of controllers, each with its arm, in place of one arm
            bus = importlib.import_module("..bus", __package__)
            firmware = bus.Bus(
                options.bus,
                options.firmware,
                homing_seconds=options.homing_seconds,
                baud=options.bus_baud,
                options=bus.BusOptions.parse(options.bus_options),
            )
        else:
            module = importlib.import_module("..firmware", __package__)
            firmware = module.Firmware(options.firmware, homing_seconds=options.homing_seconds)
        return firmware

    return make


def _make_link(link: str, target: str) -> None:
    """A symlink ``link`` -> ``target``, replacing a stale one atomically (never a file)."""
    if os.path.lexists(link) and not os.path.islink(link):
        raise FileExistsError(f"--link {link}: exists and is not a symlink, not replacing it")
    tmp = f"{link}.{os.getpid()}.tmp"
    os.symlink(target, tmp)
    os.replace(tmp, link)  # atomic, replaces a stale link from an earlier run


def _wait_until_landed(port: Port, written: int) -> None:
    """Wait (briefly) until the ``written`` bytes are in the port for the client to read (a pty
    moves them there asynchronously), so that a client opening it afterwards flushes them all."""
    deadline = time.monotonic() + LANDING_TIMEOUT_S
    while (unread := port.unread()) is not None and unread < written:
        if time.monotonic() >= deadline:
            return
        time.sleep(0.0001)


def _bounded_wait(times: list[float], now: float) -> float | None:
    """Seconds from ``now`` to the earliest of ``times`` (None: none), at most
    :data:`LONGEST_WAIT_S` (an infinite or nan deadline too)."""
    if not times:
        return None
    wait = min(times) - now
    return max(0.0, wait) if wait < LONGEST_WAIT_S else LONGEST_WAIT_S


def _unregister(selector: selectors.BaseSelector, fileobjs: Iterable[Any]) -> None:
    """Take ``fileobjs`` out of ``selector`` (those already gone or closed too)."""
    for fileobj in fileobjs:
        with contextlib.suppress(KeyError, ValueError, OSError):
            selector.unregister(fileobj)


def _make_port(options: ServerOptions, log: Callable[[str], None]) -> Port:
    if options.listen is not None:
        from ._tcp_port import TcpPort

        return TcpPort(*options.listen, log=log)
    from ._pty_port import PtyPort

    return PtyPort(log=log)


class EmulatorServer:
    """A firmware model served on a pseudo-terminal or, with ``options.listen``, a TCP socket.

    ``open()`` creates the port, powers the firmware on (the banner goes into the port), creates
    the link and returns the address to open (the pty's path or ``socket://HOST:PORT``);
    ``serve()`` runs the loop until :meth:`request_stop` (thread- and signal-safe) or a ``close``
    fault, and returns ``"stopped"`` or ``"closed"``; ``close()`` releases everything
    (idempotent). Control commands come from ``control_fd`` (the CLI passes stdin; read in a
    thread) and/or :meth:`submit` (thread-safe); each is answered by calling ``on_reply`` (or the
    ``reply`` given to :meth:`submit`) with ``"ack <command>"`` or ``"error <command>: ..."``.
    With ``stop_on_control_eof`` the end of ``control_fd`` stops the server (its owner is gone).
    ``renew_parser`` turns the arguments of the ``renew`` control command into options (the
    CLI's own parser): see :meth:`renew`.
    """

    def __init__(
        self,
        options: ServerOptions,
        *,
        firmware_factory: Callable[[], FirmwareLike] | None = None,
        on_reply: Callable[[str], None] | None = None,
        control_fd: int | None = None,
        log: Callable[[str], None] | None = None,
        stop_on_control_eof: bool = False,
        renew_parser: Callable[[Sequence[str]], ServerOptions] | None = None,
    ) -> None:
        options.check()
        self.options = options
        self._custom_factory = firmware_factory
        self._factory = firmware_factory or _default_firmware_factory(options)
        self._on_reply = on_reply
        self._control_fd = control_fd
        self._stop_on_control_eof = stop_on_control_eof
        self._renew_parser = renew_parser
        self._log = log or (lambda message: None)
        self.path: str | None = None
        """The address clients open: the pty's path, or ``socket://HOST:PORT``."""
        self.port: Port = _make_port(options, self._log)
        self.sim: Simulation | None = None
        self._wake_r: socket.socket | None = None
        self._wake_w: socket.socket | None = None
        self._link_made = False
        self._stop = False
        self._stop_when_idle = False  # stop once the queued control commands are answered
        self._result = "stopped"
        self._commands: deque[tuple[str, Callable[[str], None] | None]] = deque()
        self._selector: selectors.BaseSelector | None = None  # while serving
        self._watched: dict[Any, int] = {}  # the port's registrations in the selector
        self._start = 0.0
        self._build_paths(options)

    def _build_paths(self, options: ServerOptions) -> None:
        """The fault filter and schedule, both directions of the wire, the counters: all new."""
        self._filter = FaultFilter(options.faults, seed=options.seed)
        self._schedule = FaultSchedule(options.faults)
        self.input = InputPath(options.baud, self._filter)
        self.output = OutputPath(options.baud, options.usb_latency_ms / 1000.0, self._filter)
        self.ports_opened = 0  # clients that opened the port
        self.firmware_errors = 0  # exceptions raised by the firmware model (logged, survived)

    @property
    def firmware(self) -> FirmwareLike | None:
        """The firmware model (None before :meth:`open`); read it from the loop's thread."""
        return self.sim.firmware if self.sim is not None else None

    @property
    def split_writes(self) -> int:
        """Bytes written one by one (split-bytes)."""
        return self.output.split_writes

    @property
    def motion_end_walls(self) -> deque[float]:
        """Ends of motion on the wall clock (see :class:`~.clock.Simulation`)."""
        return self.sim.motion_end_walls if self.sim is not None else deque()

    # ------------------------------------------------------------------ lifecycle
    def open(self) -> str:
        """Create the port and power the arm on; return the address, ready to be opened.

        The firmware's power-on output (the banner) goes into the port at once, before the
        address is published: a client's open-time flush discards it, as with an arm powered on
        before the port is opened (``--reset-on-open`` prints a fresh one). Then the link is
        created.
        """
        if self.path is not None:
            return self.path
        path = self.port.open()
        self._wake_r, self._wake_w = socket.socketpair()
        for sock in (self._wake_r, self._wake_w):
            sock.setblocking(False)
        self.path = path
        if self.sim is None:
            firmware = self._factory()
            self.sim = Simulation(
                firmware, self.options.time_scale, time.monotonic(), self.options.baud
            )
        self._power_on()
        if self.options.link:
            _make_link(self.options.link, path)
            self._link_made = True
        if self._control_fd is not None:
            on_eof = self._stop_after_commands if self._stop_on_control_eof else None
            ControlReader(self._control_fd, self.submit, on_eof=on_eof).start()
        return path

    def _power_on(self) -> None:
        """The banner into the port; timed faults count from now; the link faults armed."""
        assert self.sim is not None
        self._start = time.monotonic()
        self.output.power_on(self.sim.firmware.read_output())
        self.output.write_to(self.port)
        _wait_until_landed(self.port, self.output.bytes_out)
        for command in link_commands(self.options.faults):  # from now on, not the banner
            self._apply(command, self._start)
        if self.options.reset_on_open and not getattr(self.port, "sees_opens", True):
            self._log("this platform's pty does not report opens: --reset-on-open has no effect")

    def renew(self, options: ServerOptions) -> str:
        """Become what a new process with ``options`` would be; return the new port's address.

        A new port (a new pty, or a new listening socket on the same ``listen`` address: a
        connected client and every byte in flight both ways are dropped), a freshly powered-on
        firmware model (its banner in the port), new fault filter and schedule, wire paths and
        counters. ``options.listen`` is replaced by this server's (its kind cannot change);
        :class:`ValueError` if the options cannot be served or this server made a ``link``
        (nothing has changed then). Call it from the loop's thread (the ``renew`` command does).
        """
        if self.options.link or options.link:
            raise ValueError("a server with a link (--link) cannot be renewed: start a new one")
        options = dataclasses.replace(options, listen=self.options.listen)
        options.check()
        factory = self._custom_factory or _default_firmware_factory(options)
        firmware = factory()  # before anything is torn down: a failure changes nothing
        if self._selector is not None:  # the port's file objects out, before they are closed
            _unregister(self._selector, self._watched)
        self._watched = {}
        self.port.close()
        self.options, self._factory = options, factory
        self.port = _make_port(options, self._log)
        self.path = self.port.open()
        self.sim = Simulation(firmware, options.time_scale, time.monotonic(), options.baud)
        self._build_paths(options)
        self._power_on()
        return self.path

    def close(self) -> None:
        """Close the port and the wake sockets, remove the link (only if it still points here)."""
        if self._link_made and self.options.link:
            self._link_made = False
            with contextlib.suppress(OSError):
                if os.readlink(self.options.link) == self.path:
                    os.unlink(self.options.link)
        self.port.close()
        for sock in (self._wake_r, self._wake_w):
            if sock is not None:
                sock.close()

    def __enter__(self) -> EmulatorServer:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def request_stop(self) -> None:
        """Make :meth:`serve` return soon. Safe from a signal handler or another thread."""
        self._stop = True
        self._wake()

    def _stop_after_commands(self) -> None:
        """Stop once every command submitted so far is answered (thread-safe)."""
        self._stop_when_idle = True
        self._wake()

    def submit(self, command: str, reply: Callable[[str], None] | None = None) -> None:
        """Queue a control command (thread-safe); ``reply`` (or ``on_reply``) gets the answer."""
        self._commands.append((command, reply))
        self._wake()

    def _wake(self) -> None:
        if self._wake_w is not None:
            with contextlib.suppress(OSError):  # full (already awake) or closed
                self._wake_w.send(b"!")

    def _guard(self, func: Callable[..., object], *args: object) -> bool:
        """Call ``func``; if the firmware model raises, log it and keep serving (False)."""
        try:
            func(*args)
        except Exception:
            self._firmware_error()
            return False
        return True

    def _firmware_error(self) -> None:
        self.firmware_errors += 1
        if self.firmware_errors <= MAX_LOGGED_ERRORS:
            self._log("internal error (the emulator keeps serving):\n" + traceback.format_exc())
        elif self.firmware_errors == MAX_LOGGED_ERRORS + 1:
            self._log("more internal errors; not logging them any more")

    # ------------------------------------------------------------------ loop
    def serve(self) -> str:
        """Run until stopped; return ``"stopped"`` or ``"closed"`` (a close fault)."""
        self.open()
        assert self._wake_r is not None
        selector = self._selector = selectors.DefaultSelector()
        self._watched = {}
        try:
            selector.register(self._wake_r, selectors.EVENT_READ, "wake")
            # A client may have opened the port already (while the firmware was being built):
            # see its open before the power-on output goes out.
            self._take(self.port.on_ready(None, selectors.EVENT_READ, self.input.room()))
            while not self._stop:
                now = time.monotonic()
                self._guard(self._step, now)
                if self._stop or not self.port.is_open:
                    break
                self._watched = self._watch(selector, self._watched)
                try:
                    timeout = self._timeout(now)
                except Exception:
                    self._firmware_error()
                    timeout = 0.05  # do not spin on a broken firmware
                for key, events in selector.select(timeout):
                    if key.data == "wake":
                        self._drain_wake()
                    elif self.port.is_open:
                        self._on_port_ready(key.fileobj, events)
                while self._commands and not self._stop:
                    text, reply = self._commands.popleft()
                    self._handle_command(text, reply)
                if self._stop_when_idle and not self._commands:
                    self._stop = True
        finally:
            self._selector = None
            selector.close()
        return self._result

    def _watch(self, selector: selectors.BaseSelector, watched: dict[Any, int]) -> dict[Any, int]:
        """Bring the selector's registrations of the port to what is wanted now."""
        want = self.port.watches(
            read=not self.output.full and self.input.room() > 0,
            write=self.output.wants_write(self.port),
        )
        _unregister(selector, watched.keys() - want.keys())
        for fileobj, events in want.items():
            if fileobj not in watched:
                selector.register(fileobj, events, "port")
            elif watched[fileobj] != events:
                selector.modify(fileobj, events, "port")
        return want

    def _on_port_ready(self, fileobj: Any, events: int) -> None:
        room = 0 if self.output.full else self.input.room()
        self._take(self.port.on_ready(fileobj, events, room))
        if events & selectors.EVENT_WRITE:
            self.output.write_to(self.port)

    def _take(self, arrival: Arrival) -> None:
        """Act on what came in through the port: opens first, then the client's bytes."""
        if not arrival:
            return
        now = time.monotonic()
        if arrival.opened:
            self.ports_opened += arrival.opened
            if self.options.reset_on_open and self.sim is not None:
                self._log("port opened: reset")
                self.output.discard()
                self.input.clear()
                self.sim.firmware.read_output()  # the reset wipes what was not printed yet
                self._guard(self.sim.firmware.reset)
        if arrival.closed:
            self.output.discard()  # on its way to a client that is gone
        self.input.push(arrival.data, now)

    def _drain_wake(self) -> None:
        assert self._wake_r is not None
        with contextlib.suppress(OSError):
            while self._wake_r.recv(4096):
                pass

    def _step(self, now: float) -> None:
        sim = self.sim
        assert sim is not None
        for command in self._schedule.due(now - self._start):
            self._log(f"timed fault: {command.text}")
            self._apply(command, now)
            if not self.port.is_open:
                return
        self._take(self.port.poll(now))
        data = self.input.pop(now)
        sim.deliver(data, self.input.crossed_at, now)
        self.output.collect(sim.firmware.read_output(), now)
        self.output.release(now)
        self.output.write_to(self.port)

    def _timeout(self, now: float) -> float | None:
        sim = self.sim
        assert sim is not None
        times = [
            t
            for t in (
                sim.next_wall_deadline(),
                self.input.next_time(),
                self.output.next_time(now),
                self.port.next_time(),
            )
            if t is not None
        ]
        due = self._schedule.next_time()
        if due is not None:
            times.append(self._start + due)
        if _MAX_SLEEP_S is not None:
            times.append(now + _MAX_SLEEP_S)
        return _bounded_wait(times, now)

    # ------------------------------------------------------------------ control channel
    def _handle_command(self, text: str, reply: Callable[[str], None] | None) -> None:
        answer = reply or self._on_reply or (lambda line: None)
        words = text.split()
        if words and words[0].lower() == RENEW:
            answer(self._renew_command(text))
            return
        if words and words[0].lower() in QUERIES:  # asks the server, changes nothing
            if self.sim is not None and self.port.is_open:
                self._guard(self.sim.sync, time.monotonic())  # the present, not the last step
            answer(answer_query(words, self.motion_end_walls, self.firmware))
            return
        try:
            command = parse_command(text)
        except FaultSpecError as exc:
            answer(f"error {text.strip()}: {exc}")
            return
        now = time.monotonic()
        if not self._guard(self._apply, command, now):
            answer(f"error {command.text}: the firmware model raised (see stderr)")
            return
        if self.sim is not None and self.port.is_open:
            self._guard(self.output.collect, self.sim.firmware.read_output(), now)
        extra = f" {self.stats_text()}" if command.kind == "stats" else ""
        answer(f"ack {command.text}{extra}")

    def _renew_command(self, text: str) -> str:
        """Answer ``renew ARGS...`` (ARGS: the command line's options, shell-quoted)."""
        text = text.strip()
        if self._renew_parser is None:
            return f"error {text}: this server cannot parse options (renew is the CLI's)"
        try:
            options = self._renew_parser(shlex.split(text)[1:])
            address = self.renew(options)
        except ValueError as exc:
            return f"error {text}: {exc}"
        except OSError as exc:  # the new port: the old one is gone, the server stops
            self._log(f"renew: cannot create the port: {exc}")
            return f"error {text}: cannot create the port: {exc}"
        except Exception:
            self._firmware_error()
            return f"error {text}: the firmware model raised (see stderr)"
        return f"ack {text} url={address}"

    def stats(self) -> dict[str, int]:
        """The counters answered to the ``stats`` command (see the package docstring)."""
        return wire_counters(
            self._filter,
            self.input,
            self.output,
            ports_opened=self.ports_opened,
            refused_clients=int(getattr(self.port, "refused", 0)),
            firmware=self.firmware,
        )

    def stats_text(self) -> str:
        """:meth:`stats` as ``name=value`` words."""
        return " ".join(f"{name}={value}" for name, value in self.stats().items())

    def _apply(self, command: Command, now: float) -> None:
        sim = self.sim
        assert sim is not None
        if self._filter.apply(command) or command.kind == "stats":
            return
        if command.kind == "stall":
            self.output.stall(now + command.value)
        elif command.kind == "hard-limit":
            sim.sync(now)
            sim.firmware.trigger_hard_limit(command.count)
        elif command.kind == "reset":
            sim.sync(now)
            sim.firmware.reset()
        elif command.kind == "time-scale":
            sim.set_scale(command.value, now)
        elif command.kind == "delay":
            self.output.delay.delay = command.value
        elif command.kind == "split-bytes":
            self.output.split = bool(command.count)
        elif command.kind == "close":
            self._log("closing the port")
            self.port.hang_up()
            self._result = "closed"
            self._stop = True
