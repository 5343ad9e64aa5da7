"""An outgoing command line: the one check of its bytes, and the one object that carries it
(PURE: no I/O).

:func:`encode_line` is used by :meth:`MirobotConnection.send_line
<mirobot_async._core.protocol.MirobotConnection.send_line>` and by the client before anything is
written: a line is one ASCII line without the realtime bytes, short enough for the robot's
receive buffer. :class:`OutgoingLine` is what the client makes of it once (its bytes, its one
parse, its label) and hands unchanged from ``send()``/``stream()``/a command to the line's reply
slot: every fact about the line is read from that parse, never from its text again.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from mirobot_async._core.line import ParsedLine, parse_line
from mirobot_async.errors import MirobotUsageError

__all__ = ["OutgoingLine", "encode_line"]

# Bytes that a command line may not contain: line ends (a line is one line) and the realtime bytes,
# which the firmware takes out of the stream wherever they are, even inside a comment (PROTOCOL.md
# section 3): "@" (GRBL's safety door) holds the firmware's parser until "~".
_FORBIDDEN_TEXT_RE = re.compile(r"[\r\n?!~%@]")
_REALTIME_HINTS = {
    "?": "use status()",
    "!": "use hold()",
    "~": "use resume()",
    "%": "use reset()",
    "@": "the safety-door byte: the robot would stop reading lines until '~'",
}


def encode_line(line: object, rx_buffer_size: int = 128, *, strip: bool = True) -> bytes:
    """One command line as the bytes to send (without its line end); the only check of a line's
    bytes before it is written.

    Accepts ``str``, ``bytes`` or ``bytearray`` of ASCII text; one trailing line end (``"\\n"``,
    and with ``strip`` also ``"\\r\\n"`` and surrounding blanks) is removed. Raises
    :class:`MirobotUsageError` for another type, non-ASCII text, a line break inside, a realtime
    byte (``? ! ~ % @``, which the firmware would act on at once, even inside a comment), or a
    line that with its line end
    is longer than the robot's ``rx_buffer_size``-byte receive buffer.
    """
    if isinstance(line, bytes | bytearray):
        try:
            text = bytes(line).decode("ascii")
        except UnicodeDecodeError as err:
            raise MirobotUsageError(f"line={bytes(line)!r} is not ASCII") from err
    elif isinstance(line, str):
        text = line
    else:
        raise MirobotUsageError(f"line={line!r} must be str or bytes, not {type(line).__name__}")
    if not text.isascii():
        raise MirobotUsageError(f"line={text!r} is not ASCII")
    if strip:
        text = text.strip(" \t")
        if text.endswith("\r\n"):
            text = text[:-2]
        elif text.endswith("\n"):
            text = text[:-1]
        text = text.strip(" \t")
    elif text.endswith("\n"):
        text = text[:-1]
    bad = _FORBIDDEN_TEXT_RE.search(text)
    if bad is not None:
        char = bad.group()
        if char in "\r\n":
            raise MirobotUsageError(f"line={text!r} contains a line break: send one line")
        raise MirobotUsageError(
            f"line={text!r} contains the realtime byte {char!r}, which the firmware would "
            f"act on at once ({_REALTIME_HINTS[char]})"
        )
    data = text.encode("ascii")
    if len(data) + 1 > rx_buffer_size:
        raise MirobotUsageError(
            f"line={text!r} is {len(data) + 1} bytes with its line end, more than the "
            f"robot's {rx_buffer_size}-byte receive buffer"
        )
    return data


@dataclass(frozen=True, slots=True)
class OutgoingLine:
    """One command line on its way to the robot, made once (:meth:`of`) and never re-read."""

    data: bytes
    """The bytes written, without the line end (checked by :func:`encode_line`)."""
    command: str
    """``data`` as text: how errors and logs quote the line."""
    parsed: ParsedLine
    """The line's one parse: homing, dwell, ``$`` barrier, modes, validation, envelope."""
    what: str | None = None
    """The label of messages about it (``send('G0 X1')``, ``stream line 3 ...``)."""

    @classmethod
    def of(
        cls, data: bytes, what: str | None = None, *, parsed: ParsedLine | None = None
    ) -> OutgoingLine:
        """``data`` (one trailing ``\\n`` dropped) with its parse: ``parsed`` when the caller
        parsed exactly these bytes already (a stream judged before it began), else parsed
        here."""
        data = data.rstrip(b"\n")
        return cls(data, data.decode("ascii"), parse_line(data) if parsed is None else parsed, what)
