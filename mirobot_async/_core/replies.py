"""What the robot says: line classification and the status report (PURE: no I/O, no asyncio).

Everything the Mirobot prints is one line of ASCII text. This module answers two questions about
such a line, without any state:

* **What kind of line is it?** :func:`classify_line` returns a :class:`Reply` whose
  :class:`ReplyKind` tells the connection state machine (:mod:`mirobot_async._core.protocol`)
  whether the line is a final reply (``ok``, ``error: ...``, ``Error, E113,...``), asynchronous
  (``ALARM: ...``, ``<...>`` status), text that belongs to the command being executed (``[...]``
  feedback, ``Info, ...``, bare text), or the first / last line of the power-on banner.
* **What does a status report say?** :func:`parse_status` turns ``<Idle,Angle(ABCDXYZ):...>``
  into a :class:`StatusReport` with the joints in **J1..J6 order** (the wire order is
  J4, J5, J6, D, J1, J2, J3) and :meth:`StatusReport.to_line` prints it back byte for byte.

:func:`find_refusal` recognises the firmware's "``ok`` but dropped" texts (axes locked, soft limit,
unreachable target), the most common silent failure of existing SDKs.

The rules that are guesses rather than documented facts are marked **ASSUMED** and live in one
place each, so they can be changed without hunting (see PROTOCOL.md for the sources).
"""

from __future__ import annotations

import enum
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

from mirobot_async.errors import MirobotProtocolError, RefusalReason

__all__ = [
    "NONFINAL_INFO_CODES",
    "REFUSAL_TEXT_CODES",
    "Refusal",
    "Reply",
    "ReplyKind",
    "State",
    "StatusReport",
    "classify_line",
    "find_refusal",
    "format_status",
    "parse_setting_line",
    "parse_status",
]


# --------------------------------------------------------------------------------------------------
# Status report


class State(enum.Enum):
    """The firmware state word at the start of a status report (values are the exact words)."""

    IDLE = "Idle"
    RUN = "Run"
    HOLD = "Hold"
    HOME = "Home"
    ALARM = "Alarm"
    CHECK = "Check"
    DOOR = "Door"


_STATES: dict[str, State] = {s.value: s for s in State}

Joints = tuple[float, float, float, float, float, float]
Pose = tuple[float, float, float, float, float, float]


@dataclass(frozen=True, slots=True)
class StatusReport:
    """One parsed ``<...>`` status line: the answer to ``?``.

    ``joints`` are in **joint order J1..J6** (degrees), whatever the wire order; ``rail`` is the
    linear rail D in mm, or ``None`` when the line carried only 6 angles. ``pose`` is the flange
    pose ``(x, y, z, rx, ry, rz)`` in mm and degrees, as computed by the firmware's FK.
    ``pump_pwm`` / ``valve_pwm`` are the last ``M3 S`` / ``M4 E`` values and ``motion_mode`` is
    ``1`` after ``M20`` (Cartesian), ``0`` after ``M21`` (joint), ``None`` when the line has no
    ``Motion_MODE`` field (older firmware, manual templates).

    The constructor does not validate (parsing is on the hot path and :func:`parse_status` has
    already checked everything); a report built by hand with non-finite numbers prints a line that
    :func:`parse_status` rejects.
    """

    state: State
    joints: Joints
    rail: float | None
    pose: Pose
    pump_pwm: int
    valve_pwm: int
    motion_mode: int | None

    def to_line(self) -> str:
        """The status line exactly as the firmware prints it, without ``<CR><LF>``.

        See :func:`format_status` for the number format (and the sign of zero).
        """
        return format_status(self)


def _f(value: float) -> str:
    # C's printf("%.3f") and Python's "%.3f" agree: round half to even on the binary value, and a
    # negative value that rounds to zero prints "-0.000". Kept faithful (see format_status).
    return f"{value:.3f}"


