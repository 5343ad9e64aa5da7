"""The multi-function controller's own commands as typed calls (EXBOX.md 3).

Every call sends one request to the controller at its address and waits for the reply, at most
``timeout`` seconds (default :data:`CONTROLLER_TIMEOUT`; the node itself must start answering
within the bus's ``answer_timeout``, else :class:`~mirobot_async.bus.NodeSilentError` naming the
address). Cancelling a call leaves the bus in step: its request still gets its reply, which is
discarded. An ``error`` reply raises :class:`ControllerCommandError` (naming the address and the
command, quoting the controller). Forms sent (EXBOX.md 3.1, what the vendor's clients send):
``o105=<n>``, ``o111<name>``, ``o13x=a,b,c,d`` (the SDK's GPIO form, fields A0,A1,D0,D1).
"""

from __future__ import annotations

import asyncio
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from mirobot_async.errors import (
    ControllerCommandError,  # defined with the error tree
    MirobotTimeoutError,
    MirobotUsageError,
)

if TYPE_CHECKING:
    from mirobot_async.bus._link import LinkSide

__all__ = [
    "BAUD_CODES",
    "CONTROLLER_TIMEOUT",
    "PINS",
    "ArmState",
    "Controller",
    "ControllerCommandError",
    "ControllerVersion",
]

CONTROLLER_TIMEOUT = 5.0
"""Default ``timeout`` of a controller command (seconds)."""

BAUD_CODES = {4800: 0, 9600: 1, 38400: 2, 57600: 3, 115200: 4}
"""``O141``'s codes for the bus baud rates (manual p.36)."""

PINS = ("A0", "A1", "D0", "D1")
"""The GPIO fields in the SDK's order."""

_STATE_WORDS = {0: "Offline", 1: "Idle", 2: "Alarm", 3: "Home", 4: "Busy", 5: "Run"}
_NAME = re.compile(r"^[A-Za-z0-9_\-]+$")


@dataclass(frozen=True, slots=True)
class ArmState:
    """``O103``'s answer: the state word (``Idle``, ``Alarm``, ``Home``, ``Run``...) and number."""

    word: str
    number: int | None
    text: str
    """The reply line as received."""


@dataclass(frozen=True, slots=True)
class ControllerVersion:
    """``$V``'s answer: the controller's ``EXbox ...`` line and the arm's line, if printed."""

    controller: str | None
    arm: str | None


def _parse_state(text: str) -> ArmState:
    fields = [f.strip() for f in text.split(",")]
    if fields[0] == "State" and len(fields) >= 2:
        number = int(fields[2]) if len(fields) > 2 and fields[2].isdigit() else None
        return ArmState(fields[1], number, text)
    if text.strip().isdigit():
        number = int(text.strip())
        return ArmState(_STATE_WORDS.get(number, "Unknown"), number, text)
    raise ValueError(text)


