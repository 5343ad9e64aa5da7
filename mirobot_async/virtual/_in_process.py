"""A virtual Mirobot inside this process: the pure firmware model, no pty, no subprocess.

::

    from mirobot_async import Mirobot
    from mirobot_async.virtual import start_emulator

    async with start_emulator(firmware="classic", time_scale=0, in_process=True) as url:
        async with Mirobot.connect(url) as arm:         # url is "virtual://1"
            await arm.home()

:class:`InProcessArm` holds one :class:`mirobot_emulator.firmware.Firmware` and its clock (the
same :class:`mirobot_emulator.server.clock.Simulation` the ``mirobot-emulator`` process runs), and
serves it to :meth:`Mirobot.connect <mirobot_async.Mirobot.connect>` under a ``virtual://N`` URL
through the client's transport seam, as httpx's ``MockTransport`` and python-can's ``VirtualBus``
do. Bytes the client writes reach the firmware at once; its output is delivered on the next turn
of the event loop, and a timer of the loop runs the firmware's clock to its next change by itself
(motion ends, homing, reports). Time scale 0 makes every motion complete at once, as with the
process. What it does not model: the serial line's pacing (``--baud``, USB latency) and the
process's fault injection and control channel (use :class:`~mirobot_async.virtual.EmulatorProcess`
for those, and to prove the transport itself).

The arm keeps its state between connections, like a powered arm whose cable is plugged again;
one client at a time (a second one fails to connect, as a locked serial port does). Closing the
arm (the end of the ``with`` block) ends a connected client's link, as a process exit does.
"""

from __future__ import annotations

import asyncio
import importlib
import itertools
import math
from typing import TYPE_CHECKING, Final, Protocol

from mirobot_async._client.wire import (
    IN_PROCESS_SCHEME,
    DataCallback,
    LostCallback,
    register_in_process,
    unregister_in_process,
)
from mirobot_async.errors import MirobotConnectionError, MirobotUsageError

if TYPE_CHECKING:
    from types import TracebackType

__all__ = ["InProcessArm"]


class _FirmwareModel(Protocol):
    """What this module uses of :class:`mirobot_emulator.firmware.Firmware`."""

    state: str
    joints: tuple[float, ...]
    now: float

    def read_output(self) -> bytes: ...


class _Clock(Protocol):
    """What this module uses of :class:`mirobot_emulator.server.clock.Simulation`."""

    def sync(self, wall: float) -> None: ...

    def feed(self, data: bytes) -> None: ...

    def next_wall_deadline(self) -> float | None: ...


FIRMWARES: Final = ("2021", "classic", "2024")
_numbers = itertools.count(1)


class InProcessArm:
    """One virtual Mirobot in this process, reachable as :attr:`url` while open.

    ``firmware`` is ``"2021"``, ``"classic"`` or ``"2024"``; ``time_scale`` is simulated seconds
    per wall
    second (0: motion completes at once, 1: real time). ``homing_seconds`` overrides the
    duration of the homing search (``None``: the profile's). Use it as a (sync or async)
    context manager, or call :meth:`open` and :meth:`close`.
    """

    def __init__(
        self,
        firmware: str = "2021",
        time_scale: float = 0.0,
        *,
        homing_seconds: float | None = None,
    ) -> None:
        if firmware not in FIRMWARES:
            raise MirobotUsageError(f"firmware={firmware!r} must be one of {FIRMWARES}")
        if not (isinstance(time_scale, int | float) and math.isfinite(time_scale)) or (
            time_scale < 0
        ):
            raise MirobotUsageError(f"time_scale={time_scale!r} must be a number >= 0")
        # Imported here: the firmware model pulls in numpy (kinematics), and the modules that
        # offer this class (mirobot_async.virtual, the pytest plugin) stay cheap to import.
        # (importlib keeps the type checker to the protocols above: the client does not depend
        # on the emulator's package.)
        model = importlib.import_module("mirobot_emulator.firmware")
        clock = importlib.import_module("mirobot_emulator.server.clock")

        self.firmware_name = firmware
        self.time_scale = float(time_scale)
        self._firmware: _FirmwareModel = model.Firmware(firmware, homing_seconds=homing_seconds)
        self._sim: _Clock = clock.Simulation(self._firmware, self.time_scale, _now())
        self.url = f"{IN_PROCESS_SCHEME}{next(_numbers)}"
        self._link: _InProcessLink | None = None
        self._open = False

    # ---- lifecycle ----

    def open(self) -> str:
        """Make :attr:`url` connectable; return it."""
        if not self._open:
            register_in_process(self.url, self._connect)
            self._open = True
        return self.url

    def close(self) -> None:
        """Stop serving: a connected client's link ends (its pending calls fail at once)."""
        if self._open:
            unregister_in_process(self.url)
            self._open = False
        link, self._link = self._link, None
        if link is not None:
            link.end(ConnectionResetError(f"the virtual Mirobot {self.url} was closed"))

    def __enter__(self) -> InProcessArm:
        self.open()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    async def __aenter__(self) -> InProcessArm:
        return self.__enter__()

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # ---- what tests may look at ----

    @property
    def state(self) -> str:
        """The firmware's state word now (``Idle``, ``Run``, ``Home``, ``Alarm``...)."""
        self._sim.sync(_now())
        return str(self._firmware.state)

    @property
    def joints(self) -> tuple[float, ...]:
        """Where the arm stands now: J1..J6 in degrees, then the rail in mm."""
        self._sim.sync(_now())
        return tuple(self._firmware.joints)

    # ---- the transport seam ----

    async def _connect(
        self, url: str, *, on_data: DataCallback, on_lost: LostCallback, timeout: float
    ) -> _InProcessLink:
        if self._link is not None and not self._link.closed:
            raise MirobotConnectionError(
                f"{url}: the virtual Mirobot is busy (another client has it open)"
            )
        # What the arm printed before this host opened the port is gone, as a serial port's
        # flush at open discards it.
        self._sim.sync(_now())
        self._firmware.read_output()
        link = _InProcessLink(self, asyncio.get_running_loop(), on_data, on_lost)
        self._link = link
        return link


