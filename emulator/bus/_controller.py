"""One multi-function controller ("EXbox") with its arm: the ``O`` commands, ``$V``, the files on
its TF card, and the relay of the arm's replies (EXBOX 2-3, 6).

Pure: the controller is driven by :class:`mirobot_emulator.bus.Bus`, which hands it the lines
addressed to it (:meth:`Controller.hear`) and collects what it has to transmit
(:meth:`Controller.take_output`). Its arm is a :class:`mirobot_emulator.firmware.Firmware`.

Relay rule (INFERRED, EXBOX 7.5): the arm's replies are passed back unchanged, line by line,
except those to lines the controller sent itself (a running file, ``O105`` homing with
``o105_reply=ok``, a broadcast). The arm answers every line end (``\\r`` and ``\\n`` each end a
line, so ``G0 X1\\r\\n`` gets a reply and an ``ok``) with ``ok`` or an error, in order, so the
controller knows whose each reply is by counting line ends.
"""

from __future__ import annotations

import re
from collections import deque
from dataclasses import dataclass

from ..firmware import Firmware
from ._gpio import Pins
from ._options import BAUD_CODES, BusOptions

__all__ = ["HARDWARE_VERSION", "TEST_PROGRAM", "Controller"]

HARDWARE_VERSION = "V1.0"
"""``O102``'s reply; the real text is unknown (INFERRED)."""

TEST_PROGRAM = (
    "M21 G90",
    "G00 X10",
    "G00 X0",
    "G00 Y10",
    "G00 Y0",
    "G00 Z10",
    "G00 Z0",
    "G00 A10",
    "G00 A0",
    "G00 B10",
    "G00 B0",
    "G00 C10",
    "G00 C0",
)
"""``test.gcode``, on every new controller: it moves each axis (manual p.17)."""

_O_COMMAND = re.compile(rb"^[oO](\d{3})=?(.*)$", re.DOTALL)
_STATE_NUMBERS = {"Offline": 0, "Idle": 1, "Alarm": 2, "Home": 3, "Run": 5}
_ARM_VERSION = re.compile(r"(?:Qinnew Robot |Firmware version:Mirobot,)(\S+)")
_HOMING_MODES = ("$H0", "$H1", "$H2", "$H3", "$H4", "$H5", "$H6", "$H7", "$H", "$HH", "$HE")
_NO_EFFECT = frozenset({162, 163, 164, 170, 171, 172, 173, 174, 175, 180})

HOST = "host"
QUIET = "quiet"
RUNNER = "runner"


@dataclass(slots=True)
class _Run:
    """A program being fed to the arm, one line per reply (send-response)."""

    name: str
    lines: tuple[str, ...]
    loop: bool
    index: int = 0
    waiting: bool = False


def _is_final(line: str) -> bool:
    """The arm's last line for one received line: ``ok`` (possibly glued) or an error."""
    text = line.strip()
    return text.endswith("ok") or text.lower().startswith("error")


def _ends(data: bytes) -> int:
    """Line ends the arm sees in ``data`` (after its last ``%``, which empties its buffer)."""
    tail = data[data.rfind(b"%") + 1 :]
    return tail.count(b"\r") + tail.count(b"\n")


