"""Where ``mirobot view`` listens: ``--listen HOST:PORT`` read (pure; the view and its
``--replay`` form share it)."""

from __future__ import annotations

from mirobot_async._cli.exits import CliError

__all__ = ["DEFAULT_HOST", "parse_listen"]

DEFAULT_HOST = "127.0.0.1"


def parse_listen(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (``:PORT`` or ``HOST`` alone allowed; port 0 = a free one)."""
    host, _, port = text.rpartition(":") if ":" in text else (text, ":", "0")
    host = host.strip("[]") or DEFAULT_HOST
    try:
        number = int(port or "0")
    except ValueError:
        raise CliError(f"--listen {text!r}: the port must be a number") from None
    if not 0 <= number <= 65535:
        raise CliError(f"--listen {text!r}: the port must be 0..65535")
    return host, number
