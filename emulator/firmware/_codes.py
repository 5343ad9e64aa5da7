"""The firmware's numbers and texts: GRBL 0.9j status codes, error lines per profile, the
Mirobot messages of PROTOCOL 4.3, the ``$`` help and the version strings."""

from __future__ import annotations

from typing import Final

PROFILES: Final = ("classic", "2021", "2024")

BEHAVES_AS: Final = {"classic": "classic", "2021": "2021", "2024": "2021"}
"""The profile whose behaviour a profile has: the 2024 family is the 2021 profile with its own
texts, banner, settings list and states (EVIDENCE-NEWER.md; ASSUMED where it is silent:
docs/2024-profile.md). Code that compares the profile reads this one; texts read the family."""

VERSIONS: Final = {"classic": "20191228_2", "2021": "20210516", "2024": "20240820"}
GRBL_VERSION: Final = "0.9j"
GRBL_BUILD: Final = "20160303"
"""GRBL's build date in ``$I`` (the classic firmware's; ASSUMED the same on 2021)."""
BUILD_INFO_SUFFIX: Final = {
    "classic": "--ZDX&LEAH(201306)",
    "2021": "--ZDX&LEAH(201306)",
    "2024": "",
}
"""What ``$I`` appends to the stored build info (the classic firmware's, oracle; on 2021 the
same, no 2021 evidence shows ``$I``: docs/2021-profile.md; 2024: nothing, the MT4 capture's
``[0.9j.20160303:]``)."""
BANNER_2024: Final = "WLKATA Robot started successfully.Firmware version:Mirobot,{version}"
"""The 2024 family's whole banner (the MT4 capture's line; ``Mirobot`` INFERRED from the
``Mirobot,20240820`` build in the same flash image)."""
ANSWERS_STATUS_WHILE_HOMING: Final = {"classic": False, "2021": False, "2024": True}
"""Whether ``?`` is answered during the homing search (oracle: not on classic, and 2021 as
classic; 2024: the 2026 Mirobot shows ``Home`` to a host polling ``?``, INFERRED)."""

# --- GRBL 0.9j status codes ---------------------------------------------------------------
EXPECTED_COMMAND_LETTER: Final = 1
BAD_NUMBER_FORMAT: Final = 2
INVALID_STATEMENT: Final = 3
NEGATIVE_VALUE: Final = 4
SETTING_DISABLED: Final = 5
SETTING_STEP_PULSE_MIN: Final = 6
IDLE_ERROR: Final = 8
ALARM_LOCK: Final = 9
SOFT_LIMIT_ERROR: Final = 10
OVERFLOW: Final = 11
UNSUPPORTED_COMMAND: Final = 20
MODAL_GROUP_VIOLATION: Final = 21
UNDEFINED_FEED_RATE: Final = 22
COMMAND_VALUE_NOT_INTEGER: Final = 23
AXIS_COMMAND_CONFLICT: Final = 24
WORD_REPEATED: Final = 25
NO_AXIS_WORDS: Final = 26
INVALID_LINE_NUMBER: Final = 27
VALUE_WORD_MISSING: Final = 28
G53_INVALID_MOTION_MODE: Final = 30
AXIS_WORDS_EXIST: Final = 31
NO_AXIS_WORDS_IN_PLANE: Final = 32
INVALID_TARGET: Final = 33
ARC_RADIUS_ERROR: Final = 34
NO_OFFSETS_IN_PLANE: Final = 35
UNUSED_WORDS: Final = 36
INVALID_TOOL_LENGTH_AXIS: Final = 37

_STATUS_TEXT: Final = {
    EXPECTED_COMMAND_LETTER: "Expected command letter",
    BAD_NUMBER_FORMAT: "Bad number format",
    INVALID_STATEMENT: "Invalid statement",
    NEGATIVE_VALUE: "Value < 0",
    SETTING_DISABLED: "Setting disabled",
    SETTING_STEP_PULSE_MIN: "Value < 3 usec",
    7: "EEPROM read fail. Using defaults",
    IDLE_ERROR: "Not idle",
    ALARM_LOCK: "Alarm lock",
    SOFT_LIMIT_ERROR: "Homing not enabled",
    OVERFLOW: "Line overflow",
    UNSUPPORTED_COMMAND: "Unsupported command",
    MODAL_GROUP_VIOLATION: "Modal group violation",
    UNDEFINED_FEED_RATE: "Undefined feed rate",
}

_CODES_2021: Final = {
    UNDEFINED_FEED_RATE: (113, "Undefined feed rate"),  # 2021 manual 2.1.3
    ARC_RADIUS_ERROR: (116, "Arc radius error"),  # 2021 manual 2.1.9
}