class Controller:
    """A controller at ``address`` with ``arm`` behind it, configured by ``options``."""

    def __init__(
        self, address: int, arm: Firmware, options: BusOptions, *, baud_code: int = 2
    ) -> None:
        self.address = address
        self.baud_code = baud_code
        """``O141`` code of the baud the controller listens at (2 = 38400)."""
        self.arm = arm
        self.options = options
        self.pins = Pins()
        self.files: dict[str, list[str]] = {"test": list(TEST_PROGRAM)}
        """Programs on the TF card, oldest first (the list order of ``O110``)."""
        self.bluetooth_name = "mirobot"
        self.bluetooth_pin = "7676"
        self.home_at_power_on = 0
        self.repeat_run = 0
        self._owners: deque[str] = deque()
        self._partial = b""
        self._out = bytearray()
        self._run: _Run | None = None
        self._download: str | None = None
        self._answering = True
        self._baud_after_reply: int | None = None
        banner = arm.read_output()
        match = _ARM_VERSION.search(banner.decode("ascii", "replace"))
        self.arm_version = match.group(1) if match else "unknown"
        if options.relay_banner:
            self._out += banner

    # ---- what the bus sees

    @property
    def baud(self) -> int:
        """The baud the controller listens and talks at."""
        return BAUD_CODES[self.baud_code]

    @property
    def running_file(self) -> str | None:
        """The program being fed to the arm, or ``None``."""
        return self._run.name if self._run is not None else None

    def take_output(self) -> bytes:
        """The bytes the controller has to transmit (whole lines), emptied.

        Transmitted at :attr:`baud` as it was before this call (an ``O141`` change applies after
        its ``ok``).
        """
        out = bytes(self._out)
        self._out.clear()
        if self._baud_after_reply is not None:
            self.baud_code, self._baud_after_reply = self._baud_after_reply, None
        return out

    def hear(self, body: bytes, *, answer: bool = True) -> None:
        """A line addressed to this controller, ``@NN`` removed, line end included.

        ``answer=False`` for a broadcast: executed, nothing transmitted.
        """
        text = body.rstrip(b"\r\n ").lstrip(b" ")
        self._answering = answer
        match = _O_COMMAND.match(text)
        if match is not None:
            reply = bytearray()
            self._o_command(int(match.group(1)), match.group(2).decode("ascii", "replace"), reply)
            if answer:
                self._out += reply
            return
        if self._download is not None:
            if text:
                self.files[self._download].append(text.decode("ascii", "replace"))
            if answer:
                self._out += b"ok\r\n"
            return
        if text.upper() == b"$V" and self.options.version != "forward":
            if answer:
                self._out += f"EXbox {self.options.controller_version}\r\n".encode()
                if self.options.version == "both":
                    self._out += f"Mirobot {self.arm_version}\r\n".encode()
                self._out += b"ok\r\n"
            return
        self._to_arm(body, HOST if answer else QUIET)

    def collect(self) -> None:
        """Read the arm's output: relay or consume each complete line; feed a running file."""
        data = self.arm.read_output()
        if data:
            self._partial += data
            *lines, self._partial = self._partial.split(b"\n")
            for raw in lines:
                self._route(raw + b"\n")
        self._feed()

    def restart(self) -> None:
        """``O100``: the controller restarts; the arm is reset, its banner not relayed."""
        self._run = None
        self._download = None
        self._owners.clear()
        self._partial = b""
        self.arm.reset()
        banner = self.arm.read_output()
        if self.options.relay_banner:
            self._out += banner

    def state_word(self) -> str:
        """The arm's state as ``O103`` names it (``Run`` while a program is being fed)."""
        return "Run" if self._run is not None else self.arm.state

    # ---- the arm side

    def _to_arm(self, data: bytes, owner: str) -> None:
        if b"%" in data:
            self._owners.clear()  # the reset discards every line the arm had not answered
            self._partial = b""
            if self._run is not None:
                self._run = None
        self._owners.extend([owner] * _ends(data))
        self.arm.receive(data)

    def _route(self, raw: bytes) -> None:
        line = raw.decode("ascii", "replace")
        if line.startswith("<"):
            self._out += raw  # a status report answers a "?", which owes no line end
            return
        if _is_final(line):
            owner = self._owners.popleft() if self._owners else HOST
            if owner == RUNNER and self._run is not None:
                self._run.waiting = False
        else:
            owner = self._owners[0] if self._owners else HOST
        if owner == HOST:
            self._out += raw

    def _feed(self) -> None:
        run = self._run
        while run is not None and not run.waiting:
            if run.index >= len(run.lines):
                if not run.loop or not any(line.strip() for line in run.lines):
                    self._run = None
                    return
                run.index = 0
            line = run.lines[run.index].strip()
            run.index += 1
            if line:
                run.waiting = True
                self._to_arm(line.encode("ascii", "replace") + b"\n", RUNNER)
                run = self._run  # "%" in a program ends it

    # ---- the controller's own commands

    def _o_command(self, number: int, argument: str, reply: bytearray) -> None:
        argument = argument.strip()
        options = self.options
        if 130 <= number <= 134:
            answer = self.pins.command(number, argument, options.gpio)
            if answer is None:
                self._error(reply)
            elif answer[1]:
                self._values(reply, answer[0], gpio=True)
            else:
                reply += b"ok\r\n"
            return
        values: list[str] | None = self._query(number) if argument == "?" else None
        if values is not None:
            self._values(reply, values)
            return
        if not self._execute(number, argument, reply):
            self._error(reply)

    def _query(self, number: int) -> list[str] | None:
        queries = {
            105: lambda: str(self.repeat_run),
            106: lambda: str(self.home_at_power_on),
            140: lambda: f"{self.address:02d}",
            141: lambda: str(self.baud_code),
            150: lambda: self.bluetooth_name,
            151: lambda: self.bluetooth_pin,
        }
        if number not in queries or (number == 105 and self.options.o105 == "homing"):
            return None
        return [queries[number]()]

    def _execute(self, number: int, argument: str, reply: bytearray) -> bool:
        """Run one command with its argument; False for a bad or unknown one."""
        if number == 100:
            reply += b"ok\r\n"
            self.restart()
        elif number == 101:
            self._values(reply, [self.options.controller_version])
        elif number == 102:
            self._values(reply, [HARDWARE_VERSION])
        elif number == 103:
            self._values(reply, [self._o103()])
        elif number == 105 and self.options.o105 == "homing":
            return self._home(argument, reply)
        elif number in (105, 106):
            if argument not in ("0", "1"):
                return False
            if number == 105:
                self.repeat_run = int(argument)
            else:
                self.home_at_power_on = int(argument)
            reply += b"ok\r\n"
        elif 110 <= number <= 122:
            return self._file_command(number, argument, reply)
        elif number == 140:
            if not (argument.isdigit() and 1 <= int(argument) <= 99):
                return False
            reply += b"ok\r\n"
            self.address = int(argument)
        elif number == 141:
            if not (argument.isdigit() and int(argument) in BAUD_CODES):
                return False
            reply += b"ok\r\n"  # sent at the old baud; the new one applies after it
            self._baud_after_reply = int(argument)
        elif number == 150:
            if not argument or not argument.isascii():
                return False
            self.bluetooth_name = argument
            reply += b"ok\r\n"
        elif number == 151:
            if not (len(argument) == 4 and argument.isdigit()):
                return False
            self.bluetooth_pin = argument
            reply += b"ok\r\n"
        elif number in _NO_EFFECT:
            reply += b"ok\r\n"
        else:
            return False
        return True

    def _o103(self) -> str:
        word = self.state_word()
        number = _STATE_NUMBERS.get(word, 4)
        if word == "Idle" and self.arm.locked:
            number = 2  # the manual's "locked"
        if self.options.o103 == "number":
            return str(number)
        return f"State,{word},{number}"

    def _home(self, argument: str, reply: bytearray) -> bool:
        mode = 8 if argument == "" else int(argument) if argument.isdigit() else -1
        if not 0 <= mode < len(_HOMING_MODES):
            return False
        relay = self.options.o105_reply == "relay" and self._answering
        if not relay:
            reply += b"ok\r\n"
        # the arm's reply goes into this controller's output when relayed
        self._to_arm(_HOMING_MODES[mode].encode() + b"\n", HOST if relay else QUIET)
        return True

    def _file_command(self, number: int, argument: str, reply: bytearray) -> bool:
        if number == 110:
            names = list(self.files)
            if self.options.o110 == "list":
                self._values(reply, ["[" + ",".join(f'"{n}"' for n in names) + "]"])
            else:
                self._values(reply, names)
            return True
        if number == 122:
            if self._download is None:
                return False
            self._download = None
            reply += b"ok\r\n"
            return True
        if number == 117:
            if self._run is not None and self.options.o117 == "reset":
                self._to_arm(b"%", QUIET)
            self._run = None
            reply += b"ok\r\n"
            return True
        if number in (120, 121):
            new = argument.removesuffix(".gcode")
            if not new or not new.isascii():
                return False
            self.files.pop(new, None)
            self.files[new] = []  # newest last
            if number == 121:
                self._download = new
            reply += b"ok\r\n"
            return True
        found = self._find(argument, by_number=number == 116)
        if found is None or number not in (111, 112, 113, 114, 116):
            return False
        name = found
        if number == 113:
            del self.files[name]
            reply += b"ok\r\n"
        elif number == 114:
            self._values(reply, self.files[name])
        else:
            self._run = _Run(name, tuple(self.files[name]), loop=number == 112)
            reply += b"ok\r\n"
        return True

    def _find(self, argument: str, *, by_number: bool) -> str | None:
        if by_number:
            if not argument.isdigit():
                return None
            wanted = int(argument)
            for name in self.files:
                if name[:2].isdigit() and int(name[:2]) == wanted:
                    return name
            return None
        name = argument.removesuffix(".gcode")
        if name in self.files:
            return name
        folded = {n.lower(): n for n in self.files}
        return folded.get(name.lower())

    def _values(self, reply: bytearray, lines: list[str], *, gpio: bool = False) -> None:
        for line in lines:
            reply += line.encode("ascii", "replace") + b"\r\n"
        style = self.options.query_ok
        if style == "always" or (style == "gpio" and gpio):
            reply += b"ok\r\n"

    def _error(self, reply: bytearray) -> None:
        reply += self.options.error_text.encode("ascii", "replace") + b"\r\n"