def format_status(report: StatusReport) -> str:
    """Print ``report`` as the firmware does: ``<State,Angle(ABCDXYZ):...,Motion_MODE:m>``.

    * Wire order of the angles: J4, J5, J6, D, J1, J2, J3 (the firmware's internal axis letters
      A, B, C, D, X, Y, Z); with ``rail=None`` the D value is left out (6 angles).
    * Every float with exactly 3 decimals, like the firmware's ``%.3f``; PWM values and the motion
      mode as integers; no ``Motion_MODE`` field when ``motion_mode`` is ``None``.
    * **Sign of zero (decision):** the value is printed as C's ``%.3f`` prints it, so a negative
      value that rounds to zero (including ``-0.0``) prints ``-0.000``, which a real arm does print
      for tiny negative FK results. This is the only choice that makes the round trip exact in both
      directions: ``parse_status(line).to_line() == line`` for every line in the firmware's own
      format (``"-0.000"`` parses to ``-0.0`` and prints back as ``"-0.000"``), and
      ``parse_status(r.to_line()) == r`` for every report whose numbers have 3 decimals (``-0.0``
      and ``0.0`` compare equal). Normalising to ``0.000`` would break the first direction.
    """
    j1, j2, j3, j4, j5, j6 = report.joints
    x, y, z, rx, ry, rz = report.pose
    if report.rail is None:
        angles = f"{_f(j4)},{_f(j5)},{_f(j6)},{_f(j1)},{_f(j2)},{_f(j3)}"
    else:
        angles = f"{_f(j4)},{_f(j5)},{_f(j6)},{_f(report.rail)},{_f(j1)},{_f(j2)},{_f(j3)}"
    mode = "" if report.motion_mode is None else f",Motion_MODE:{report.motion_mode:d}"
    return (
        f"<{report.state.value},Angle(ABCDXYZ):{angles},"
        f"Cartesian coordinate(XYZ RxRyRz):{_f(x)},{_f(y)},{_f(z)},{_f(rx)},{_f(ry)},{_f(rz)},"
        f"Pump PWM:{report.pump_pwm:d},Valve PWM:{report.valve_pwm:d}{mode}>"
    )


# A number field: a run of ASCII sign, digit and dot characters, checked by float() / int()
# afterwards (twice as fast as spelling the number grammar out in the regex; "1.2.3" or "--1" then
# fail in float() and become MirobotProtocolError). No letters, so nan, inf and 1e5 never match;
# ASCII only ("\d" would accept other scripts' digits); bounded length, so float() cannot overflow
# to inf and int() stays far from its digit limit. The firmware always prints 3 decimals; other
# counts ("1", "1.5", ".5") are accepted leniently.
_NUM = r"([-+0-9.]{1,24})"
_INT = r"([-+0-9]{1,10})"

# One compiled regex for the whole line. Variants accepted (PROTOCOL.md section 5):
# "Value PWM" for "Valve PWM"; no Motion_MODE field; "(XYZRxRyRz)" without the space; 6 angles.
# 6 angles: ASSUMED order J4, J5, J6, J1, J2, J3, i.e. the D (rail) value left out: the manuals
# describe D as "external rail (if present)" between J6 and J1. The header may then read
# "Angle(ABCXYZ)". The optional group for D is unambiguous: the literal that follows anchors it.
_STATUS_RE = re.compile(
    r"<(Idle|Run|Hold|Home|Alarm|Check|Door),"
    r"Angle\(ABCD?XYZ\):"
    rf"{_NUM},{_NUM},{_NUM},(?:{_NUM},)?{_NUM},{_NUM},{_NUM},"
    r"Cartesian coordinate\(XYZ ?RxRyRz\):"
    rf"{_NUM},{_NUM},{_NUM},{_NUM},{_NUM},{_NUM},"
    rf"Pump PWM:{_INT},Va(?:lv|lu)e PWM:{_INT}"
    rf"(?:,Motion_MODE:{_INT})?"
    r"(?:,Buf:[0-9]{1,3})?(?:,RX:[0-9]{1,3})?(?:,Lim:[01]{1,8})?>"
)
"""A status report with the angles, the pose and the PWM values (``$10`` bits 1 and 32), and
what the other bits of the mask add: ``Motion_MODE`` (64), ``Buf`` (4), ``RX`` (8), ``Lim`` (16).
"""


