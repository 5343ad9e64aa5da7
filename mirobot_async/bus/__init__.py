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
* :func:`connect` (``bus.connect(url, address=N)``) opens a bus for one arm alone on it.

Flow control: an arm answers a motion line when it is queued in its planner (18 blocks), and
a line sent to a full planner would hold the whole bus until a block ends. So each arm may have
at most ``BusTiming.planner_window`` (16) lines that may move answered but not known finished;
the next waits (other nodes talk meanwhile) until a status request of the bus's own finds the
arm ``Idle``. ``stream()`` works unchanged: its character counting fills the bus's queue for the
arm, and the bus sends the lines one request at a time. A line the arm answers late anyway
(``$H``, ``G4``) holds the bus meanwhile: the bus then asks that same node for its status
(unambiguous: only it talks), so the wait is not taken for a dead node.

Limits (see ``EXBOX.md``; no controller firmware or device log exists): the prefix form, the
reply shapes (the arm's ``ok`` for each line end relayed, ``O103`` as ``State,<Word>,<n>`` or
a number, ``O110`` as ``["a","b"]`` or one name per line, a query's bare value) and the
turnaround are inferred from the vendor's clients and the manual. Prefer
:meth:`Controller.home` (answered at once) to ``arm.home()`` (holds the bus while homing);
meanwhile that arm answers no ``?``, so its client's status requests wait in the bus's queue
until ``O103`` or the arm's first report says the search is over (other arms go on). A
status report is ~190 bytes: ~50 ms on the bus at 38400 baud, shared by every arm. A reply lost
on the wire (a collision) holds the bus; the arm's call times out.
"""

from mirobot_async.bus._controller import (
    BAUD_CODES,
    CONTROLLER_TIMEOUT,
    PINS,
    ArmState,
    Controller,
    ControllerCommandError,
    ControllerVersion,
)
from mirobot_async.bus._controller_bus import (
    ArmConnector,
    ArmTransport,
    BusOpener,
    ControllerBus,
    SingleArmConnector,
    connect,
)
from mirobot_async.bus._link import DEFAULT_BUS_BAUD, BusStats, BusTiming, NodeSilentError

__all__ = [
    "BAUD_CODES",
    "CONTROLLER_TIMEOUT",
    "DEFAULT_BUS_BAUD",
    "PINS",
    "ArmConnector",
    "ArmState",
    "ArmTransport",
    "BusOpener",
    "BusStats",
    "BusTiming",
    "Controller",
    "ControllerBus",
    "ControllerCommandError",
    "ControllerVersion",
    "NodeSilentError",
    "SingleArmConnector",
    "connect",
]
