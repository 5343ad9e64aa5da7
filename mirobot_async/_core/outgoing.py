"""The one check of an outgoing command line's bytes (PURE: no I/O).

:func:`encode_line` is used by :meth:`MirobotConnection.send_line
<mirobot_async._core.protocol.MirobotConnection.send_line>` and by the client before anything is
written: a line is one ASCII line without the realtime bytes, short enough for the robot's
receive buffer.
"""

from __future__ import annotations

import re

from mirobot_async.errors import MirobotUsageError

__all__ = ["encode_line"]

# Bytes that a command line may not contain: line ends (a line is one line) and the realtime bytes,
# which the firmware takes out of the stream wherever they are (PROTOCOL.md section 3).
_FORBIDDEN_TEXT_RE = re.compile(r"[\r\n?!~%]")
_REALTIME_HINTS = {"?": "use status()", "!": "use hold()", "~": "use resume()", "%": "use reset()"}


def encode_line(line: object, rx_buffer_size: int = 128, *, strip: bool = True) -> bytes:
    """One command line as the bytes to send (without its line end); the only check of a line's
    bytes before it is written.

    Accepts ``str``, ``bytes`` or ``bytearray`` of ASCII text; one trailing line end (``"\\n"``,
    and with ``strip`` also ``"\\r\\n"`` and surrounding blanks) is removed. Raises
    :class:`MirobotUsageError` for another type, non-ASCII text, a line break inside, a realtime
    byte (``? ! ~ %``, which the firmware would act on at once), or a line that with its line end
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
