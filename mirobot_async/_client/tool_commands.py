"""The tool commands of :class:`~mirobot_async._client.client.Mirobot` (a mixin): the pump, the
valve and the servo gripper, on the firmware's two PWM outputs (``M3``/``M4``).

Each sends one line and awaits its reply through the facade's ``_command`` helpers, so errors,
timeouts and cancellation are those of :meth:`Mirobot.send
<mirobot_async._client.client.Mirobot.send>`.
"""

from __future__ import annotations

from mirobot_async._client.parts import MOVE_TIMEOUT, ClientParts
from mirobot_async._core import gcode

__all__ = ["ToolCommands"]


class ToolCommands(ClientParts):
    """Pump, valve and gripper: one-line commands of the facade."""

    async def set_pump(self, pwm: int, *, timeout: float | None = MOVE_TIMEOUT) -> None:
        """``M3 S<pwm>``: PWM output 1 (pump: 0 off, 500 blow, 1000 suck; servo gripper).

        The firmware answers it only once the motion queued before it has ended (and switches
        the output then), so its ``timeout`` defaults to :data:`MOVE_TIMEOUT`, as a
        ``wait=True`` move's does. Errors and cancellation as in :meth:`send`.
        """
        data = gcode.set_pump(pwm)
        await self._command_within(data, timeout)

    async def set_valve(self, pwm: int, *, timeout: float | None = MOVE_TIMEOUT) -> None:
        """``M4 E<pwm>``: PWM output 2 (valve, or the V1.1 gripper). As :meth:`set_pump`."""
        data = gcode.set_valve(pwm)
        await self._command_within(data, timeout)

    async def suction_on(self, *, timeout: float | None = MOVE_TIMEOUT) -> None:
        """Suction cup: pump sucking (``M3 S1000``). As :meth:`set_pump`."""
        await self.set_pump(gcode.PUMP_SUCK, timeout=timeout)

    async def blow(self, *, timeout: float | None = MOVE_TIMEOUT) -> None:
        """Suction cup: pump blowing, to release a part (``M3 S500``). As :meth:`set_pump`."""
        await self.set_pump(gcode.PUMP_BLOW, timeout=timeout)

    async def pump_off(self, *, timeout: float | None = MOVE_TIMEOUT) -> None:
        """Pump off (``M3 S0``). As :meth:`set_pump`."""
        await self.set_pump(gcode.PUMP_OFF, timeout=timeout)

    async def gripper_open(
        self, *, legacy: bool = False, timeout: float | None = MOVE_TIMEOUT
    ) -> None:
        """Open the servo gripper (``M3 S40``; ``legacy=True``: the V1.1 gripper, ``M4 E65``).

        As :meth:`set_pump`."""
        data = gcode.set_gripper(False, legacy=legacy)
        await self._command_within(data, timeout)

    async def gripper_close(
        self, *, legacy: bool = False, timeout: float | None = MOVE_TIMEOUT
    ) -> None:
        """Close the servo gripper (``M3 S60``; ``legacy=True``: ``M4 E40``).

        As :meth:`set_pump`."""
        data = gcode.set_gripper(True, legacy=legacy)
        await self._command_within(data, timeout)
