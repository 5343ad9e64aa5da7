"""mirobot-async: an asyncio client for the WLKATA Mirobot 6-axis arm.

::

    import asyncio
    from mirobot_async import Mirobot

    async def main() -> None:
        async with Mirobot.connect("/dev/ttyUSB0") as arm:
            await arm.home()
            await arm.move_joints(j1=30, speed=1500)
            print(await arm.status())

    asyncio.run(main())

Public names are imported lazily (on first use), so that ``import mirobot_async.testing`` (the
pytest plugin) and the error classes stay cheap to import.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from mirobot_async._version import __version__ as __version__
from mirobot_async.errors import (
    EnvelopeRefusedError,
    MirobotAlarmError,
    MirobotCommandError,
    MirobotConnectionError,
    MirobotError,
    MirobotLinkLostError,
    MirobotOutcomeUnknownError,
    MirobotProtocolError,
    MirobotResetError,
    MirobotTimeoutError,
    MirobotUsageError,
    MotionChainError,
    MotionRefusedError,
    RefusalReason,
)

if TYPE_CHECKING:
    from mirobot_async._client.client import (
        ClientStats,
        Connector,
        LineResult,
        Mirobot,
        PathError,
        Stream,
        StreamResult,
    )
    from mirobot_async._client.condition import Firmware, HomingCycle
    from mirobot_async._client.path_commands import Point
    from mirobot_async._client.transport import Implementation
    from mirobot_async._client.wire import DataCallback, LostCallback, Transport, TransportOpener
    from mirobot_async._core.modal import LineCheck, MotionModes
    from mirobot_async._core.replies import Refusal, State, StatusReport, parse_status
    from mirobot_async._core.validation import InvalidLineError
    from mirobot_async._safety.envelope import Envelope
    from mirobot_async._view.watch import ArmView
    from mirobot_async.virtual import start_emulator

__all__ = [
    "ArmView",
    "ClientStats",
    "Connector",
    "DataCallback",
    "Envelope",
    "EnvelopeRefusedError",
    "Firmware",
    "HomingCycle",
    "Implementation",
    "InvalidLineError",
    "LineCheck",
    "LineResult",
    "LostCallback",
    "Mirobot",
    "MirobotAlarmError",
    "MirobotCommandError",
    "MirobotConnectionError",
    "MirobotError",
    "MirobotLinkLostError",
    "MirobotOutcomeUnknownError",
    "MirobotProtocolError",
    "MirobotResetError",
    "MirobotTimeoutError",
    "MirobotUsageError",
    "MotionChainError",
    "MotionModes",
    "MotionRefusedError",
    "PathError",
    "Point",
    "Refusal",
    "RefusalReason",
    "State",
    "StatusReport",
    "Stream",
    "StreamResult",
    "Transport",
    "TransportOpener",
    "parse_status",
    "start_emulator",
]

_LAZY: dict[str, str] = {
    "ClientStats": "mirobot_async._client.client",
    "Connector": "mirobot_async._client.client",
    "LineResult": "mirobot_async._client.client",
    "Mirobot": "mirobot_async._client.client",
    "PathError": "mirobot_async._client.client",
    "Stream": "mirobot_async._client.client",
    "StreamResult": "mirobot_async._client.client",
    "Firmware": "mirobot_async._client.condition",
    "HomingCycle": "mirobot_async._client.condition",
    "Point": "mirobot_async._client.path_commands",
    "Implementation": "mirobot_async._client.transport",
    "DataCallback": "mirobot_async._client.wire",
    "LostCallback": "mirobot_async._client.wire",
    "Transport": "mirobot_async._client.wire",
    "TransportOpener": "mirobot_async._client.wire",
    "Refusal": "mirobot_async._core.replies",
    "LineCheck": "mirobot_async._core.modal",
    "MotionModes": "mirobot_async._core.modal",
    "State": "mirobot_async._core.replies",
    "StatusReport": "mirobot_async._core.replies",
    "parse_status": "mirobot_async._core.replies",
    "start_emulator": "mirobot_async.virtual",
    "ArmView": "mirobot_async._view.watch",
    "Envelope": "mirobot_async._safety.envelope",
    "InvalidLineError": "mirobot_async._core.validation",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*__all__, "__version__"})
