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

from mirobot_async.errors import (
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
    from mirobot_async.client import (
        ClientStats,
        LineResult,
        Mirobot,
        PathError,
        Stream,
        StreamResult,
    )
    from mirobot_async.envelope import Envelope
    from mirobot_async.replies import State, StatusReport, parse_status
    from mirobot_async.testing import start_emulator
    from mirobot_async.validation import InvalidLineError

__all__ = [
    "ClientStats",
    "Envelope",
    "InvalidLineError",
    "LineResult",
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
    "MotionRefusedError",
    "PathError",
    "RefusalReason",
    "State",
    "StatusReport",
    "Stream",
    "StreamResult",
    "parse_status",
    "start_emulator",
]

__version__ = "0.1.0"

_LAZY: dict[str, str] = {
    "ClientStats": "mirobot_async.client",
    "LineResult": "mirobot_async.client",
    "Mirobot": "mirobot_async.client",
    "PathError": "mirobot_async.client",
    "Stream": "mirobot_async.client",
    "StreamResult": "mirobot_async.client",
    "State": "mirobot_async.replies",
    "StatusReport": "mirobot_async.replies",
    "parse_status": "mirobot_async.replies",
    "start_emulator": "mirobot_async.testing",
    "Envelope": "mirobot_async.envelope",
    "InvalidLineError": "mirobot_async.validation",
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
