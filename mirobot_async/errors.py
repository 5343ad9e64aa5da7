"""The one exception tree of mirobot-async.

Every error the library raises derives from :class:`MirobotError`, so ``except MirobotError``
catches them all; the leaves carry structured fields and build their own message, which names the
command involved and quotes the firmware's own words.

::

    MirobotError
    ├── MirobotUsageError (also ValueError)      bad arguments, caught before a byte is written
    │   ├── InvalidLineError                     a raw line the firmware would refuse or misread
    │   ├── MotionChainError                     a line streaming would make end elsewhere
    │   ├── PathRefused                          a path point refused (its index)
    │   ├── TapeFormatError                      a tape file that cannot be read (file, line)
    │   └── Unreachable, OutOfLimits, BehindShoulder   kinematics: no (reachable) solution
    ├── MirobotConnectionError                   the serial link could not be opened or failed
    │   └── MirobotLinkLostError                 the link closed or broke while in use
    ├── MirobotProtocolError                     garbled or unexpected bytes from the robot
    ├── MirobotTimeoutError (also TimeoutError)  a reply or condition did not come in time
    │   └── NodeSilentError                      a controller on the bus did not answer
    ├── MirobotResetError                        the robot reset while commands were pending
    ├── MirobotOutcomeUnknownError               a reset cut a line: whether it ran is unknown
    ├── PathError                                a path failed at one point (index, point, cause)
    ├── EmulatorError                            the emulator process failed or refused a command
    └── MirobotCommandError                      the firmware refused a line (error: / Error, Ennn)
        ├── MotionRefusedError                   "ok but dropped": locked, soft limit, unreachable
        ├── MirobotAlarmError                    the robot is in Alarm (hard limit, abort, ...)
        └── ControllerCommandError               a bus controller refused its own command
"""

from __future__ import annotations

import enum

__all__ = [
    "BehindShoulder",
    "ControllerCommandError",
    "EmulatorError",
    "EnvelopeRefusedError",
    "InvalidLineError",
    "MirobotAlarmError",
    "MirobotCommandError",
    "MirobotConnectionError",
    "MirobotError",
    "MirobotLinkLostError",
    "MirobotOutcomeUnknownError",
    "MirobotProtocolError",
    "MirobotResetError",
    "MirobotTimeoutError",
    "MirobotUsageError",
    "MotionChainError",
    "MotionRefusedError",
    "NodeSilentError",
    "OutOfLimits",
    "PathError",
    "PathRefused",
    "RefusalReason",
    "TapeFormatError",
    "Unreachable",
]


def _quote_command(command: str | bytes | None) -> str:
    if command is None:
        return ""
    if isinstance(command, bytes):
        command = command.decode("ascii", "replace")
    return command.rstrip("\r\n")


class MirobotError(Exception):
    """Root of every error raised by mirobot-async."""


class MirobotUsageError(MirobotError, ValueError):
    """A caller passed a bad argument; raised before anything is written to the robot."""


class EnvelopeRefusedError(MirobotUsageError):
    """The safety envelope refused a line before a byte of it was written: it leaves the
    envelope, or its effect cannot be predicted (the message names the line and why). The
    ``mirobot`` command exits 1 for it, as for any command the robot refuses."""


class MotionChainError(MirobotUsageError):
    """A line refused before it is written because, streamed behind queued motion, it would end
    elsewhere than sent after the arm stopped: its ``M20``/``M21`` makes the firmware restart
    from where the arm is, not from where the queued motion ends. :attr:`line` is the line;
    the message says which joints and the fix (state the mode once at the top, or ``G4 P0``
    before the line)."""

    def __init__(self, line: str, message: str) -> None:
        super().__init__(f"line {line!r} refused before sending: {message}")
        self.line = line


class MirobotConnectionError(MirobotError):
    """The serial link could not be opened, or failed."""


class MirobotLinkLostError(MirobotConnectionError):
    """The link closed (EOF, I/O error, ``close()``) while calls were pending or afterwards."""


class MirobotProtocolError(MirobotError):
    """The robot printed bytes that do not fit the protocol (garbled status, overlong line...)."""

    def __init__(self, message: str, *, data: bytes | str | None = None) -> None:
        self.data = data
        super().__init__(message)


class MirobotTimeoutError(MirobotError, TimeoutError):
    """A reply or a condition did not arrive in time. ``waited_for`` says what."""

    def __init__(
        self, waited_for: str, timeout: float | None = None, *, command: str | bytes | None = None
    ) -> None:
        self.waited_for = waited_for
        self.timeout = timeout
        self.command = _quote_command(command) or None
        msg = f"timed out waiting for {waited_for}"
        if timeout is not None:
            msg += f" after {timeout:g} s"
        if self.command:
            msg += f" (command {self.command!r})"
        super().__init__(msg)


class MirobotResetError(MirobotError):
    """The robot reset (its banner appeared) while this command was pending, and it was not run.

    Raised only when the client knows: the line was written before a reset the client asked for,
    or the robot answered every later line and none of its replies is this line's. A line whose
    fate a reset left open waits for the robot's replies instead of getting a guess.
    """

    def __init__(self, command: str | bytes | None = None, detail: str = "") -> None:
        self.command = _quote_command(command) or None
        msg = "the robot reset"
        if self.command:
            msg = f"{self.command!r} failed: the robot reset before acknowledging it"
        if detail:
            msg += f" ({detail})"
        super().__init__(msg)


