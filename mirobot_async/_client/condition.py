"""The robot's condition as the client knows it: alarm, resets, a dead link, the firmware.

:class:`RobotCondition` holds what decides whether anything may be sent at all (a lost link, an
alarm that only a reset clears, a remembered alarm for motion calls), counts resets and alarms
in *epochs* (so that a waiting call can tell that one happened meanwhile), keeps the callers of
:meth:`Mirobot.reset <mirobot_async._client.client.Mirobot.reset>` waiting for their banner, and
learns the firmware profile from banners (or a ``$$`` listing the user asked for).
"""

from __future__ import annotations

import asyncio
import logging
import math
import re
from collections.abc import Iterable, Mapping
from typing import Final, Literal

from mirobot_async.errors import (
    MirobotAlarmError,
    MirobotConnectionError,
    MirobotLinkLostError,
)

__all__ = ["RESET_ONLY_ALARMS", "Firmware", "RobotCondition", "firmware_from_banner"]

_log = logging.getLogger("mirobot_async.client")

Firmware = Literal["2021", "classic"]

# Alarms after which the firmware processes nothing but "%" (PROTOCOL.md 6.1; GRBL's critical
# alarms print "[Reset to continue]").
RESET_ONLY_ALARMS: Final = ("hard limit", "soft limit")
_VERSION_RE: Final = re.compile(r"Robot\s+(\d{8})(\S*)")

_BannerResult = tuple[str, ...] | BaseException


def firmware_from_banner(lines: Iterable[str]) -> tuple[Firmware | None, str | None]:
    """The profile and version printed in a banner (``(None, None)`` when it names none)."""
    for line in lines:
        match = _VERSION_RE.search(line)
        if match is not None:
            date = match.group(1)
            version = date + match.group(2)
            return ("classic" if date < "20210000" else "2021"), version
    return None, None


class RobotCondition:
    """Alarm, reset and link state of one connection (no I/O of its own)."""

    def __init__(self, firmware: Firmware | None) -> None:
        self.firmware: Firmware | None = firmware
        self.firmware_version: str | None = None
        self.banner: tuple[str, ...] | None = None
        self.alarm: str | None = None
        self.alarm_epoch = 0
        self.reset_only: str | None = None  # an alarm only "%" clears: nothing is sent
        self.reset_epoch = 0
        self.fatal: str | None = None
        self.closing = False
        self.connected = False
        # "%" written whose banner has not started yet: a second reset() joins it.
        self.reset_requested = False
        self.resetting = 0  # reset() calls awaiting their banner: no line is written meanwhile
        self.banner_started = -math.inf
        # The 2021 base offset $41..$43 from the last $$ listing (None: unknown or changed since).
        self.base_offset: tuple[float, float, float] | None = None
        self._banner_waiters: list[tuple[float, asyncio.Future[_BannerResult]]] = []

    # ---- may anything be sent? ----

    def raise_if_closed(self) -> None:
        """Raise :class:`MirobotLinkLostError` once the link is gone (or it was never open)."""
        if self.fatal is not None:
            raise MirobotLinkLostError(self.fatal)
        if not self.connected:
            raise MirobotConnectionError("not connected: use Mirobot.connect(url)")

    def check_sendable(self, command: str | None, *, motion: bool) -> None:
        """Raise unless ``command`` may be sent now (link up, no reset-only alarm, no alarm for
        ``motion`` calls)."""
        self.raise_if_closed()
        if self.reset_only is not None:
            raise MirobotAlarmError(
                command,
                f"{self.reset_only} (nothing, not even a status request, is sent until reset())",
            )
        if motion and self.alarm is not None:
            raise MirobotAlarmError(command, self.alarm)

    def check_answering(self) -> None:
        """Raise unless the robot answers status requests (link up, no reset-only alarm)."""
        self.raise_if_closed()
        if self.reset_only is not None:
            raise MirobotAlarmError(
                None,
                f"{self.reset_only} (the robot answers nothing, not even '?', until reset())",
            )

    # ---- events ----

    def on_alarm(self, text: str) -> bool:
        """Remember an alarm; True when only a reset clears it (nothing is answered)."""
        self.alarm = text
        self.alarm_epoch += 1
        _log.warning("robot alarm: %s", text)
        if text.strip().lower() in RESET_ONLY_ALARMS:
            self.reset_only = text
            return True
        return False

    def on_feedback(self, text: str) -> None:
        """``[Reset to continue]``: the firmware takes nothing but ``%`` now."""
        if "reset to continue" in text.lower():
            self.reset_only = self.reset_only or (self.alarm or text)

    def on_reset(self, now: float) -> None:
        """A banner started: the robot reset."""
        self.reset_epoch += 1
        self.banner_started = now
        self.reset_requested = False

    def on_banner(self, lines: tuple[str, ...]) -> None:
        """The banner ended: learn the firmware, release the reset() calls it answers."""
        self.banner = lines
        firmware, version = firmware_from_banner(lines)
        if version is not None:
            self.firmware_version = version
        if firmware is not None:
            if self.firmware is not None and self.firmware != firmware:
                _log.warning(
                    "firmware=%r was given but the banner says %r", self.firmware, firmware
                )
            else:
                self.firmware = firmware
        keep = []
        for asked_at, fut in self._banner_waiters:
            if fut.done():
                continue
            if asked_at <= self.banner_started:
                fut.set_result(lines)
            else:
                keep.append((asked_at, fut))
        self._banner_waiters = keep

    def learn_firmware_from_settings(self, numbers: Iterable[int]) -> None:
        """A ``$$`` listing (numbers, or a mapping to values): ``$29`` exists only on the 2021
        firmware; ``$41..$43`` is the base offset."""
        values = set(numbers)
        if isinstance(numbers, Mapping) and all(n in numbers for n in (41, 42, 43)):
            self.base_offset = (float(numbers[41]), float(numbers[42]), float(numbers[43]))
        if self.firmware is None and values:
            self.firmware = "2021" if 29 in values else "classic"

    def cleared_by_reset(self, alarm_epoch: int) -> None:
        """A reset() ended: the reset-only lock is gone, and so is an alarm raised before it."""
        self.reset_only = None
        if self.alarm_epoch == alarm_epoch:
            self.alarm = None

    def unlocked(self) -> None:
        """``$X``, ``$H``... succeeded: forget the remembered alarm (not a reset-only one)."""
        if self.reset_only is None:
            self.alarm = None

    # ---- reset() callers ----

    def add_banner_waiter(self, asked_at: float, fut: asyncio.Future[_BannerResult]) -> None:
        """``fut`` gets the first banner that starts after ``asked_at``."""
        self._banner_waiters.append((asked_at, fut))

    def remove_banner_waiter(self, asked_at: float, fut: asyncio.Future[_BannerResult]) -> None:
        """Forget a waiter (its reset() call ended)."""
        entry = (asked_at, fut)
        if entry in self._banner_waiters:
            self._banner_waiters.remove(entry)

    @property
    def banner_waiters_waiting(self) -> bool:
        """True while some reset() call waits for its banner."""
        return any(not fut.done() for _, fut in self._banner_waiters)

    def set_fatal(self, message: str) -> bool:
        """The link is unusable; True the first time (then fail the banner waiters)."""
        if self.fatal is not None:
            return False
        self.fatal = message
        return True

    def fail_banner_waiters(self, message: str) -> None:
        """Every reset() waiting for its banner fails with :class:`MirobotLinkLostError`."""
        for _, fut in self._banner_waiters:
            if not fut.done():
                fut.set_result(MirobotLinkLostError(f"{message}; no banner"))
        self._banner_waiters.clear()
