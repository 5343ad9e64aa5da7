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
from dataclasses import dataclass
from typing import Final, Literal

from mirobot_async._core.events import LineAcknowledged, LineRejected
from mirobot_async._core.line import ParsedLine
from mirobot_async.errors import (
    MirobotAlarmError,
    MirobotConnectionError,
    MirobotLinkLostError,
)

__all__ = [
    "HOMING_BOUND",
    "HOMING_DEFAULT_RATES",
    "REFUSAL_ALARMS",
    "RESET_ONLY_ALARMS",
    "Firmware",
    "HomingCycle",
    "RobotCondition",
    "firmware_from_banner",
    "homing_bound",
]

_log = logging.getLogger("mirobot_async.client")

Firmware = Literal["2021", "classic", "2024"]

FAMILY_2024_SETTINGS: Final = frozenset({44, 45, 51, 52})
"""Settings only the 2024 family lists in ``$$`` (EVIDENCE-NEWER.md 1: ``$44`` line discard
number, ``$45`` rail/conveyor mode, ``$51``, ``$52`` colour sensor); ``$29`` (D1) is the 2021
manual's, absent on classic."""
CLASSIC_BUILD_SUFFIX: Final = "--ZDX&LEAH(201306)"
"""What the classic firmware (oracle) appends to the build info in ``$I``; the 2024 family's
``$I`` has no suffix (``[0.9j.20160303:]``, EVIDENCE-NEWER.md 1). No 2021 device shows ``$I``."""
_ONE_LINE_VERSION_RE: Final = re.compile(r"Firmware version\s*:\s*(\S+)")
_BUILD_INFO_RE: Final = re.compile(r"\[[0-9.]+[a-z]?\.[0-9]{8}:(.*)\]")

# Alarms after which the firmware processes nothing but "%" (PROTOCOL.md 6.1; GRBL's critical
# alarms print "[Reset to continue]").
RESET_ONLY_ALARMS: Final = ("hard limit", "soft limit")
ALARM_STALL_WAIT: Final = 1.5
"""After printing an alarm the firmware stalls about 500 ms (the firmware tapes: its next line
starts 500.6 ms after the alarm's) and loses the realtime bytes that arrive meanwhile, ``%`` too;
after a reset-only alarm the stall ends with ``[Reset to continue]``. :meth:`Mirobot.reset
<mirobot_async.Mirobot.reset>` waits for that line, at most this many seconds after the alarm
arrived, before it writes its ``%`` (a ``%`` written earlier is lost: no banner would come)."""
REFUSAL_ALARMS: Final = frozenset({102, 106, 107})
"""The 2024 family's alarm-table lines that replace the classic "``ok`` but dropped" texts
(EVIDENCE-NEWER.md 2, INFERRED): ``A102`` ``Soft limit:<axis>`` (classic ``Soft limit
triggered:<axis>``), ``A106`` ``Locked status of each axis``, ``A107`` ``Axis 2 and 3 have
conflicting angles.:``. They are kept in the line's output (a refusal when its ``ok`` follows);
if the firmware instead stops as GRBL does at a soft limit, its ``[Reset to continue]`` makes
the alarm reset-only."""
_VERSION_RE: Final = re.compile(r"Robot\s+(\d{8})(\S*)")

_BannerResult = tuple[str, ...] | BaseException

HOMING_BOUND: Final = {"$H": 45.0, "$HH": 120.0}
"""The longest a homing line can stay unanswered at the default homing rates (seconds): the
firmware answers nothing, not even ``?``, until its switch search ends (oracle). Measured
searches: ``$H`` 8.2 s (oracle), 10-15 s on real arms (PROTOCOL.md 6.2), the 2021 ``$H0`` with
its rail 1.5 times longer; ``$HH`` 29.1 s (oracle). The bounds are three to four times those;
which of the two a line takes is :attr:`ParsedLine.homing_kind
<mirobot_async._core.line.ParsedLine.homing_kind>` (``$H0``..``$H7`` the ``$H`` bound; ``$HE``
and any other ``$H...`` the ``$HH`` one)."""
HOMING_DEFAULT_RATES: Final = (1500.0, 2000.0)
"""The homing feed ``$24`` and seek ``$25`` (deg/min) the bounds were measured at (both
profiles' defaults): slower rates stretch the bound in proportion."""


