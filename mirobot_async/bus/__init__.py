"""Several arms on one RS485 bus of WLKATA multi-function controllers ("EXbox", issue 16).

::

    from mirobot_async.bus import ControllerBus

    async with ControllerBus.open("/dev/ttyUSB0") as bus:     # 38400 8N1, the vendor's default
        arms = [await bus.connect_arm(n) for n in (1, 2, 3, 4)]
        await asyncio.gather(*(arm.move_joints(j1=10 * n) for n, arm in enumerate(arms)))
        print(await bus.controller(2).list_files())

* :class:`ControllerBus` owns the one serial link and hands out a full
  :class:`~mirobot_async.Mirobot` per address (:meth:`ControllerBus.connect_arm`); each arm's
  lines go out as ``@<n><line>\\r\\n`` and its replies come back as on a direct link.
* Replies carry no address, so one node talks at a time: a request goes out only once the node
  addressed before has answered everything it owes (nodes with work are served round-robin).
* :meth:`ControllerBus.controller` gives the controller's own commands
  (:class:`Controller`: ``$V``, ``O103``, ``O105`` homing, files, GPIO, ``O140``/``O141``).
* A node that does not answer a status request or a controller command within
  ``BusTiming.answer_timeout`` (0.5 s) raises :class:`NodeSilentError` (a
  :class:`~mirobot_async.MirobotTimeoutError` naming the address); the other arms keep working.
* :func:`connect` is ``Mirobot.connect(url, address=N)`` for one arm alone on a bus.

Limits (see ``EXBOX.md``; no controller firmware or device log exists): the reply shapes are
inferred from the vendor's clients; a line the arm answers late (a full planner, ``$H``,
``G4``) holds the whole bus until it is answered: prefer :meth:`Controller.home` (the controller
answers ``O105`` at once) to ``arm.home()``, and expect several arms streaming at once to share
the bus's throughput. Streaming works one line at a time per request (the character counting of
the arm's client still pipelines lines into the bus's queue; the bus sends them one by one).
"""

from mirobot_async.bus.controller import (
    BAUD_CODES,
    CONTROLLER_TIMEOUT,
    PINS,
    ArmState,
    Controller,
    ControllerCommandError,
    ControllerVersion,
)
from mirobot_async.bus.controller_bus import ArmTransport, ControllerBus, connect
from mirobot_async.bus.link import DEFAULT_BUS_BAUD, BusStats, BusTiming, NodeSilentError

__all__ = [
    "BAUD_CODES",
    "CONTROLLER_TIMEOUT",
    "DEFAULT_BUS_BAUD",
    "PINS",
    "ArmState",
    "ArmTransport",
    "BusStats",
    "BusTiming",
    "Controller",
    "ControllerBus",
    "ControllerCommandError",
    "ControllerVersion",
    "NodeSilentError",
    "connect",
]