def parse_status(line: str | bytes) -> StatusReport:
    """Parse one status line (``str`` or ``bytes``) into a :class:`StatusReport`.

    Surrounding whitespace and line endings are ignored. Accepts the firmware's line and the
    variants of PROTOCOL.md section 5. Raises :class:`MirobotProtocolError` (and nothing else, for
    any input) when the line is not a complete, well-formed status report: a corrupted status is a
    recoverable event (drop it, poll again), never a crash.
    """
    if isinstance(line, bytes | bytearray):
        try:
            text = line.decode("ascii")
        except UnicodeDecodeError:
            raise MirobotProtocolError(
                "status line contains non-ASCII bytes", data=bytes(line)
            ) from None
    elif isinstance(line, str):
        text = line
    else:
        raise MirobotProtocolError(f"status line must be str or bytes, not {type(line).__name__}")
    m = _STATUS_RE.fullmatch(text.strip())
    if m is None:
        raise MirobotProtocolError(_diagnose(text.strip()), data=line)
    (state, a4, a5, a6, d, a1, a2, a3, x, y, z, rx, ry, rz, pump, valve, mode) = m.groups()
    try:
        return StatusReport(
            _STATES[state],
            (float(a1), float(a2), float(a3), float(a4), float(a5), float(a6)),
            None if d is None else float(d),
            (float(x), float(y), float(z), float(rx), float(ry), float(rz)),
            int(pump),
            int(valve),
            None if mode is None else int(mode),
        )
    except ValueError:
        raise MirobotProtocolError(f"bad number in status line {text[:120]!r}", data=line) from None


_SETTING_LINE_RE = re.compile(r"\$(\d{1,3})\s*=\s*([+-]?(?:\d+\.?\d*|\.\d+))(?:[^\d.].*)?")


def parse_setting_line(line: str | bytes) -> tuple[int, float] | None:
    """``(number, value)`` of one line of a ``$$`` listing (``$110=1800.000 (...)``), or None
    for any other line (the one reading of the listing: the client and the port probe)."""
    text = line.decode("ascii", "replace") if isinstance(line, bytes | bytearray) else line
    m = _SETTING_LINE_RE.fullmatch(text.strip())
    if m is None:
        return None
    return int(m.group(1)), float(m.group(2))


_DIAG_HEAD_RE = re.compile(r"<([A-Za-z]*)")


def _diagnose(text: str) -> str:
    """A short human reason for a status line that did not match (slow path only)."""
    if not text.startswith("<"):
        return f"status line does not start with '<': {text[:80]!r}"
    if not text.endswith(">"):
        return f"status line is truncated (no closing '>'): {text[:80]!r}"
    head = _DIAG_HEAD_RE.match(text)
    if head is not None and head.group(1) not in _STATES:
        return f"unknown state {head.group(1)!r} in status line {text[:80]!r}"
    if ",Angle(" not in text or ",Pump PWM:" not in text:
        return (
            f"status line {text[:80]!r} lacks the angles or the PWM values: the robot's status "
            "report mask $10 leaves them out (set $10=99)"
        )
    low = text.lower()
    if "nan" in low or "inf" in low:
        return f"non-finite number in status line {text[:80]!r}"
    return f"malformed status line {text[:120]!r}"


# --------------------------------------------------------------------------------------------------
# Line classification


class ReplyKind(enum.Enum):
    """What a line printed by the robot is, for the connection state machine."""

    OK = "ok"  # final reply: success ("ok" alone; glued oks are TEXT/INFO/FEEDBACK with ok=True)
    ERROR = "error"  # final reply: failure, "error: <text>" or "Error, E<code>,<text>"
    ALARM = "alarm"  # asynchronous: "ALARM: <text>"
    FEEDBACK = "feedback"  # "[<text>]"
    INFO = "info"  # 2021: "Info, <text>"
    STATUS = "status"  # "<...>" (possibly corrupted: parse it to know)
    BANNER_START = "banner start"  # first line of the reset banner: the robot reset
    BANNER_END = "banner end"  # "Using reset pos!": last line of the banner
    BANNER = "banner"  # a whole one-line banner (2024: "WLKATA Robot started successfully...")
    TEXT = "text"  # anything else (classic bare info, banner body, ""), also empty lines
    UNKNOWN = "unknown"  # a line in a reply form (Error,/Info,/non-ASCII) but none of the known