class Controller:
    """The controller at :attr:`address` on a :class:`~mirobot_async.bus.ControllerBus`."""

    def __init__(self, side: LinkSide, address: int, moved: Callable[[int, int], None]) -> None:
        self._side = side
        self.address = address
        self._moved = moved

    async def request(
        self, command: str, *, timeout: float | None = CONTROLLER_TIMEOUT
    ) -> tuple[str, ...]:
        """Send ``command`` (``O...`` or ``$V``, no prefix, no line end); return its reply lines
        without a final ``ok``. Raises :class:`ControllerCommandError` on ``error``."""
        if not command.isascii() or any(c in command for c in "\r\n@") or not command:
            raise MirobotUsageError(f"{command!r} is not one ASCII command line")
        future = self._side.submit_controller(self.address, command)
        try:
            async with asyncio.timeout(timeout):
                lines = await asyncio.shield(future)
        except MirobotTimeoutError:
            raise  # the node did not answer (NodeSilentError, itself a TimeoutError)
        except TimeoutError as err:
            raise MirobotTimeoutError(
                f"the controller at @{self.address:02d}", timeout, command=command
            ) from err
        if lines and lines[-1].strip().lower().startswith("error"):
            raise ControllerCommandError(self.address, command, lines[-1].strip())
        if lines and lines[-1].strip() == "ok":
            lines = lines[:-1]
        return lines

    async def _set(self, command: str, timeout: float | None) -> None:
        lines = await self.request(command, timeout=timeout)
        if lines:
            raise ControllerCommandError(self.address, command, " / ".join(lines))

    async def _value(self, command: str, timeout: float | None) -> str:
        lines = await self.request(command, timeout=timeout)
        if len(lines) != 1:
            raise ControllerCommandError(self.address, command, " / ".join(lines) or "no value")
        return lines[0].strip()

    # ---- identity

    async def version(self, *, timeout: float | None = CONTROLLER_TIMEOUT) -> ControllerVersion:
        """``$V``: the controller's ``EXbox ...`` line and the arm's version line (either may
        be missing: the vendor says ``$V`` is not supported over RS485 yet, EXBOX.md 2)."""
        lines = await self.request("$V", timeout=timeout)
        exbox = next((x.strip() for x in lines if x.startswith("EXbox")), None)
        arm = next((x.strip() for x in lines if not x.startswith("EXbox") and x.strip()), None)
        return ControllerVersion(exbox, arm)

    async def software_version(self, *, timeout: float | None = CONTROLLER_TIMEOUT) -> str:
        """``O101``: the controller's firmware version (a date such as ``20210410``)."""
        return await self._value("o101", timeout)

    async def arm_state(self, *, timeout: float | None = CONTROLLER_TIMEOUT) -> ArmState:
        """``O103``: the arm's state as the controller sees it (``State,<Word>,<n>`` or the
        manual's bare number 0..5; both parsed)."""
        text = await self._value("O103", timeout)
        try:
            state = _parse_state(text)
        except ValueError:
            raise ControllerCommandError(self.address, "O103", text) from None
        if state.word != "Home":
            self._side.homing_ended(self.address)
        return state

    async def restart(self, *, timeout: float | None = CONTROLLER_TIMEOUT) -> None:
        """``O100``: restart the controller (its arm resets)."""
        await self._set("o100", timeout)

    # ---- homing

    async def home(
        self,
        mode: int = 8,
        *,
        wait: bool = True,
        poll_interval: float = 0.05,
        timeout: float | None = 180.0,
    ) -> None:
        """``O105=<mode>``: home the arm (8 = all axes together, 9 = one by one, 0 = arm and
        7th axis, 1..7 one axis, 10 compact). The controller answers at once and homes by
        itself, so the bus stays free. ``wait``: poll ``O103`` until the arm is ``Idle`` again
        (within ``timeout`` seconds)."""
        if isinstance(mode, bool) or not isinstance(mode, int) or not 0 <= mode <= 10:
            raise MirobotUsageError(f"mode={mode!r}: homing modes are 0..10")
        loop = asyncio.get_running_loop()
        started = loop.time()
        await self._set(f"o105={mode}", timeout)
        self._side.homing_started(self.address, mode)  # the arm answers no "?" meanwhile
        if wait:
            await self.wait_idle(
                poll_interval=poll_interval,
                timeout=None if timeout is None else max(0.0, timeout - (loop.time() - started)),
            )

    async def wait_idle(
        self, *, poll_interval: float = 0.05, timeout: float | None = 180.0
    ) -> ArmState:
        """Poll ``O103`` every ``poll_interval`` s until the arm is ``Idle`` (as the vendor's
        Arduino examples do); :class:`MirobotTimeoutError` after ``timeout`` seconds."""
        try:
            async with asyncio.timeout(timeout):
                while True:
                    state = await self.arm_state()
                    if state.word == "Idle":
                        return state
                    await asyncio.sleep(poll_interval)
        except TimeoutError as err:
            raise MirobotTimeoutError(
                f"the arm at @{self.address:02d} to be Idle", timeout, command="O103"
            ) from err

    # ---- files on the TF card

    async def list_files(self, *, timeout: float | None = CONTROLLER_TIMEOUT) -> tuple[str, ...]:
        """``O110``: the programs on the TF card, without ``.gcode`` (the manual's one-line
        ``["a","b"]`` list or one name per line; both parsed)."""
        lines = await self.request("o110", timeout=timeout)
        if len(lines) == 1 and lines[0].strip().startswith("["):
            body = lines[0].strip()[1:-1]
            names = [n.strip().strip('"').strip("'") for n in body.split(",")]
        else:
            names = [n.strip() for n in lines]
        return tuple(n.lstrip("/").removesuffix(".gcode") for n in names if n)

    async def run_file(
        self, name: str, *, loop: bool = False, timeout: float | None = CONTROLLER_TIMEOUT
    ) -> None:
        """``O111<name>`` (``O112`` with ``loop``): run a program from the TF card (no
        extension). The controller feeds it to the arm; :meth:`wait_idle` waits for its end."""
        await self._set(f"o{112 if loop else 111}{self._file_name(name)}", timeout)

    async def run_file_number(
        self, number: int, *, timeout: float | None = CONTROLLER_TIMEOUT
    ) -> None:
        """``O116=<n>``: run the program whose name starts with the two digits ``n``."""
        if isinstance(number, bool) or not isinstance(number, int) or not 0 <= number <= 99:
            raise MirobotUsageError(f"number={number!r}: a file number is 0..99")
        await self._set(f"O116={number}", timeout)

    async def stop_file(self, *, timeout: float | None = CONTROLLER_TIMEOUT) -> None:
        """``O117``: stop the running program (the arm finishes what it already received)."""
        await self._set("o117", timeout)

    async def delete_file(self, name: str, *, timeout: float | None = CONTROLLER_TIMEOUT) -> None:
        """``O113<name>``: delete a program."""
        await self._set(f"o113{self._file_name(name)}", timeout)

    async def read_file(
        self, name: str, *, timeout: float | None = CONTROLLER_TIMEOUT
    ) -> tuple[str, ...]:
        """``O114<name>``: a program's lines (its reply shape is INFERRED: one line each)."""
        return await self.request(f"o114{self._file_name(name)}", timeout=timeout)

    async def write_file(
        self, name: str, lines: Iterable[str], *, timeout: float | None = CONTROLLER_TIMEOUT
    ) -> None:
        """``O121<name>``, each line, ``O122``: store a program on the TF card (INFERRED:
        what Studio's download does; each line is answered ``ok``)."""
        checked = [line.strip() for line in lines if line.strip()]
        for line in checked:
            if not line.isascii() or any(c in line for c in "\r\n@") or len(line) > 200:
                raise MirobotUsageError(f"{line!r} cannot be stored as one program line")
        await self._set(f"o121{self._file_name(name)}", timeout)
        try:
            for line in checked:
                await self._set(line, timeout)
        finally:
            await self._set("o122", timeout)

    @staticmethod
    def _file_name(name: str) -> str:
        base = name.removesuffix(".gcode")
        if not _NAME.match(base):
            raise MirobotUsageError(f"file name {name!r}: ASCII letters, digits, '_' and '-'")
        return base

    # ---- GPIO (the SDK's four-field form)

    async def set_pin_modes(
        self, *, timeout: float | None = CONTROLLER_TIMEOUT, **modes: int
    ) -> None:
        """``O130``: pin modes by name (``A0=2, D0=1``: 0 digital in, 1 digital out, 2 analog
        in, 3 PWM out); pins not named keep theirs."""
        await self._set(f"o130={self._fields(modes, 0, 3)}", timeout)

    async def write_pins(
        self, *, timeout: float | None = CONTROLLER_TIMEOUT, **values: int
    ) -> None:
        """``O131``: output values by pin name (0..255)."""
        await self._set(f"o131={self._fields(values, 0, 255)}", timeout)

    async def enable_pins(
        self, *, timeout: float | None = CONTROLLER_TIMEOUT, **flags: int
    ) -> None:
        """``O132``: enable (1) or disable (0) pins by name."""
        await self._set(f"o132={self._fields(flags, 0, 1)}", timeout)

    async def set_thresholds(
        self, *, timeout: float | None = CONTROLLER_TIMEOUT, **values: int
    ) -> None:
        """``O133``: trigger thresholds by pin name (0..255)."""
        await self._set(f"o133={self._fields(values, 0, 255)}", timeout)

    async def set_trigger_files(
        self, *, timeout: float | None = CONTROLLER_TIMEOUT, **names: str
    ) -> None:
        """``O134``: the program each pin's trigger runs, by pin name."""
        fields = {pin: self._file_name(name) for pin, name in names.items()}
        await self._set(f"o134={self._fields(fields, None, None)}", timeout)

    async def pin_modes(self, *, timeout: float | None = CONTROLLER_TIMEOUT) -> dict[str, int]:
        """``O130?``: every pin's mode."""
        return await self._pins("o130?", timeout)

    async def read_pins(self, *, timeout: float | None = CONTROLLER_TIMEOUT) -> dict[str, int]:
        """``O131?``: every pin's value (inputs as read, outputs as set)."""
        return await self._pins("o131?", timeout)

    async def _pins(self, command: str, timeout: float | None) -> dict[str, int]:
        text = await self._value(command, timeout)
        fields = text.split(",")
        if len(fields) != 4 or not all(f.strip().isdigit() for f in fields):
            raise ControllerCommandError(self.address, command, text)
        return {pin: int(f) for pin, f in zip(PINS, fields, strict=True)}

    @staticmethod
    def _fields(values: dict[str, int] | dict[str, str], low: int | None, high: int | None) -> str:
        out = ["", "", "", ""]
        for pin, value in values.items():
            key = pin.upper()
            if key not in PINS:
                raise MirobotUsageError(f"pin {pin!r}: expected one of {', '.join(PINS)}")
            if low is not None and high is not None:
                if isinstance(value, bool) or not isinstance(value, int):
                    raise MirobotUsageError(f"{pin}={value!r}: expected an integer")
                if not low <= value <= high:
                    raise MirobotUsageError(f"{pin}={value}: expected {low}..{high}")
            out[PINS.index(key)] = str(value)
        if not any(out):
            raise MirobotUsageError("name at least one pin (A0, A1, D0, D1)")
        return ",".join(out)

    # ---- address and bus baud

    async def bus_address(self, *, timeout: float | None = CONTROLLER_TIMEOUT) -> int:
        """``O140?``: the controller's RS485 address as it reports it."""
        text = await self._value("o140?", timeout)
        if not text.isdigit():
            raise ControllerCommandError(self.address, "o140?", text)
        return int(text)

    async def set_bus_address(
        self, address: int, *, timeout: float | None = CONTROLLER_TIMEOUT
    ) -> None:
        """``O140<nn>``: give the controller a new address (1..99); this object (and its arm's
        client) follow it. Raises :class:`MirobotUsageError` if another node here uses it."""
        if isinstance(address, bool) or not isinstance(address, int) or not 1 <= address <= 99:
            raise MirobotUsageError(f"address={address!r}: a controller's address is 1..99")
        await self._set(f"o140{address:02d}", timeout)
        old, self.address = self.address, address
        self._side.rekey(old, address)
        self._moved(old, address)

    async def bus_baud(self, *, timeout: float | None = CONTROLLER_TIMEOUT) -> int:
        """``O141?``: the baud rate the controller listens at."""
        text = await self._value("o141?", timeout)
        rates = {code: rate for rate, code in BAUD_CODES.items()}
        if not text.isdigit() or int(text) not in rates:
            raise ControllerCommandError(self.address, "o141?", text)
        return rates[int(text)]

    async def set_bus_baud(self, baud: int, *, timeout: float | None = CONTROLLER_TIMEOUT) -> None:
        """``O141=<code>``: the controller listens at ``baud`` after its ``ok`` (the host must
        reopen the bus at that rate to reach it again)."""
        if baud not in BAUD_CODES:
            raise MirobotUsageError(f"baud={baud!r}: expected one of {sorted(BAUD_CODES)}")
        await self._set(f"o141={BAUD_CODES[baud]}", timeout)
