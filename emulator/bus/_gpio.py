"""The controller's four I/O pins and the ``O130``-``O134`` commands (EXBOX 3.5, a CONFLICT).

Two readings, picked by ``BusOptions.gpio``:

* ``sdk`` (wlkatapython, SIM): four comma-separated fields in the order ``A0,A1,D0,D1``, an
  empty field meaning "no change". ``o130`` mode, ``o131`` output value (``o131?`` the pins'
  values), ``o132`` enable, ``o133`` trigger threshold, ``o134`` trigger file name.
* ``manual`` (manual p.35-36): ``O130=n`` trigger mode, ``O131<pin>/<mode>[/<value or
  condition>[/<file>]]`` configures one pin, ``O132<pin>?`` / ``O133<pin>?`` read it.

Not modelled: triggers firing (an input crossing its threshold does not start the file); pin
electrical limits. Input values are whatever :meth:`Pins.set_input` last set (0 at power-on).
"""

from __future__ import annotations

import re

__all__ = ["PIN_NAMES", "Pins"]

PIN_NAMES = ("A0", "A1", "D0", "D1")
"""The SDK's field order."""

_MANUAL_CONFIG = re.compile(r"^(A0|A1|D0|D1)/([0-3])(?:/([<>=]?\d{1,3}))?(?:/(\w+))?$")
_MANUAL_QUERY = re.compile(r"^(A0|A1|D0|D1)\?$")


class Pins:
    """The I/O state of one controller; :meth:`command` answers one GPIO command."""

    def __init__(self) -> None:
        self.mode = [0, 0, 0, 0]
        """0 digital in, 1 digital out, 2 analog in, 3 PWM out."""
        self.output = [0, 0, 0, 0]
        self.enabled = [0, 0, 0, 0]
        self.threshold = [0, 0, 0, 0]
        self.trigger_file = ["", "", "", ""]
        self.inputs = [0, 0, 0, 0]
        self.trigger_mode = 0

    def set_input(self, pin: str, value: int) -> None:
        """What an input pin reads from now on (tests stand in for the sensor)."""
        self.inputs[PIN_NAMES.index(pin.upper())] = int(value)

    def value(self, index: int) -> int:
        """The pin's value: its input for input modes, its output otherwise."""
        return self.inputs[index] if self.mode[index] in (0, 2) else self.output[index]

    def command(self, number: int, argument: str, style: str) -> tuple[list[str], bool] | None:
        """Answer ``O<number>`` with ``argument`` (after an optional ``=``).

        Returns (value lines, is a query) or ``None`` for a bad command (the caller answers
        its error text). A set command returns no value lines (the caller answers ``ok``).
        """
        if style == "manual":
            return self._manual(number, argument.upper())
        return self._sdk(number, argument)

    # ---- the SDK's four-field form

    def _sdk(self, number: int, argument: str) -> tuple[list[str], bool] | None:
        tables: dict[int, list[int]] = {
            130: self.mode,
            131: self.output,
            132: self.enabled,
            133: self.threshold,
        }
        if argument == "?":
            if number == 131:
                return [",".join(str(self.value(i)) for i in range(4))], True
            if number == 134:
                return [",".join(self.trigger_file)], True
            return [",".join(str(v) for v in tables[number])], True
        fields = argument.split(",")
        if len(fields) != 4:
            return None
        if number == 134:
            for index, name in enumerate(fields):
                if name:
                    self.trigger_file[index] = name.strip()
            return [], False
        parsed: list[int | None] = []
        for text in fields:
            text = text.strip()
            if not text:
                parsed.append(None)
            elif text.isdigit() and int(text) <= 255:
                parsed.append(int(text))
            else:
                return None
        if number == 130 and any(v is not None and v > 3 for v in parsed):
            return None
        for index, new in enumerate(parsed):
            if new is not None:
                tables[number][index] = new
        return [], False

    # ---- the manual's per-pin form

    def _manual(self, number: int, argument: str) -> tuple[list[str], bool] | None:
        if number == 130:
            if argument == "?":
                return [str(self.trigger_mode)], True
            if argument in ("0", "1", "2"):
                self.trigger_mode = int(argument)
                return [], False
            return None
        if number in (132, 133):
            match = _MANUAL_QUERY.match(argument)
            if match is None:
                return None
            return [str(self.value(PIN_NAMES.index(match.group(1))))], True
        if number in (131, 134):
            match = _MANUAL_CONFIG.match(argument)
            if match is None:
                return None
            index = PIN_NAMES.index(match.group(1))
            mode = int(match.group(2))
            if mode == 2 and not match.group(1).startswith("A"):
                return None  # analog input exists only on the analog pins
            self.mode[index] = mode
            extra = match.group(3)
            if extra is not None:
                digits = int(extra.lstrip("<>="))
                if digits > 255:
                    return None
                if mode in (1, 3):
                    self.output[index] = digits
                else:
                    self.threshold[index] = digits
            if match.group(4):
                self.trigger_file[index] = match.group(4)
            return [], False
        return None
