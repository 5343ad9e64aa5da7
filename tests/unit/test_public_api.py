"""The public surface, pinned: which modules are public, what each exports, and that every
public signature names only public types (as aioesphomeapi's test_public_api does)."""

from __future__ import annotations

import dataclasses
import enum
import importlib
import inspect
import pkgutil
import types
import typing
from collections.abc import Iterator

import pytest

import mirobot_async

PUBLIC_MODULES = {
    "mirobot_async": [
        "ClientStats",
        "Connector",
        "DataCallback",
        "Envelope",
        "EnvelopeRefusedError",
        "Firmware",
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
    ],
    "mirobot_async.__main__": None,
    "mirobot_async.errors": None,
    "mirobot_async.kinematics": None,
    "mirobot_async.bus": None,
    "mirobot_async.sync": None,
    "mirobot_async.testing": None,
    "mirobot_async.virtual": None,
}
"""The public modules; the root's names pinned here, the others' by their ``__all__`` below."""

PINNED_ALL = {
    "mirobot_async.sync": [
        "BlockingContextManager",
        "BlockingFacade",
        "BlockingIterator",
        "EventLoopThread",
        "Mirobot",
    ],
    "mirobot_async.testing": [
        "BorrowedEmulatorProcess",
        "EmulatorError",
        "EmulatorPool",
        "EmulatorProcess",
        "InProcessArm",
        "SyncEmulatorProcess",
        "WireSpy",
        "emulator_command",
        "run_emulator",
        "session_link",
        "start_emulator",
    ],
    "mirobot_async.virtual": [
        "EmulatorError",
        "EmulatorProcess",
        "InProcessArm",
        "SyncEmulatorProcess",
        "emulator_command",
        "run_emulator",
        "start_emulator",
    ],
}


def _all_modules() -> Iterator[str]:
    yield "mirobot_async"
    for info in pkgutil.walk_packages(mirobot_async.__path__, "mirobot_async."):
        yield info.name


def test_public_modules_are_the_pinned_few() -> None:
    public = {
        name
        for name in _all_modules()
        if not any(part.startswith("_") and part != "__main__" for part in name.split("."))
    }
    assert public == set(PUBLIC_MODULES)
    assert len(public) <= 15


def test_the_root_exports_exactly_the_pinned_names() -> None:
    assert sorted(mirobot_async.__all__) == PUBLIC_MODULES["mirobot_async"]
    for name in mirobot_async.__all__:
        assert getattr(mirobot_async, name) is not None, name


@pytest.mark.parametrize("module", sorted(PINNED_ALL))
def test_public_packages_export_the_pinned_names(module: str) -> None:
    assert sorted(importlib.import_module(module).__all__) == PINNED_ALL[module]


_FOREIGN = (
    "builtins",
    "typing",
    "collections",
    "asyncio",
    "enum",
    "pathlib",
    "numpy",
    "types",
    "contextlib",
    "os",
    "argparse",
    "logging",
    "_collections_abc",
    "abc",
)


def _exported() -> dict[int, str]:
    """id(object) -> public name, for every object a public module exports."""
    names: dict[int, str] = {}
    for module_name in PUBLIC_MODULES:
        module = importlib.import_module(module_name)
        for name in getattr(module, "__all__", []):
            names[id(getattr(module, name))] = f"{module_name}.{name}"
    return names


def _classes_in(annotation: object) -> Iterator[type]:
    if isinstance(annotation, type) and not isinstance(annotation, types.GenericAlias):
        yield annotation
    for arg in typing.get_args(annotation):
        yield from _classes_in(arg)
    origin = typing.get_origin(annotation)
    if isinstance(origin, type) and origin.__module__.split(".")[0] not in _FOREIGN:
        yield origin


def _hints(obj: object) -> dict[str, object]:
    try:
        return typing.get_type_hints(obj)
    except (NameError, TypeError):  # a TYPE_CHECKING import: resolve with the public names
        namespace: dict[str, object] = {"pytest": pytest}
        for module_name in PUBLIC_MODULES:
            module = importlib.import_module(module_name)
            namespace.update({n: getattr(module, n) for n in getattr(module, "__all__", [])})
        return typing.get_type_hints(obj, localns=namespace)


def _signatures() -> Iterator[tuple[str, dict[str, object]]]:
    seen: set[int] = set()
    for module_name in PUBLIC_MODULES:
        if module_name in TYPED_BY_STUB:
            continue
        module = importlib.import_module(module_name)
        for name in getattr(module, "__all__", []):
            obj = getattr(module, name)
            if id(obj) in seen or not (inspect.isclass(obj) or inspect.isfunction(obj)):
                continue
            seen.add(id(obj))
            if obj.__module__.split(".")[0] != "mirobot_async":
                continue
            if inspect.isfunction(obj):
                yield f"{module_name}.{name}", _hints(obj)
                continue
            if issubclass(obj, (BaseException, enum.Enum)):
                continue
            if dataclasses.is_dataclass(obj):
                yield f"{module_name}.{name} fields", _hints(obj)
            constructible = name in CONSTRUCTIBLE  # the others are handed out, not built
            for attr, member in vars(obj).items():
                if attr.startswith("_") and not (attr == "__init__" and constructible):
                    continue
                function = getattr(member, "__func__", member)
                if isinstance(member, property):
                    function = member.fget
                if inspect.isfunction(function):
                    yield f"{module_name}.{name}.{attr}", _hints(function)


CONSTRUCTIBLE = {"Mirobot", "Envelope", "ControllerBus", "BusTiming", "InProcessArm"}
TYPED_BY_STUB = {"mirobot_async.sync"}  # the blocking facade: generated, typed by its stub


def test_public_signatures_name_only_public_types() -> None:
    exported = _exported()
    problems = []
    for where, hints in _signatures():
        for param, annotation in hints.items():
            if annotation is typing.Any:
                problems.append(f"{where}({param}): Any")
            for cls in _classes_in(annotation):
                home = cls.__module__.split(".")[0]
                if home == "mirobot_async" and id(cls) not in exported:
                    problems.append(f"{where}({param}): {cls.__module__}.{cls.__qualname__}")
    assert not problems, "\n".join(sorted(set(problems)))
