""":class:`ControllerBus`: several arms behind WLKATA multi-function controllers on one RS485 bus.

::

    async with ControllerBus.open("/dev/ttyUSB0") as bus:        # 38400 8N1
        arm1, arm2 = await bus.connect_arm(1), await bus.connect_arm(2)
        await asyncio.gather(arm1.move_joints(j1=30), arm2.move_joints(j1=-30))
        await bus.controller(1).home()                            # O105=8

See :mod:`mirobot_async.bus._link` for how requests share the bus.
"""

from __future__ import annotations

from collections.abc import Generator
from os import PathLike
from typing import TYPE_CHECKING, Any

from mirobot_async._client.client import CONNECT_TIMEOUT, STATUS_TIMEOUT, Connector, Mirobot
from mirobot_async._client.condition import Firmware
from mirobot_async._client.wire import DataCallback, LostCallback, Transport
from mirobot_async.bus._controller import Controller
from mirobot_async.bus._link import DEFAULT_BUS_BAUD, BusStats, BusTiming, LinkSide
from mirobot_async.errors import MirobotConnectionError, MirobotUsageError

if TYPE_CHECKING:
    from mirobot_async._safety.envelope import Envelope

__all__ = [
    "ArmConnector",
    "ArmTransport",
    "BusOpener",
    "ControllerBus",
    "SingleArmConnector",
    "connect",
]


def _check_address(address: int) -> int:
    if isinstance(address, bool) or not isinstance(address, int) or not 1 <= address <= 99:
        raise MirobotUsageError(f"address={address!r}: a controller's address is 1..99")
    return address


class ArmTransport:
    """One arm's virtual link (a :class:`~mirobot_async._client.wire.Transport`): lines and realtime
    bytes become requests to its node; the node's replies reach the arm's client."""

    link_kind = "bus"
    """What a recorded tape's header calls this link (``connect(record=...)``)."""

    def __init__(self, side: LinkSide, address: int) -> None:
        self._side = side
        self.address = address
        self._closed = False

    def write(self, data: bytes) -> None:
        """A line (``...\\n``) or one realtime byte from the arm's client; never blocks."""
        if self._closed:
            return
        chunk = bytes(data)
        if chunk in (b"?", b"!", b"~", b"%"):
            self._side.submit_realtime(self.address, chunk)
        else:
            for line in chunk.replace(b"\r", b"\n").split(b"\n"):
                if line:
                    self._side.submit_line(self.address, line)

    def abort(self) -> None:
        """Detach from the bus: queued lines are dropped, owed replies consumed there."""
        if not self._closed:
            self._closed = True
            self._side.detach(self.address)

    async def close(self) -> None:
        """As :meth:`abort` (the bus itself stays open)."""
        self.abort()


class BusOpener:
    """What :meth:`ControllerBus.open` returns: ``await`` it or use it with ``async with``."""

    def __init__(self, bus: ControllerBus, baud: int, exclusive: bool, timeout: float) -> None:
        self._bus = bus
        self._args = (baud, exclusive, timeout)

    def __await__(self) -> Generator[Any, None, ControllerBus]:
        return self._bus._start(*self._args).__await__()

    async def __aenter__(self) -> ControllerBus:
        return await self._bus._start(*self._args)

    async def __aexit__(self, *exc_info: object) -> None:
        await self._bus.close()