@dataclass(frozen=True, slots=True)
class Reply:
    """One classified line.

    ``text`` is the payload: the error text, the alarm text, the feedback inside ``[]``, the info
    after ``Info, ``, the status line itself, or the whole (stripped) line for TEXT and banner
    lines; a glued ``ok`` is *not* part of it. ``code`` is the 2021 error number
    (``Error, E113,...`` -> 113). ``ok`` is True for ``ok`` and for a text line ending in a glued
    ``ok`` (``in homeing moving...ok``): such a line is both text and the final reply. ``raw`` is
    the line as received, without its line ending.

    The 2024 family (EVIDENCE-NEWER.md) numbers its texts: ``Info,E102,Invalid statement``
    (a refusal: ERROR, code 102), ``Error,A102,Soft limit:B`` (ALARM, code 102),
    ``Info,A100,Line Discard`` (INFO, code 100; its ``ok`` follows), ``Error,E118,...`` (TEXT,
    code 118: an "``ok`` but dropped" text, see :data:`REFUSAL_TEXT_CODES`).
    """

    kind: ReplyKind
    text: str
    code: int | None
    ok: bool
    raw: str


# Numbered lines: 2021 "Error, E113,Undefined feed rate"; 2024 "Error,E113,...",
# "Error,E000, Invalid gcode ID:24", "Error,A102,Soft limit:B", "Info,E102,Invalid statement",
# "Info,A100,Line Discard". Spaces after the commas optional; the text may be empty.
_CODED_RE = re.compile(
    r"(Error|Info)\s*,\s*([EA])([0-9]{1,9})\s*(?:,\s*(.*))?", re.IGNORECASE | re.DOTALL
)
# What claims to be a numbered or an error line: one that does not match _CODED_RE is UNKNOWN.
_CODED_HEAD_RE = re.compile(r"(?:Error\s*,|Info\s*,\s*[EA][0-9])", re.IGNORECASE)
# Classic GRBL style with a number only ("error:23" as GRBL 1.1 prints it).
_DIGITS_RE = re.compile(r"[0-9]{1,9}")
_INFO_RE = re.compile(r"Info\s*[,:]\s*(.*)", re.IGNORECASE | re.DOTALL)
_SWITCH_ALARM_RE = re.compile(r"[01]{8}ALARM:(.*)", re.IGNORECASE)
# Printable ASCII and tab: a line with any other byte is line noise, not a reply.
_NOISE_RE = re.compile(r"[^\t\x20-\x7e]")
# The 2024 family's one-line banner: "WLKATA Robot started successfully.Firmware
# version:MT4,20240820" (EVIDENCE-NEWER.md 1).
_ONE_LINE_BANNER_RE = re.compile(r".*\bstarted successfully\b.*\bFirmware version\s*:.*")

REFUSAL_TEXT_CODES: Final = frozenset({118, 119})
"""``Error,E118,The given location is outside the workspace.`` and ``Error,E119,The angle of an
axis is out of range.``: the 2024 family's forms of the classic "``ok`` but dropped" texts
(``GOAL OUT OF WORKSPACE...``, ``There is one angle out of limit!!!``). **INFERRED**
(EVIDENCE-NEWER.md 2): printed as the classic texts are (an empty line first), so their ``ok``
follows; they are text for the line, never its final reply. Taking them as final would give
that ``ok`` to the next line (a shifted attribution); this way a missing ``ok`` is at worst a
lost reply, which the client detects."""

NONFINAL_INFO_CODES: Final = frozenset({100})
"""``Info,A100,Line Discard``: its ``ok`` follows (the message table: ``...Line Discard\nok``)."""


def _coded(s: str, raw: str) -> Reply | None:
    """A numbered 2021/2024 line, or None when ``s`` is not one."""
    m = _CODED_RE.fullmatch(s)
    if m is None:
        return None
    prefix, letter, number, rest = m.groups()
    code, text = int(number), (rest or "").strip()
    if letter in "Aa":
        if prefix[0] in "Ii" or code in NONFINAL_INFO_CODES:
            return Reply(ReplyKind.INFO, text, code, False, raw)
        return Reply(ReplyKind.ALARM, text, code, False, raw)
    if prefix[0] in "Ee" and code in REFUSAL_TEXT_CODES:
        ok = _glued_ok(s)  # as the classic GOAL text's "...THETA3!ok"
        return Reply(ReplyKind.TEXT, s[:-2].rstrip() if ok else s, code, ok, raw)
    return Reply(ReplyKind.ERROR, text, code, False, raw)


