"""Finding the arm: the serial ports pyserial finds (or the devices named), with VID:PID, the
description, and a verdict from a short, harmless probe (``mirobot ports``); and
:func:`find_mirobot`, the one Mirobot among them (``Mirobot.connect("auto")``, ``mirobot --auto``).

The probe opens the port (exclusively, so a port in use is reported busy rather than disturbed),
asks ``?`` (status; realtime, answered even mid-move, changes nothing) about every half second,
and waits for a status line. Only a port that answered with a Mirobot status is then asked
``$$`` (the settings listing: read-only) to tell the firmware, unless a banner already said it.
Nothing that moves the arm or writes a setting is ever sent, and each probe gives up after its
timeout. A Mirobot whose controller resets when the port opens (DTR) prints its banner first;
the repeated ``?`` is answered once it has booted.

:func:`find_mirobot` probes the ports whose USB VID:PID is one of the USB-serial chips Mirobot
controllers carry (:data:`MIROBOT_USB_IDS`) first, and the other ports only if none of those is a
Mirobot. It returns the one port that answered as a Mirobot (logged at INFO on
``mirobot_async.ports``) and refuses, listing them, when several did: which arm to move is
the user's choice, never a guess. ``$MIROBOT_AUTO_PORTS`` (ports separated by commas or spaces,
pyserial URLs such as ``socket://host:port`` allowed) replaces the listed ports as the candidates.
Blocking (threads, pyserial); the whole search takes about one probe timeout per stage.
"""

from __future__ import annotations

import concurrent.futures
import logging
import os
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

from mirobot_async._core.replies import StatusReport, parse_status
from mirobot_async.errors import MirobotConnectionError, MirobotProtocolError

if TYPE_CHECKING:
    import serial
    from serial.tools.list_ports_common import ListPortInfo

__all__ = [
    "AUTO",
    "AUTO_PORTS_ENV",
    "DEFAULT_PROBE_TIMEOUT",
    "MIROBOT_USB_IDS",
    "PortVerdict",
    "candidate_ports",
    "describe_ports",
    "find_mirobot",
    "probe_port",
]

_log = logging.getLogger("mirobot_async.ports")

AUTO: Final = "auto"
"""The port name that means "find the Mirobot" (``Mirobot.connect("auto")``, ``--port auto``)."""
AUTO_PORTS_ENV: Final = "MIROBOT_AUTO_PORTS"
"""Environment variable: the candidate ports of :func:`find_mirobot` (separated by commas or
spaces) instead of every serial port listed."""
MIROBOT_USB_IDS: Final = frozenset(
    {
        "1a86:7523",  # WCH CH340 (Mirobot main board, classic and 2021)
        "1a86:5523",  # WCH CH341
        "1a86:55d4",  # WCH CH9102 (later boards)
        "10c4:ea60",  # Silicon Labs CP210x (multi-function extender box)
    }
)
"""USB VID:PID of the USB-serial chips of Mirobot controllers: probed first by find_mirobot."""

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
        link = serial.serial_for_url(
            device,
            115200,
            timeout=0.05,
            write_timeout=1.0,
            exclusive=True if "://" not in device else None,
        )
    except (serial.SerialException, OSError, ValueError) as err:
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


def _listed() -> dict[str, ListPortInfo]:
    from serial.tools import list_ports

    return {port.device: port for port in list_ports.comports()}


def _vid_pid(info: ListPortInfo | None) -> str:
    if info is None or info.vid is None or info.pid is None:
        return "-"
    return f"{info.vid:04x}:{info.pid:04x}"


def _verdict(device: str, info: ListPortInfo | None, found: tuple[str, bool]) -> PortVerdict:
    """``found`` (a probe's verdict) for ``device``, with its VID:PID and description."""
    description = "-"
    if info is not None and info.description and info.description != "n/a":
        description = info.description
    return PortVerdict(device, _vid_pid(info), description, *found)


def _probe_all(
    devices: Sequence[str], listed: dict[str, ListPortInfo], probe: bool, timeout: float
) -> list[PortVerdict]:
    """Each of ``devices`` described (and probed, in parallel, unless ``probe`` is False)."""

    def one(device: str) -> PortVerdict:
        found = probe_port(device, timeout) if probe else ("not probed", False)
        return _verdict(device, listed.get(device), found)

    if not devices:
        return []
    with concurrent.futures.ThreadPoolExecutor(max_workers=min(8, len(devices))) as pool:
        return list(pool.map(one, devices))


def describe_ports(
    devices: list[str], *, probe: bool = True, timeout: float = DEFAULT_PROBE_TIMEOUT
) -> list[PortVerdict]:
    """The ports named in ``devices``, or every port pyserial lists when it is empty, each
    probed (in parallel) unless ``probe`` is False."""
    listed = _listed()
    return _probe_all(devices or sorted(listed), listed, probe, timeout)


def candidate_ports() -> list[str]:
    """The ports :func:`find_mirobot` considers: ``$MIROBOT_AUTO_PORTS``, else every serial port
    pyserial lists."""
    chosen = os.environ.get(AUTO_PORTS_ENV, "").replace(",", " ").split()
    if chosen:
        return chosen
    return sorted(_listed())


def _table(verdicts: Sequence[PortVerdict]) -> str:
    return "; ".join(
        f"{v.device} ({v.vid_pid}{', ' + v.description if v.description != '-' else ''}): "
        f"{v.verdict}"
        for v in verdicts
    )


def find_mirobot(
    candidates: Sequence[str] | None = None, *, timeout: float = DEFAULT_PROBE_TIMEOUT
) -> str:
    """The one port among ``candidates`` (default :func:`candidate_ports`) that answers as a
    Mirobot; blocking, about ``timeout`` seconds per stage (USB-matched ports, then the rest).

    Sends only ``?`` and ``$$`` (see :func:`probe_port`). Raises
    :class:`~mirobot_async.errors.MirobotConnectionError` listing every port and its verdict when
    none or several answer (several: name one with ``--port``).
    """
    names = list(candidate_ports() if candidates is None else candidates)
    if not names:
        raise MirobotConnectionError(
            "auto: no serial ports found (is the arm plugged in and switched on?)"
        )
    listed = _listed()
    matched = [name for name in names if _vid_pid(listed.get(name)) in MIROBOT_USB_IDS]
    others = [name for name in names if name not in matched]
    probed: list[PortVerdict] = []
    for stage in (matched, others):
        probed += _probe_all(stage, listed, True, timeout)
        found = [verdict for verdict in probed if verdict.is_mirobot]
        if len(found) == 1:
            _log.info("auto: using %s: %s", found[0].device, found[0].verdict)
            return found[0].device
        if len(found) > 1:
            raise MirobotConnectionError(
                f"auto: {len(found)} Mirobots answer; name one with --port / connect(PORT): "
                + _table(found)
            )
    raise MirobotConnectionError("auto: no Mirobot answered: " + _table(probed))