def homing_bound(
    kind: Literal["$H", "$HH"],
    rates: tuple[float, float] | None = None,
    bounds: Mapping[str, float] = HOMING_BOUND,
) -> float:
    """Seconds a homing search of ``kind`` (:attr:`ParsedLine.homing_kind
    <mirobot_async._core.line.ParsedLine.homing_kind>`) may go unanswered: ``bounds`` (default
    :data:`HOMING_BOUND`), stretched when the homing feed or seek (``rates``: ``$24``, ``$25``;
    ``None``: the defaults) is slower than :data:`HOMING_DEFAULT_RATES`."""
    base = bounds[kind]
    if rates is None:
        return base
    stretch = max(
        [1.0]
        + [
            default / rate
            for default, rate in zip(HOMING_DEFAULT_RATES, rates, strict=True)
            if rate > 0
        ]
    )
    return base * stretch


@dataclass(frozen=True, slots=True)
class HomingCycle:
    """A homing line written and not answered yet: the firmware answers no ``?`` until its
    switch search ends, which may take up to ``bound`` seconds after ``started``."""

    command: str
    started: float
    bound: float

    @property
    def ends_by(self) -> float:
        """The loop time by which its reply must have come (else the link is dead)."""
        return self.started + self.bound

    def describe(self) -> str:
        """Why the robot is silent, for error messages."""
        return (
            f"the arm is homing ({self.command!r}): the firmware answers nothing, not even "
            f"'?', until its homing search ends (at most {self.bound:g} s)"
        )