def _now() -> float:
    """The clock the simulation runs on: the event loop's (monotonic), also outside a loop."""
    import time

    return time.monotonic()


class _InProcessLink:
    """The client's end of an :class:`InProcessArm`: a
    :class:`~mirobot_async._client.wire.Transport`."""

    link_kind = "virtual"
    """What a recorded tape's header calls this link (``connect(record=...)``)."""

    def __init__(
        self,
        arm: InProcessArm,
        loop: asyncio.AbstractEventLoop,
        on_data: DataCallback,
        on_lost: LostCallback,
    ) -> None:
        self.status_min_gap: float | None = 0.0 if arm.time_scale == 0 else None
        """How far apart the client's ``?`` must be. At time scale 0 (nothing takes wall time) a
        report is printed the instant its ``?`` arrives: no gap. When the arm moves in wall time,
        ``None``: the client's gap on a port (2 ms), so that waiting for the arm costs no more
        CPU than it does with an emulator process."""
        self._arm = arm
        self._loop = loop
        self._on_data = on_data
        self._on_lost = on_lost
        self._timer: asyncio.TimerHandle | None = None
        self._wake_at = 0.0
        self._delivery: asyncio.Handle | None = None
        self._output: list[tuple[float, bytes]] = []  # (simulated instant printed, bytes)
        self._instant = arm._firmware.now
        self.time_scale = arm.time_scale
        self.firmware_profile = arm.firmware_name  # a recorded tape's family, if not detected
        self.closed = False

    # Transport protocol

    def write(self, data: bytes) -> None:
        """Hand ``data`` to the firmware now; its answer arrives on a later loop turn."""
        if self.closed or not data:
            return
        sim = self._arm._sim
        sim.sync(_now())
        self._instant = self._arm._firmware.now
        sim.feed(bytes(data))
        self._collect()

    def clock(self) -> float:
        """The arm's simulated clock (seconds since its power-on) at the bytes being written or
        delivered now: a recorded tape's instants (``connect(record=...)``), so that a replay
        into the firmware model feeds each byte when this arm took it."""
        return self._instant

    def abort(self) -> None:
        """Drop the link at once (the client closes it: no ``on_lost``)."""
        self._stop()

    async def close(self) -> None:
        """Drop the link (nothing to wait for in-process)."""
        self._stop()

    # internals

    def _stop(self) -> None:
        self.closed = True
        for handle in (self._timer, self._delivery):
            if handle is not None:
                handle.cancel()
        self._timer = self._delivery = None
        self._output.clear()
        if self._arm._link is self:
            self._arm._link = None

    def end(self, exc: BaseException) -> None:
        """The arm went away: the client hears of it once, as from a closed port."""
        if self.closed:
            return
        self._stop()
        self._loop.call_soon_threadsafe(self._on_lost, exc)

    def _collect(self) -> None:
        """Take the firmware's output, deliver it soon, and wake at its next change."""
        out = self._arm._firmware.read_output()
        if out:
            self._output.append((self._arm._firmware.now, out))
            if self._delivery is None:
                self._delivery = self._loop.call_soon(self._deliver)
        self._schedule()

    def _deliver(self) -> None:
        self._delivery = None
        chunks, self._output = self._output, []
        for instant, data in chunks:
            if self.closed:
                return
            self._instant = instant
            self._on_data(data)

    def _schedule(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        if self.closed:
            return
        wall = self._arm._sim.next_wall_deadline()
        if wall is not None:
            # The loop's clock is time.monotonic() (asyncio's default); a deadline in the past
            # runs on the next turn.
            self._wake_at = wall
            self._timer = self._loop.call_at(max(wall, self._loop.time()), self._tick)

    def _tick(self) -> None:
        self._timer = None
        if self.closed:
            return
        # asyncio may run a timer up to its clock resolution early: run the firmware at least
        # to the change it was set for, so that it never wakes again for the same one.
        self._arm._sim.sync(max(_now(), self._wake_at))
        self._collect()