# --- Mirobot texts (PROTOCOL 4.3, exact) ------------------------------------------------------
TEXT_LOCKED: Final = "Locked status of each axis!"
TEXT_SOFT_LIMIT: Final = "Soft limit triggered:"
TEXT_UNREACHABLE: Final = "GOAL OUT OF WORKSPACE, THERE IS NO VAILD VALUS FOR  THETA3!"
TEXT_OUT_OF_LIMIT: Final = "There is one angle out of limit!!!"
TEXTS_WITHOUT_LINE_END: Final = frozenset({TEXT_UNREACHABLE})
"""Refusal texts the firmware prints without a line end: the ``ok`` follows on the same line
(oracle: ``GOAL OUT OF WORKSPACE, ... THETA3!ok``); the 2024 form ends its line (``...\n``)."""
TEXT_M50: Final = "M50: Unlock each axis."
TEXT_M20: Final = "M20: Cartesian mode start."
TEXT_M21: Final = "M21: Angle mode start."
TEXT_HOMED: Final = {"classic": "in homeing moving...ok", "2021": "Info, in homing moving...ok"}
HOMED_LINES: Final = {
    "classic": (TEXT_HOMED["classic"],),
    "2021": (TEXT_HOMED["2021"],),
    "2024": ("Info,in homing moving...", "ok"),  # the message table: "...moving...\r\n"
}
FEEDBACK_RESET_TO_CONTINUE: Final = "[Reset to continue]"
FEEDBACK_ALARM_LOCK: Final = "['$H'|'$X' to unlock]"
FEEDBACK_UNLOCKED: Final = "[Caution: Unlocked]"

HELP: Final = (
    "$$ (view Grbl settings)",
    "$# (view # parameters)",
    "$G (view parser state)",
    "$I (view build info)",
    "$N (view startup blocks)",
    "$x=value (save Grbl setting)",
    "$Nx=line (save startup block)",
    "$C (check gcode mode)",
    "$X (kill alarm lock)",
    "$H (run homing cycle)",
    "~ (cycle start)",
    "! (feed hold)",
    "? (current status)",
    "ctrl-x (reset Grbl)",
)


def error_text(status: int) -> str:
    """The classic text of GRBL 0.9j status ``status`` (PROTOCOL 4.1)."""
    return _STATUS_TEXT.get(status, f"Invalid gcode ID:{status}")


def error_line(profile: str, status: int) -> str:
    """The final reply of a failed line, per profile (ASSUMED code rule for 2021)."""
    if profile == "classic":
        return f"error: {error_text(status)}"
    if profile == "2024":
        return _error_line_2024(status)
    code, text = _CODES_2021.get(status, (100 + status, error_text(status)))
    return f"Error, E{code},{text}"


_CODES_2024: Final = {
    MODAL_GROUP_VIOLATION: 111,
    UNSUPPORTED_COMMAND: 112,
    UNDEFINED_FEED_RATE: 113,
    ARC_RADIUS_ERROR: 116,
}
"""The 2024 message table (EVIDENCE-NEWER.md 2): GRBL status 1..11 print ``Info,E100..E110``
(in order), the g-code errors ``Error,E111..E117``, any other ``Error,E000,Invalid gcode ID:``
(ASSUMED: the number follows, as on classic)."""


def _error_line_2024(status: int) -> str:
    if 1 <= status <= 11:
        return f"Info,E{99 + status},{error_text(status)}"
    code = _CODES_2024.get(status)
    if code is None:
        return f"Error,E000,Invalid gcode ID:{status}"
    return f"Error,E{code},{'Arc radius error' if code == 116 else error_text(status)}"


_REFUSALS_2024: Final = {
    TEXT_LOCKED: "Error,A106,Locked status of each axis",
    TEXT_UNREACHABLE: "Error,E118,The given location is outside the workspace.",
    TEXT_OUT_OF_LIMIT: "Error,E119,The angle of an axis is out of range.",
}
"""The 2024 family's forms of the "ok but dropped" texts (EVIDENCE-NEWER.md 2; which replaces
which is INFERRED from the words); ``Soft limit triggered:X`` is ``Error,A102,Soft limit:X``."""


def refusal_lines(text: str, profile: str = "classic") -> list[str]:
    """The "ok but dropped" texts: an empty line, then the text (oracle); 2024: its forms."""
    if profile == "2024":
        if text.startswith(TEXT_SOFT_LIMIT):
            return ["", "Error,A102,Soft limit:" + text[len(TEXT_SOFT_LIMIT) :]]
        return ["", _REFUSALS_2024.get(text, text)]
    return ["", text]


_ALARMS_2024: Final = {
    "Hard limit": "Error,A101,Hard limit:",
    "Abort during cycle": "Error,A103,Abort during cycle",
    "Homing fail": "Error,A105,Homing fail",
}


def alarm_line(profile: str, text: str, axis: str = "") -> str:
    """``ALARM: <text>``; 2024: ``Error,A10x,<text>`` (the hard limit followed by ``axis``)."""
    if profile == "2024":
        return _ALARMS_2024[text] + (axis if text == "Hard limit" else "")
    return f"ALARM: {text}"
