"""The accessory and setting commands of :class:`~mirobot_async.client.Mirobot` (a mixin).

Each sends one line and awaits its reply through the facade's ``_command`` helpers, so errors,
timeouts and cancellation are those of :meth:`Mirobot.send <mirobot_async.client.Mirobot.send>`.
"""

from __future__ import annotations

from mirobot_async import gcode
from mirobot_async.deadline import deadline_after
from mirobot_async.parts import DEFAULT_TIMEOUT, MOVE_TIMEOUT, ClientParts

__all__ = ["AccessoryCommands"]


class AccessoryCommands(ClientParts):
    """Pump, valve, gripper, limits and settings: one-line commands of the facade."""

    # ---- outputs ----

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

    # ---- settings ----

    async def set_soft_limits(self, on: bool, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """``$20=1|0``: refuse (on) or allow joint targets outside the soft limits.

        Sent when nothing else is in flight; errors, ``timeout`` and cancellation as in
        :meth:`send`.
        """
        data = gcode.set_soft_limits(on)
        await self._command_within(data, timeout)

    async def set_hard_limits(self, on: bool, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
        """``$21=1|0``: stop with ``ALARM: Hard limit`` when a J1..J3 switch trips (on).

        Sent when nothing else is in flight; errors, ``timeout`` and cancellation as in
        :meth:`send`.
        """
        data = gcode.set_hard_limits(on)
        await self._command_within(data, timeout)

    async def settings(self, *, timeout: float | None = DEFAULT_TIMEOUT) -> dict[int, float]:
        """``$$``: every setting as ``{number: value}`` (also decides :attr:`firmware`).

        Sent when nothing else is in flight. Errors, ``timeout`` (default :data:`DEFAULT_TIMEOUT`)
        and cancellation as in :meth:`send`.
        """
        return await self._settings(deadline_after(self._running_loop(), timeout), timeout)

    async def set_setting(
        self, number: int, value: float, *, timeout: float | None = DEFAULT_TIMEOUT
    ) -> None:
        """Write ``$<number>=<value>`` (checked against the firmware's known settings first).

        Settings live in EEPROM and survive power cycles. Errors and ``timeout`` as in
        :meth:`send` (the firmware profile is detected first if unknown: see
        :meth:`detect_firmware`).
        """
        deadline = deadline_after(self._running_loop(), timeout)
        firmware = self._condition.firmware
        if firmware is None:
            gcode.set_setting(number, value)  # argument errors before any I/O
            firmware = await self._require_firmware(deadline, timeout)
        data = gcode.set_setting(number, value, firmware=firmware)
        await self._command(data, deadline=deadline, timeout=timeout)
