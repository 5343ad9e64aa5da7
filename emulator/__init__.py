"""The virtual Mirobot: a firmware-exact WLKATA Mirobot emulator (import name ``mirobot_emulator``).

- :class:`Firmware` (:mod:`mirobot_emulator.firmware`): the pure firmware model, bytes in and out
  with an explicit clock.
- :class:`EmulatorServer`, :class:`ServerOptions`, :class:`VirtualMirobot`
  (:mod:`mirobot_emulator.server`): the model on a pseudo-terminal, as a process
  (``mirobot-emulator``) or in a background thread.
- :mod:`mirobot_emulator._faults`: fault injection, deterministic by seed.

Attributes are imported lazily so that ``python -m mirobot_emulator`` starts fast (the firmware
imports numpy).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .firmware import Firmware
    from .server import EmulatorServer, ServerOptions, VirtualMirobot

__all__ = ["EmulatorServer", "Firmware", "ServerOptions", "VirtualMirobot"]

_LAZY = {
    "Firmware": ".firmware",
    "EmulatorServer": ".server",
    "ServerOptions": ".server",
    "VirtualMirobot": ".server",
}


def __getattr__(name: str) -> Any:
    module_name = _LAZY.get(name)
    if module_name is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module_name, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