class MirobotOutcomeUnknownError(MirobotError):
    """A reset caught this line on its way to the robot; whether it ran is unknown.

    The robot answered it after its reset, but that reply may be for the line's tail alone: a
    reset wipes the bytes the robot had received, and the rest of a line cut there is read as a
    line of its own. The client cannot tell the two apart, so it does not guess; ``reply`` is
    what the robot answered. Check the arm (its status) before going on.
    """

    def __init__(self, command: str | bytes | None, reply: str) -> None:
        self.command = _quote_command(command) or None
        self.reply = reply
        super().__init__(
            f"{self.command!r}: the robot reset while this line was on its way; it answered "
            f"{reply!r} after the reset, but that may be for the line's tail alone (the reset "
            "wiped what had arrived): whether the line ran is unknown"
        )


class MirobotCommandError(MirobotError):
    """The firmware refused a line. ``command`` is the line, ``text`` the firmware's words.

    ``code`` is the numeric code when the firmware printed one (2021: ``Error, E113,...`` -> 113).
    """

    def __init__(
        self,
        command: str | bytes | None,
        text: str,
        code: int | None = None,
        *,
        output: tuple[str, ...] = (),
    ) -> None:
        self.command = _quote_command(command)
        self.text = text
        self.code = code
        self.output = output
        super().__init__(self._message())

    def _message(self) -> str:
        where = f"{self.command!r}" if self.command else "command"
        code = f" (E{self.code})" if self.code is not None else ""
        return f"{where} refused by the firmware{code}: {self.text!r}"


class RefusalReason(enum.Enum):
    """Why the firmware acknowledged a motion line with ``ok`` but dropped it."""

    LOCKED = "locked"
    SOFT_LIMIT = "soft limit"
    UNREACHABLE = "unreachable"
    ANGLE_OUT_OF_LIMIT = "angle out of limit"


class MotionRefusedError(MirobotCommandError):
    """The firmware said ``ok`` but dropped the motion (locked, soft limit, unreachable...).

    ``reason`` is a :class:`RefusalReason`; ``axis`` the firmware axis letter for soft limits.
    """

    def __init__(
        self,
        command: str | bytes | None,
        text: str,
        reason: RefusalReason,
        *,
        axis: str | None = None,
        output: tuple[str, ...] = (),
    ) -> None:
        self.reason = reason
        self.axis = axis
        super().__init__(command, text, None, output=output)

    def _message(self) -> str:
        where = f"{self.command!r}" if self.command else "motion"
        return f"{where} was acknowledged but not executed ({self.reason.value}): {self.text!r}"


class MirobotAlarmError(MirobotCommandError):
    """The robot is in Alarm; motion is impossible until it is cleared (``$X``, homing, reset).

    ``text`` is the alarm text (``Hard limit``, ``Abort during cycle``...) or the firmware's
    ``Alarm lock`` refusal.
    """

    def _message(self) -> str:
        where = f"{self.command!r} failed: " if self.command else ""
        return f"{where}the robot is in Alarm: {self.text!r}"


# ---- errors of the parts (kinematics, validation, paths, the bus, the emulator process) ----


class Unreachable(MirobotUsageError):
    """The pose is outside the workspace: there is no valid value for theta3."""


class OutOfLimits(MirobotUsageError):
    """The pose has IK solutions, but none (of the requested branch) is within the joint limits."""


class BehindShoulder(MirobotUsageError):
    """The firmware does not go to this pose: its wrist centre lies behind the shoulder (within
    ``A1`` of the base axis); it solves the pose mirrored in front of the shoulder and the arm
    goes there (oracle: ``X1 Y5 Z182 A0 B0 C0`` ends at X 11.551 Y 57.749). ``actual``: that pose.
    """

    def __init__(self, message: str, actual: tuple[float, ...]) -> None:
        super().__init__(message)
        self.actual = actual


class InvalidLineError(MirobotUsageError):
    """A raw line refused before sending: the firmware would refuse it or read it otherwise
    (:attr:`problems` lists why, as :func:`check_line` reports them)."""

    def __init__(self, message: str, problems: tuple[str, ...]) -> None:
        super().__init__(message)
        self.problems = problems


class TapeFormatError(MirobotUsageError):
    """A tape file that cannot be read: truncated, invalid JSON, an unknown version or field
    (:attr:`path` and :attr:`line`, 1-based; 0 when the file itself is missing)."""

    def __init__(self, path: str, line: int, problem: str) -> None:
        super().__init__(f"{path}:{line}: bad tape: {problem}")
        self.path = path
        self.line = line
        self.problem = problem


class PathError(MirobotError):
    """A path failed at one point: :attr:`index` (0-based) and :attr:`point`; the robot's own
    error (a :class:`MotionRefusedError`, :class:`MirobotCommandError`, a reset...) is
    :attr:`error` (also the ``__cause__``)."""

    def __init__(self, index: int, point: tuple[float | None, ...], error: BaseException) -> None:
        super().__init__(f"path point {index} {point}: {error}")
        self.index = index
        self.point = point
        self.error = error


class PathRefused(EnvelopeRefusedError):
    """:meth:`EnvelopeGuard.preview` refused the line at :attr:`index`."""

    def __init__(self, index: int, message: str) -> None:
        super().__init__(message)
        self.index = index


class NodeSilentError(MirobotTimeoutError):
    """A node on the bus did not answer in time; names its address."""

    def __init__(self, address: int, command: str, timeout: float, detail: str = "") -> None:
        self.address = address
        super().__init__(
            f"a reply from the controller at @{address:02d}{detail}", timeout, command=command
        )


class ControllerCommandError(MirobotCommandError):
    """The controller answered ``error`` (or something else than expected) to a command."""

    def __init__(self, address: int, command: str, text: str) -> None:
        self.address = address
        super().__init__(command, text)

    def _message(self) -> str:
        return f"controller @{self.address:02d} refused {self.command!r}: {self.text!r}"


class EmulatorError(MirobotError):
    """The emulator process could not be started, died, or refused a control command."""