def _glued_ok(text: str) -> bool:
    """True when ``text`` ends with an ``ok`` glued to other text, the final reply on its line.

    Seen on real arms: ``in homeing moving...ok`` and ``Info, in homing moving...ok``. The rule
    (ASSUMED, one place): the line ends in ``ok`` and the character before it is not a letter or
    digit, so that words like ``look`` or ``Took`` do not count.
    """
    return len(text) > 2 and text.endswith("ok") and not text[-3].isalnum()


def _is_banner_start(s: str) -> bool:
    # "Grbl 0.9j ['$' for help]" (GRBL's reset line) or any "... based on Grbl ..." line (the
    # vendor's second banner line). A second banner start while the state machine is already
    # collecting a banner is part of the same banner (see protocol.py).
    return (s.startswith("Grbl ") and s.endswith("help]")) or "based on Grbl" in s


def classify_line(line: str | bytes) -> Reply:
    """Classify one line printed by the robot (without or with its line ending).

    Rules, in order (on the line stripped of surrounding whitespace):

    * ``""`` -> TEXT with text ``""`` (the state machine ignores empty lines before classifying).
    * ``ok`` -> OK.
    * ``<...`` -> STATUS (also when truncated: it is a status reply, to be parsed and maybe
      reported corrupted, never text for a command).
    * a line with a byte outside printable ASCII (line noise) -> UNKNOWN.
    * ``error: <text>`` -> ERROR (``error:23`` gives code 23); ``Error, E113,<text>`` (2021) and
      ``Error,E113,<text>`` (2024) -> ERROR with code 113 (spaces after commas optional), except
      :data:`REFUSAL_TEXT_CODES` (TEXT with the code); ``Info,E102,<text>`` (2024) -> ERROR with
      code 102 (the line's only reply); ``Error,A102,<text>`` -> ALARM with code 102;
      ``Info,A100,<text>`` -> INFO with code 100; any other ``Error,...`` or ``Info,E<digit>...``
      line -> UNKNOWN (never a final reply).
    * ``ALARM: <text>`` -> ALARM, also after the eight switch bits the firmware prints before a
      hard-limit alarm (``00010000ALARM: Hard limit``).
    * ``Grbl x ['$' for help]`` or ``... based on Grbl ...`` -> BANNER_START;
      ``Using reset pos!`` -> BANNER_END; ``... started successfully ... Firmware version:...``
      -> BANNER (a whole banner in one line).
    * otherwise the line is text; a glued ``ok`` at its end is removed and sets ``ok=True``; the
      remainder is ``[<text>]`` -> FEEDBACK, ``Info, <text>`` -> INFO, or anything else -> TEXT
      (``Qinnew``/``WLKATA`` banner lines, classic bare replies such as ``M50: Unlock each axis.``).
    """
    if isinstance(line, bytes | bytearray):
        line = bytes(line).decode("ascii", "replace")
    raw = line.rstrip("\r\n")
    s = raw.strip()
    if s == "ok":
        return Reply(ReplyKind.OK, "", None, True, raw)
    if not s:
        return Reply(ReplyKind.TEXT, "", None, False, raw)
    first = s[0]
    if first == "<":
        return Reply(ReplyKind.STATUS, s, None, False, raw)
    if _NOISE_RE.search(s) is not None:
        return Reply(ReplyKind.UNKNOWN, s, None, False, raw)
    if first in "EeIi":
        if s[:6].lower() == "error:":
            text = s[6:].strip()
            code = int(text) if _DIGITS_RE.fullmatch(text) else None
            return Reply(ReplyKind.ERROR, text, code, False, raw)
        if _CODED_HEAD_RE.match(s) is not None:
            coded = _coded(s, raw)
            return coded if coded is not None else Reply(ReplyKind.UNKNOWN, s, None, False, raw)
    elif first in "Aa" and s[:6].upper() == "ALARM:":
        return Reply(ReplyKind.ALARM, s[6:].strip(), None, False, raw)
    elif first in "01" and (m := _SWITCH_ALARM_RE.fullmatch(s)) is not None:
        # The firmware prints the eight limit-switch bits before a hard-limit alarm (oracle).
        return Reply(ReplyKind.ALARM, m.group(1).strip(), None, False, raw)
    elif first == "G" and _is_banner_start(s):
        return Reply(ReplyKind.BANNER_START, s, None, False, raw)
    elif first == "U" and s.startswith("Using reset pos"):
        return Reply(ReplyKind.BANNER_END, s, None, False, raw)
    if "based on Grbl" in s:
        return Reply(ReplyKind.BANNER_START, s, None, False, raw)
    if "started successfully" in s and _ONE_LINE_BANNER_RE.fullmatch(s) is not None:
        return Reply(ReplyKind.BANNER, s, None, False, raw)
    ok = _glued_ok(s)
    body = s[:-2].rstrip() if ok else s
    if body.startswith("[") and body.endswith("]"):
        return Reply(ReplyKind.FEEDBACK, body[1:-1].strip(), None, ok, raw)
    if body[:4].lower() == "info" and (m := _INFO_RE.fullmatch(body)) is not None:
        return Reply(ReplyKind.INFO, m.group(1).strip(), None, ok, raw)
    return Reply(ReplyKind.TEXT, body, None, ok, raw)


