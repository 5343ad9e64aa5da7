"""The setting commands of :class:`~mirobot_async._client.client.Mirobot` (a mixin): the ``$``
settings the firmware keeps in EEPROM (``$$``, ``$N=value``, the soft and hard limits).

Each sends one line and awaits its reply through the facade's ``_command`` helpers, so errors,
timeouts and cancellation are those of :meth:`Mirobot.send
<mirobot_async._client.client.Mirobot.send>`.
"""

from __future__ import annotations

from mirobot_async._client.deadline import deadline_after
from mirobot_async._client.parts import DEFAULT_TIMEOUT, ClientParts
from mirobot_async._core import gcode

__all__ = ["SettingCommands"]


class SettingCommands(ClientParts):
    """The firmware's settings: one-line ``$`` commands of the facade."""

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