class ControllerBus:
    """The master of an RS485 bus of controllers (addresses 1..99), each with its arm.

    Open it with :meth:`open`. :meth:`connect_arm` gives a full :class:`Mirobot` per address
    (every method works, lines addressed ``@<n>``), :meth:`controller` the controller's own
    commands. Everything may be called concurrently from many tasks of one event loop.
    """

    def __init__(self, url: str, *, timing: BusTiming | None = None, line_end: str = "\r\n"):
        if line_end not in ("\r\n", "\n"):
            raise MirobotUsageError(f"line_end={line_end!r} must be '\\r\\n' or '\\n'")
        self.url = url
        self._timing = timing or BusTiming()
        self._line_end = line_end.encode()
        self._side: LinkSide | None = None
        self._controllers: dict[int, Controller] = {}
        self._arms: dict[int, Mirobot] = {}

    @classmethod
    def open(
        cls,
        url: str,
        *,
        baud: int = DEFAULT_BUS_BAUD,
        timing: BusTiming | None = None,
        line_end: str = "\r\n",
        exclusive: bool = True,
        timeout: float = CONNECT_TIMEOUT,
    ) -> BusOpener:
        """Open the bus at ``url`` (a USB-RS485 adapter, a pty...) at ``baud`` 8N1.

        ``line_end`` is what ends each request: ``"\\r\\n"`` (default: the manual and every
        vendor client) or ``"\\n"`` (half the arm's ``ok`` lines; whether a real controller
        takes it is unknown). Raises :class:`MirobotConnectionError` when the port cannot be
        opened within ``timeout`` seconds. Nothing is sent until an arm or controller is used.
        """
        return BusOpener(cls(url, timing=timing, line_end=line_end), baud, exclusive, timeout)

    async def _start(self, baud: int, exclusive: bool, timeout: float) -> ControllerBus:
        if self._side is not None:
            raise MirobotUsageError("this ControllerBus is already open")
        side = self._side = LinkSide(self.url, self._timing, self._line_end)
        await side.open(baud, exclusive, timeout)
        return self

    async def close(self) -> None:
        """Close every arm's client and the link; idempotent. Pending calls fail with
        :class:`MirobotLinkLostError`."""
        for arm in list(self._arms.values()):
            await arm.close()
        if self._side is not None:
            await self._side.close()

    async def __aenter__(self) -> ControllerBus:
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.close()

    @property
    def stats(self) -> BusStats:
        """The bus's counters (requests, bytes, stray lines, probes, silent nodes)."""
        return self._link().stats

    @property
    def timing(self) -> BusTiming:
        """The bus's time limits (may be changed while open)."""
        return self._timing

    def _link(self) -> LinkSide:
        if self._side is None:
            raise MirobotUsageError("the ControllerBus is not open; use ControllerBus.open(url)")
        return self._side

    def controller(self, address: int) -> Controller:
        """The controller at ``address`` (no I/O; the same object for the same address)."""
        _check_address(address)
        side = self._link()
        found = self._controllers.get(address)
        if found is None:
            found = self._controllers[address] = Controller(side, address, self._moved)
        return found

    def _moved(self, old: int, new: int) -> None:
        controller = self._controllers.pop(old)
        self._controllers[new] = controller
        if old in self._arms:
            self._arms[new] = self._arms.pop(old)

    def arm(
        self,
        address: int,
        *,
        firmware: Firmware | None = None,
        timeout: float | None = CONNECT_TIMEOUT,
        envelope: Envelope | None = None,
        status_timeout: float = STATUS_TIMEOUT,
        probe: bool = True,
        record: str | PathLike[str] | None = None,
    ) -> ArmConnector:
        """``Mirobot.connect(...)``-like connector for the arm at ``address``: ``await`` it or
        use ``async with``. The options are those of :meth:`Mirobot.connect` (``record``: a
        tape of this arm's lines and replies, without the bus's address prefixes)."""
        _check_address(address)
        side = self._link()
        if address in self._arms and not self._arms[address].closed:
            raise MirobotUsageError(f"the arm at @{address:02d} already has a client")

        async def opener(
            url: str, *, on_data: DataCallback, on_lost: LostCallback, timeout: float
        ) -> Transport:
            side.attach(address, on_data, on_lost)
            return ArmTransport(side, address)

        connector = Mirobot.connect(
            f"{self.url}@{address:02d}",
            open_transport=opener,
            firmware=firmware,
            timeout=timeout,
            envelope=envelope,
            status_timeout=status_timeout,
            probe=probe,
            record=record,
        )
        return ArmConnector(self, address, connector)

    async def connect_arm(
        self,
        address: int,
        *,
        firmware: Firmware | None = None,
        timeout: float | None = CONNECT_TIMEOUT,
        envelope: Envelope | None = None,
        status_timeout: float = STATUS_TIMEOUT,
        probe: bool = True,
        record: str | PathLike[str] | None = None,
    ) -> Mirobot:
        """Connect to the arm at ``address`` (its first status proves it answers).

        Raises :class:`NodeSilentError` (a :class:`MirobotTimeoutError` naming the address) when
        no node answers there within the bus's ``answer_timeout``.
        """
        arm: Mirobot = await self.arm(
            address,
            firmware=firmware,
            timeout=timeout,
            envelope=envelope,
            status_timeout=status_timeout,
            probe=probe,
            record=record,
        )
        return arm

    async def _connect(self, address: int, connector: Connector) -> Mirobot:
        node = self._link().node(address)
        node.silenced = None
        try:
            arm: Mirobot = await connector
        except MirobotConnectionError as err:
            if node.silenced is not None:
                raise node.silenced from err  # nothing answered at this address
            raise
        arm.reply_grace = self._timing.reply_grace
        self._arms[address] = arm
        return arm