# --------------------------------------------------------------------------------------------------
# "ok but dropped"


@dataclass(frozen=True, slots=True)
class Refusal:
    """A motion the firmware acknowledged with ``ok`` but did not execute.

    ``text`` is the firmware's line; ``axis`` the firmware axis letter for a soft limit
    (``X Y Z A B C D``), else ``None``.
    """

    reason: RefusalReason
    text: str
    axis: str | None


# Matched leniently (substring, case-insensitive), so a 2021 "Info, " prefix or a trailing glued
# "ok" does not hide them. The GOAL text is the vendor's ("VAILD VALUS"); only its start is used.
# The 2024 family's forms (EVIDENCE-NEWER.md 2, INFERRED as refusals: they replace the classic
# texts): "Error,A106,Locked status of each axis", "Error,A102,Soft limit:B" (the axis after the
# colon), "Error,E118,The given location is outside the workspace.", "The Cartesian position
# exceeds the boundary.", "Error,E119,The angle of an axis is out of range.", "Error,A107,Axis 2
# and 3 have conflicting angles.:", "Axis 2 and 3 angles are too small." / "... too big.".
_REFUSAL_RE = re.compile(
    r"(?P<locked>locked status of each axis)"
    r"|(?P<soft>soft limit(?:\s+triggered\s*:?|\s*:)\s*(?P<axis>[A-Za-z](?![A-Za-z]))?)"
    r"|(?P<goal>goal out of workspace|location is outside the workspace"
    r"|position exceeds the boundary)"
    r"|(?P<angle>angle out of limit|angle of an axis is out of range"
    r"|axis 2 and 3 (?:have conflicting angles|angles are too))",
    re.IGNORECASE,
)


def find_refusal(output: Sequence[str]) -> Refusal | None:
    """The first "``ok`` but dropped" text in the lines a command printed, or ``None``.

    ``Locked status of each axis!`` -> LOCKED; ``Soft limit triggered:<axis>`` -> SOFT_LIMIT with
    the axis letter; ``GOAL OUT OF WORKSPACE...`` -> UNREACHABLE;
    ``There is one angle out of limit!!!`` -> ANGLE_OUT_OF_LIMIT. Lines that are alarms
    (``ALARM: Soft limit``) are not refusals.
    """
    for line in output:
        m = _REFUSAL_RE.search(line)
        if m is None or line.lstrip()[:6].upper() == "ALARM:":
            continue
        text = line.strip()
        if m.group("locked"):
            return Refusal(RefusalReason.LOCKED, text, None)
        if m.group("soft"):
            axis = m.group("axis")
            return Refusal(RefusalReason.SOFT_LIMIT, text, None if axis is None else axis.upper())
        if m.group("goal"):
            return Refusal(RefusalReason.UNREACHABLE, text, None)
        return Refusal(RefusalReason.ANGLE_OUT_OF_LIMIT, text, None)
    return None
