"""What the driver scripts share (they run in the third-party SDK's own interpreter, which
has pyserial but not mirobot-async): a raw ``?`` on the SDK's own port, and the JSON report."""

from __future__ import annotations

import json
import sys
import time
from typing import Any

RAW_STATUS_TIMEOUT = 3.0
"""Seconds to wait for the answer to a raw ``?`` (the emulator answers within milliseconds)."""


def raw_status(port: Any) -> str:
    """Send a bare ``?`` on the SDK's pyserial port and return the status line that answers it
    (lines left over from the SDK, its ``ok``s, are skipped), so the test can compare the SDK's
    parse with the bytes on the wire."""
    port.reset_input_buffer()
    port.write(b"?")
    deadline = time.monotonic() + RAW_STATUS_TIMEOUT
    pending = b""
    while time.monotonic() < deadline:
        pending += port.read(port.in_waiting or 1)
        while b"\n" in pending:
            line, pending = pending.split(b"\n", 1)
            text = line.decode("utf-8", "replace").strip()
            if text.startswith("<") and text.endswith(">"):
                return text
    raise TimeoutError(f"no status line within {RAW_STATUS_TIMEOUT} s (left: {pending!r})")


def report(steps: list[dict[str, Any]]) -> None:
    """Print the steps as one JSON line on stdout (the test reads the last line)."""
    sys.stdout.write(json.dumps({"steps": steps}) + "\n")
    sys.stdout.flush()
