"""What the asyncio and the synchronous emulator handles share: the command line, the control
channel's replies, and the error class."""

from __future__ import annotations

import logging
import os
import shlex
import sys
from collections.abc import Sequence

from mirobot_async.errors import (
    EmulatorError,  # defined with the error tree
    MirobotUsageError,
)

__all__ = [
    "CONTROL_TIMEOUT",
    "DEFAULT_FIRMWARE",
    "DEFAULT_TIME_SCALE",
    "EXIT_ON_EOF",
    "LINK_ENV",
    "STARTUP_TIMEOUT",
    "STOP_TIMEOUT",
    "EmulatorError",
    "control_reply",
    "control_result",
    "control_text",
    "default_link",
    "emulator_args",
    "emulator_command",
    "link_args",
    "renew_text",
    "renewed_command",
    "renewed_url",
]

_log = logging.getLogger("mirobot_async.virtual")

DEFAULT_FIRMWARE = "2021"
DEFAULT_TIME_SCALE = 0.0
STARTUP_TIMEOUT = 30.0
"""Seconds to wait for the emulator's first line (its port path)."""
STOP_TIMEOUT = 5.0
"""Seconds to wait for the emulator to exit after SIGTERM before it is killed."""
CONTROL_TIMEOUT = 5.0
"""Seconds to wait for the ``ack`` of a control command."""


EXIT_ON_EOF = "--exit-on-stdin-eof"
"""The emulator's option that stops it when its stdin ends: the process that started it is gone."""

LINK_ENV = "MIROBOT_TEST_LINK"
"""Environment variable choosing the emulator's link when a caller names none: ``pty`` or
``tcp`` (so a whole test suite can be run once over each without changing a test)."""
LINKS = ("pty", "tcp")


def default_link() -> str:
    """``$MIROBOT_TEST_LINK`` if set, else ``"pty"`` where ptys exist (POSIX) and ``"tcp"``
    elsewhere (Windows)."""
    chosen = os.environ.get(LINK_ENV, "").strip().lower()
    if chosen:
        if chosen not in LINKS:
            raise MirobotUsageError(f"{LINK_ENV}={chosen!r} must be 'pty' or 'tcp'")
        return chosen
    return "pty" if os.name == "posix" else "tcp"


def link_args(listen: str | None) -> list[str]:
    """The emulator's command-line arguments for ``listen``: ``None`` (:func:`default_link`),
    ``"pty"``, ``"tcp"`` (a free loopback port) or ``"HOST:PORT"``."""
    link = default_link() if listen is None else listen
    if not isinstance(link, str) or not link:
        raise MirobotUsageError(f"listen={listen!r} must be 'pty', 'tcp' or 'HOST:PORT'")
    if link == "pty":
        return []
    if link == "tcp":
        return ["--listen", "127.0.0.1:0"]
    _host, sep, port = link.rpartition(":")
    if not sep or not port.isdigit():
        raise MirobotUsageError(f"listen={listen!r} must be 'pty', 'tcp' or 'HOST:PORT'")
    return ["--listen", link]


def emulator_args(
    firmware: str = DEFAULT_FIRMWARE,
    time_scale: float = DEFAULT_TIME_SCALE,
    extra_args: Sequence[str] = (),
) -> list[str]:
    """The emulator's options for these settings (checked: :class:`MirobotUsageError`)."""
    if firmware not in ("2021", "classic", "2024"):
        raise MirobotUsageError(f"firmware={firmware!r} must be '2021', 'classic' or '2024'")
    scale = float(time_scale)
    if not scale >= 0 or scale == float("inf"):
        raise MirobotUsageError(f"time_scale={time_scale!r} must be a finite number >= 0")
    if isinstance(extra_args, str):
        raise MirobotUsageError("extra_args must be a sequence of strings, not one string")
    return ["--firmware", firmware, "--time-scale", repr(scale), *extra_args]


def emulator_command(
    firmware: str = DEFAULT_FIRMWARE,
    time_scale: float = DEFAULT_TIME_SCALE,
    extra_args: Sequence[str] = (),
    listen: str | None = None,
) -> list[str]:
    """The argument vector that starts the emulator with this Python interpreter
    (``listen``: see :func:`link_args`), always with ``--exit-on-stdin-eof``: the emulator
    stops when the process that started it is gone (killed too), leaving nothing behind."""
    options = emulator_args(firmware, time_scale, extra_args)
    return [
        sys.executable,
        "-m",
        "mirobot_emulator",
        *options[:4],
        *link_args(listen),
        *options[4:],
        *([] if EXIT_ON_EOF in options[4:] else [EXIT_ON_EOF]),
    ]


def renew_text(
    firmware: str = DEFAULT_FIRMWARE,
    time_scale: float = DEFAULT_TIME_SCALE,
    extra_args: Sequence[str] = (),
) -> str:
    """The ``renew`` control command that makes a running emulator a new one with these
    settings (arguments shell-quoted: the emulator splits them as a shell would)."""
    return "renew " + shlex.join(emulator_args(firmware, time_scale, extra_args))


def renewed_command(
    command: Sequence[str],
    firmware: str = DEFAULT_FIRMWARE,
    time_scale: float = DEFAULT_TIME_SCALE,
    extra_args: Sequence[str] = (),
) -> list[str]:
    """The argument vector of a new process equivalent to ``command`` renewed with these
    settings: its link (``--listen``) kept, the rest replaced (``--exit-on-stdin-eof``, as
    always)."""
    words = list(command)
    listen = "pty"
    if "--listen" in words[3:-1]:
        listen = words[words.index("--listen", 3) + 1]
    return emulator_command(firmware, time_scale, extra_args, listen)


def renewed_url(reply: str) -> str:
    """The new port's address in the emulator's answer to ``renew`` (``ack renew ... url=X``)."""
    _, sep, url = reply.rpartition(" url=")
    if not sep or not url:
        raise EmulatorError(f"the emulator's answer to renew names no port: {reply!r}")
    return url


def control_reply(raw: bytes) -> str | None:
    """The emulator's answer to a control command if stdout line ``raw`` is one (``ack ...``
    or ``error ...``), else ``None`` (anything else it prints is logged at debug level)."""
    text = raw.decode("utf-8", "replace").strip()
    if text.startswith(("ack ", "error ")) or text in ("ack", "error"):
        return text
    if text:
        _log.debug("emulator: %s", text)
    return None


def control_text(command: str) -> str:
    """``command`` as sent on the control channel: one non-empty line."""
    text = command.strip()
    if not text or "\n" in text:
        raise MirobotUsageError(f"command={command!r} must be one non-empty line")
    return text


def control_result(text: str, reply: str | None) -> str:
    """The ``ack`` line answering ``text``; :class:`EmulatorError` for a refusal or no answer
    (``None``: the emulator's stdout ended)."""
    if reply is None:
        raise EmulatorError(f"the emulator exited before answering {text!r}")
    if reply.startswith("error"):
        raise EmulatorError(f"the emulator refused {text!r}: {reply}")
    return reply
