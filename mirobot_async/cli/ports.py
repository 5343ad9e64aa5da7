"""``mirobot ports``: the serial ports pyserial finds (or the devices named), with VID:PID, the
description, and a verdict from a short, harmless probe.

The probe opens the port (exclusively, so a port in use is reported busy rather than disturbed),
asks ``?`` (status; realtime, answered even mid-move, changes nothing) about every half second,
and waits for a status line. Only a port that answered with a Mirobot status is then asked
``$$`` (the settings listing: read-only) to tell the firmware, unless a banner already said it.
Nothing that moves the arm or writes a setting is ever sent, and each probe gives up after its
timeout. A Mirobot whose controller resets when the port opens (DTR) prints its banner first;
the repeated ``?`` is answered once it has booted.
"""

from __future__ import annotations

import concurrent.futures
import re
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

from mirobot_async.errors import MirobotProtocolError
from mirobot_async.replies import StatusReport, parse_status

if TYPE_CHECKING:
    import serial

__all__ = ["DEFAULT_PROBE_TIMEOUT", "PortVerdict", "describe_ports", "probe_port"]

DEFAULT_PROBE_TIMEOUT: Final = 3.0
"""Seconds a probe waits for a status (a Mirobot resetting on open needs about 2 s to boot)."""
_ASK_EVERY: Final = 0.5
_STATUS_RE: Final = re.compile(rb"<[^<>\r\n]{10,400}>")
_VERSION_RE: Final = re.compile(rb"Robot\s+(\d{8})(\S*)")
_SETTING_29_RE: Final = re.compile(rb"^\$29\s*=", re.MULTILINE)


@dataclass(frozen=True, slots=True)
class PortVerdict:
    """What a probe found on one port."""

    device: str
    vid_pid: str
    """``"1a86:7523"``, or ``"-"`` when the port is not a USB device (or not listed)."""
    description: str
    verdict: str
    is_mirobot: bool


def _firmware_of(version: bytes) -> str:
    date = version.decode("ascii", "replace")[:8]
    return "classic" if date < "20210000" else "2021"


def _read_for(link: serial.Serial, seconds: float) -> bytes:
    """What ``link`` prints within ``seconds`` (stops early at ``ok`` or an error)."""
    data = b""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        data += link.read(512)
        if b"ok" in data or b"rror" in data:
            break
    return data


def probe_port(device: str, timeout: float = DEFAULT_PROBE_TIMEOUT) -> tuple[str, bool]:
    """``(verdict, is_mirobot)`` for ``device``; never raises for the port's behaviour and
    returns within about ``timeout`` seconds (plus up to the same for ``$$`` on a Mirobot)."""
    import serial

    try:
        link = serial.Serial(device, 115200, timeout=0.05, write_timeout=1.0, exclusive=True)
    except (serial.SerialException, OSError) as err:
        text = str(err)
        if "lock" in text.lower():
            return "busy: another program is using it", False
        return f"cannot open: {text.split(': ', 1)[-1][:60]}", False
    with link:
        data = b""
        status: StatusReport | None = None
        deadline = time.monotonic() + timeout
        asked = -1.0
        try:
            while status is None and time.monotonic() < deadline:
                if time.monotonic() - asked >= _ASK_EVERY:
                    link.write(b"?")
                    asked = time.monotonic()
                data += link.read(512)
                for match in _STATUS_RE.finditer(data):
                    try:
                        status = parse_status(match.group(0))
                    except MirobotProtocolError:
                        continue
                    break
            if status is None:
                heard = "answers something else" if data.strip() else "silent"
                return f"not a Mirobot ({heard}: no status reply to ?)", False
            version = _VERSION_RE.search(data)
            if version is not None:
                name = (version.group(1) + version.group(2)).decode("ascii", "replace")
                firmware = f"firmware {_firmware_of(version.group(1))} ({name})"
            else:
                link.write(b"$$\n")
                settings = _read_for(link, max(1.0, timeout / 2))
                if b"ok" not in settings:
                    firmware = "firmware unknown (no reply to $$)"
                elif _SETTING_29_RE.search(settings.replace(b"\r", b"")):
                    firmware = "firmware 2021"
                else:
                    firmware = "firmware classic"
        except (serial.SerialException, OSError) as err:
            return f"link failed while probing: {err}", False
    return f"Mirobot ({status.state.value}), {firmware}", True


def describe_ports(
    devices: list[str], *, probe: bool = True, timeout: float = DEFAULT_PROBE_TIMEOUT
) -> list[PortVerdict]:
    """The ports named in ``devices``, or every port pyserial lists when it is empty, each
    probed (in parallel) unless ``probe`` is False."""
    from serial.tools import list_ports

    listed = {port.device: port for port in list_ports.comports()}
    names = devices or sorted(listed)

    def one(device: str) -> PortVerdict:
        info = listed.get(device)
        vid_pid = "-"
        description = "-"
        if info is not None:
            if info.vid is not None and info.pid is not None:
                vid_pid = f"{info.vid:04x}:{info.pid:04x}"
            if info.description and info.description != "n/a":
                description = info.description
        verdict, is_mirobot = probe_port(device, timeout) if probe else ("not probed", False)
        return PortVerdict(device, vid_pid, description, verdict, is_mirobot)

    if not names:
        return []
    with concurrent.futures.ThreadPoolExecutor(max_workers=min(8, len(names))) as pool:
        return list(pool.map(one, names))
