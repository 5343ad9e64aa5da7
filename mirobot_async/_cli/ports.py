"""``mirobot ports`` and ``--auto``: the probe lives in :mod:`mirobot_async._client.ports` (the
library's, so that ``Mirobot.connect("auto")`` can use it); re-exported here for the CLI."""

from __future__ import annotations

from mirobot_async._client.ports import (
    DEFAULT_PROBE_TIMEOUT,
    PortVerdict,
    describe_ports,
    find_mirobot,
    probe_port,
)

__all__ = ["DEFAULT_PROBE_TIMEOUT", "PortVerdict", "describe_ports", "find_mirobot", "probe_port"]