def firmware_from_banner(lines: Iterable[str]) -> tuple[Firmware | None, str | None]:
    """The profile and version printed in a banner (``(None, None)`` when it names none): the
    2024 family's one line ``WLKATA Robot started successfully.Firmware version:MT4,20240820``
    (version ``MT4,20240820``), or ``Qinnew Robot 20191228_2 based on...`` (classic before
    2021, else 2021)."""
    for line in lines:
        one_line = _ONE_LINE_VERSION_RE.search(line)
        if one_line is not None and "started successfully" in line:
            return "2024", one_line.group(1)
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
        self.firmware_evidence: str | None = None if firmware is None else "given (firmware=)"
        self.firmware_version: str | None = None
        self.banner: tuple[str, ...] | None = None
        self.alarm: str | None = None
        self.alarm_epoch = 0
        self.reset_only: str | None = None  # an alarm only "%" clears: nothing is sent
        # A reset-only alarm arrived and the stall after it ("[Reset to continue]") has not
        # ended yet: set when it ends (ALARM_STALL_WAIT); None when no stall is known.
        self.alarm_stall: asyncio.Event | None = None
        self.alarm_stall_ends_by = -math.inf  # loop time: the alarm's arrival + ALARM_STALL_WAIT
        self.reset_epoch = 0
        self.fatal: str | None = None
        self.closing = False
        self.connected = False
        # "%" written whose banner has not started yet: a second reset() joins it.
        self.reset_requested = False
        self.resetting = 0  # reset() calls awaiting their banner: no line is written meanwhile
        self.banner_started = -math.inf
        self._banner_waiters: list[tuple[float, asyncio.Future[_BannerResult]]] = []
        # The homing line in flight (the robot answers no "?" meanwhile), if any.
        self.homing: HomingCycle | None = None
        # The homing feed and seek $24, $25 when known (a $$ listing, or lines that set them).
        self.homing_rates: tuple[float, float] | None = None
        self.homing_bounds: dict[str, float] = dict(HOMING_BOUND)

    # ---- homing ----

    def homing_silent(self, now: float) -> HomingCycle | None:
        """The homing cycle in flight if its search may still be running at ``now`` (then the
        robot's silence is expected), else ``None``."""
        homing = self.homing
        if homing is not None and now < homing.ends_by:
            return homing
        return None

    def set_homing_rate(self, number: int, value: float) -> None:
        """A ``$24=``/``$25=`` line succeeded: the homing bound follows it."""
        feed, seek = self.homing_rates or HOMING_DEFAULT_RATES
        self.homing_rates = (value, seek) if number == 24 else (feed, value)

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

    @staticmethod
    def refuses_a_line(text: str, code: int | None) -> bool:
        """True for the 2024 family's :data:`REFUSAL_ALARMS` (``Error,A106,...``): the refusal
        of the line being parsed, not a state of the arm (its ``ok`` follows, or
        ``[Reset to continue]`` does: :meth:`on_feedback`)."""
        if code in REFUSAL_ALARMS:
            _log.info("robot refuses a line through its alarm table: %s", text)
            return True
        return False

    def on_alarm(self, text: str, now: float) -> bool:
        """Remember an alarm (arrived at loop time ``now``); True when only a reset clears it
        (nothing is answered)."""
        self.alarm = text
        self.alarm_epoch += 1
        _log.warning("robot alarm: %s", text)
        name = text.split(":", 1)[0].strip().lower()  # 2024: "Hard limit:X", the axis after
        if name in RESET_ONLY_ALARMS:
            self.reset_only = text
            self.alarm_stall = asyncio.Event()  # "%" is lost until "[Reset to continue]"
            self.alarm_stall_ends_by = now + ALARM_STALL_WAIT
            return True
        return False

    def on_feedback(self, text: str) -> bool:
        """``[Reset to continue]``: the firmware takes nothing but ``%`` now (True when this
        is news: then the waiting calls fail)."""
        if "reset to continue" not in text.lower():
            return False
        self.end_alarm_stall()
        if self.reset_only is None:
            self.reset_only = self.alarm or text
            return True
        return False

    def end_alarm_stall(self) -> None:
        """The firmware's stall after an alarm is over (it takes ``%`` again)."""
        if self.alarm_stall is not None:
            self.alarm_stall.set()
            self.alarm_stall = None

    def on_reset(self, now: float) -> None:
        """A banner started: the robot reset (a homing search in progress ended with it)."""
        self.reset_epoch += 1
        self.end_alarm_stall()
        self.homing = None
        self.banner_started = now
        self.reset_requested = False

    def on_banner(self, lines: tuple[str, ...]) -> None:
        """The banner ended: learn the firmware, release the reset() calls it answers."""
        self.banner = lines
        firmware, version = firmware_from_banner(lines)
        if version is not None:
            self.firmware_version = version
        if firmware is not None:
            line = next((line for line in lines if version is not None and version in line), "")
            self.learn_firmware(firmware, f"the banner {line!r}")
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
        firmware; ``$24``/``$25`` are the homing rates."""
        values = set(numbers)
        if isinstance(numbers, Mapping) and all(n in numbers for n in (24, 25)):
            self.homing_rates = (float(numbers[24]), float(numbers[25]))
        if not values:
            return
        family = sorted(values & FAMILY_2024_SETTINGS)
        if family:
            shown = ", ".join(f"${n}" for n in family)
            self.learn_firmware("2024", f"$$ lists {shown} (only the 2024 family has them)")
        elif 29 in values:
            self.learn_firmware("2021", "$$ lists $29..$34 (the 2021 manual's DH lengths)")
        else:
            self.learn_firmware("classic", "$$ lists no $29 (D1) and no 2024 setting")

    def learn_build_info(self, output: Iterable[str]) -> None:
        """The lines a ``$I`` printed: without the classic build suffix, the 2024 family."""
        for line in output:
            match = _BUILD_INFO_RE.fullmatch(line.strip())
            if match is not None and not match.group(1).endswith(CLASSIC_BUILD_SUFFIX):
                self.learn_firmware("2024", f"$I {line.strip()!r} has no {CLASSIC_BUILD_SUFFIX}")

    def learn_firmware(self, firmware: Firmware, evidence: str) -> None:
        """The family is decided once per connection, by the first evidence (a banner, ``$$``,
        ``$I``, or ``firmware=`` given): later evidence that disagrees is logged, not taken."""
        if self.firmware is None:
            self.firmware, self.firmware_evidence = firmware, evidence
            _log.info("firmware family %s: %s", firmware, evidence)
        elif self.firmware != firmware:
            _log.warning(
                "firmware family %r (%s), but %s says %r",
                self.firmware,
                self.firmware_evidence,
                evidence,
                firmware,
            )

    def cleared_by_reset(self, alarm_epoch: int) -> None:
        """A reset() ended: the reset-only lock is gone, and so is an alarm raised before it."""
        self.reset_only = None
        if self.alarm_epoch == alarm_epoch:
            self.alarm = None

    def on_line_answered(
        self, parsed: ParsedLine | None, reply: LineAcknowledged | LineRejected
    ) -> None:
        """The robot answered ``parsed`` (sent by any call, a stream or a path; the line parsed
        once when it was written): the facts its success settles, decided here only."""
        if parsed is None or not isinstance(reply, LineAcknowledged) or reply.refusal is not None:
            return
        if parsed.text == "$I":
            self.learn_build_info(reply.output)
        if parsed.clears_alarm:
            self.unlocked()
        dollar = parsed.dollar
        if dollar is not None and dollar.kind == "setting" and dollar.number in (24, 25):
            if dollar.value is not None:
                self.set_homing_rate(dollar.number, dollar.value)
        elif dollar is not None and dollar.kind == "restore":
            self.homing_rates = None  # the defaults again (or unknown: the same)

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