class ArmConnector:
    """What :meth:`ControllerBus.arm` returns: ``await`` it or use it with ``async with`` (the
    arm is closed at the end of the block; the bus stays open)."""

    def __init__(self, bus: ControllerBus, address: int, connector: Connector) -> None:
        self._bus = bus
        self._address = address
        self._connector = connector

    def __await__(self) -> Generator[Any, None, Mirobot]:
        return self._bus._connect(self._address, self._connector).__await__()

    async def __aenter__(self) -> Mirobot:
        return await self._bus._connect(self._address, self._connector)

    async def __aexit__(self, *exc_info: object) -> None:
        arm = self._bus._arms.get(self._address)
        if arm is not None:
            await arm.close()


class SingleArmConnector:
    """What :func:`connect` (and ``Mirobot.connect(url, address=N)``) returns: use it with
    ``async with`` only, since the bus it opens must be closed with the arm."""

    def __init__(self, url: str, address: int, baud: int, options: dict[str, Any]) -> None:
        self._url = url
        self._address = address
        self._baud = baud
        self._options = options
        self.bus: ControllerBus | None = None

    async def __aenter__(self) -> Mirobot:
        self.bus = await ControllerBus.open(self._url, baud=self._baud)
        try:
            return await self.bus.connect_arm(self._address, **self._options)
        except BaseException:
            await self.bus.close()
            raise

    async def __aexit__(self, *exc_info: object) -> None:
        if self.bus is not None:
            await self.bus.close()


def connect(
    url: str,
    *,
    address: int,
    baud: int = DEFAULT_BUS_BAUD,
    firmware: Firmware | None = None,
    timeout: float | None = CONNECT_TIMEOUT,
    envelope: Envelope | None = None,
    status_timeout: float = STATUS_TIMEOUT,
    probe: bool = True,
    record: str | PathLike[str] | None = None,
) -> SingleArmConnector:
    """One arm behind a controller at ``address`` on the bus at ``url``:
    ``async with bus.connect(url, address=3) as arm`` (a :class:`~mirobot_async.Mirobot`).

    Opens a :class:`ControllerBus` for this one arm and closes it at the end of the block
    (an ``async with`` only: the bus must be closed with the arm). The options are those of
    :meth:`Mirobot.connect`. Raises :class:`NodeSilentError` when nothing answers there.
    """
    _check_address(address)
    options: dict[str, Any] = {
        "firmware": firmware,
        "timeout": timeout,
        "envelope": envelope,
        "status_timeout": status_timeout,
        "probe": probe,
        "record": record,
    }
    return SingleArmConnector(url, address, baud, options)
