"""A pure model of an RS485 bus of WLKATA multi-function controllers ("EXbox"), each with its
arm: what a host's USB-RS485 adapter sees (issue 16; the protocol is ``EXBOX.md``).

::

    bus = Bus(4)                       # addresses 1..4, "2021" arms, 38400 baud
    bus.receive(b"@2?\r\n")            # bytes in
    bus.advance(0.1)                   # an explicit clock, as Firmware
    bus.read_output()                  # bytes out: node 2's status line (and the arm's oks)

:class:`Bus` has the methods of :class:`mirobot_emulator.firmware.Firmware` that the server
uses, so a server can construct it instead of a Firmware. Pure: no I/O, no clock of its own.

What is modelled
----------------
* Addressing: a line ``@<digits><command>`` goes to the controller(s) at that address (``@1`` and
  ``@01`` are the same); nobody answers another address; replies carry no address. ``@0``
  (broadcast) and lines without a prefix are ignored unless :class:`BusOptions` says otherwise.
* Each controller strips the prefix, answers its own ``O1xx`` commands and ``$V``, and forwards
  every other line (G-code, ``$`` commands, ``?``, ``!``, ``~``, ``%``) unchanged to its arm (a
  :class:`~mirobot_emulator.firmware.Firmware`, either profile), relaying the arm's replies.
* Files on the TF card (``test.gcode`` preinstalled): list, run, loop, stop, delete, read, run
  by number, download (``O110``-``O122``); a run feeds the arm one line per reply.
* Homing modes (``O105``), arm state (``O103``), GPIO (``O130``-``O134``), address and baud
  (``O140``/``O141``: a node at another baud than the bus hears nothing and is not heard),
  Bluetooth name/PIN, restart; the conflicting readings are options (:class:`BusOptions`).
* Timing: the bus baud (38400 by default) for requests and replies, the controller's turnaround
  (2 ms), replies of several nodes one after the other; collisions are counted
  (:attr:`Bus.collisions`). A status request's first reply byte leaves ~3 ms after the request
  ends, its whole line arrives within ~35 ms at 38400 baud (clients need < 100 ms / 500 ms).

Not modelled
------------
Garbled bytes on a collision (counted, delivered intact); the ribbon link's own timing (115200,
faster than the bus); the OLED, keys, Bluetooth, WiFi, the auxiliary UART; GPIO triggers firing;
MS4220 stepper nodes; what a real controller prints on errors (``error``, unknown). Everything
marked INFERRED in EXBOX.md stays an inference here.
"""

from ._controller import Controller
from ._gpio import PIN_NAMES, Pins
from ._model import MAX_LINE, Bus
from ._options import BAUD_CODES, DEFAULT_BUS_BAUD, BusOptions

__all__ = [
    "BAUD_CODES",
    "DEFAULT_BUS_BAUD",
    "MAX_LINE",
    "PIN_NAMES",
    "Bus",
    "BusOptions",
    "Controller",
    "Pins",
]
