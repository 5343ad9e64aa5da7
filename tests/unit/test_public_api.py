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

PINNED_MEMBERS = {
    "mirobot_async.ClientStats": [
        "alarms",
        "bytes_received",
        "bytes_sent",
        "envelope_refusals",
        "lines_acknowledged",
        "lines_refused",
        "lines_rejected",
        "lines_sent",
        "protocol_violations",
        "replies_discarded",
        "replies_lost",
        "resets",
        "status_corrupted",
        "status_reports",
        "status_requests",
        "status_requests_forgotten",
        "status_retries",
    ],
    "mirobot_async.Envelope": [
        "box_problem",
        "check_arc",
        "check_joint_path",
        "check_joints",
        "check_linear_path",
        "check_pose",
        "contains_joints",
        "contains_point",
        "dh",
        "has_box",
        "joint_limits",
        "joint_path_steps",
        "joint_problem",
        "joints",
        "path_box_problem",
        "path_step_mm",
        "rail",
        "rail_problem",
        "tool",
        "tool_point",
        "x",
        "y",
        "z",
    ],
    "mirobot_async.HomingCycle": [
        "bound",
        "command",
        "describe",
        "ends_by",
        "started",
    ],
    "mirobot_async.LineCheck": [
        "base_offset",
        "joints",
        "modes",
        "moves",
        "pose",
        "rail",
    ],
    "mirobot_async.LineResult": [
        "error",
        "line",
        "number",
        "ok",
        "output",
    ],
    "mirobot_async.Mirobot": [
        "alarm",
        "axes_locked",
        "banner",
        "blow",
        "bytes_in_flight",
        "clear_alarm",
        "close",
        "closed",
        "connect",
        "corrupted_status_count",
        "detect_firmware",
        "envelope",
        "firmware",
        "firmware_evidence",
        "firmware_version",
        "gripper_close",
        "gripper_open",
        "hold",
        "hold_on_exit",
        "home",
        "homing",
        "homing_bounds",
        "last_status",
        "liveness_interval",
        "move_joint_path",
        "move_joints",
        "move_path",
        "move_pose",
        "needs_reset",
        "pending_count",
        "preview_lines",
        "pump_off",
        "reply_grace",
        "reply_slot_count",
        "reset",
        "resume",
        "send",
        "set_hard_limits",
        "set_pump",
        "set_setting",
        "set_soft_limits",
        "set_valve",
        "settings",
        "status",
        "status_min_gap",
        "status_requests_outstanding",
        "status_retry_interval",
        "status_timeout",
        "status_waiter_count",
        "statuses",
        "stream",
        "suction_on",
        "unlock",
        "view",
        "wait_idle",
    ],
    "mirobot_async.ArmView": [
        "clients",
        "url",
    ],
    "mirobot_async.MotionModes": [
        "cartesian",
        "feed",
        "inches",
        "inverse_time",
        "missing",
        "motion",
        "relative",
        "unknown",
    ],
    "mirobot_async.Refusal": [
        "axis",
        "reason",
        "text",
    ],
    "mirobot_async.StatusReport": [
        "joints",
        "motion_mode",
        "pose",
        "pump_pwm",
        "rail",
        "state",
        "to_line",
        "valve_pwm",
    ],
    "mirobot_async.Stream": [
        "run",
    ],
    "mirobot_async.StreamResult": [
        "acknowledged",
        "errors",
        "ok",
        "raise_for_errors",
        "sent",
        "stopped",
    ],
    "mirobot_async.Transport": [
        "abort",
        "close",
        "write",
    ],
    "mirobot_async.bus.ArmState": [
        "number",
        "text",
        "word",
    ],
    "mirobot_async.bus.ArmTransport": [
        "abort",
        "close",
        "link_kind",
        "write",
    ],
    "mirobot_async.bus.BusStats": [
        "bytes_received",
        "bytes_sent",
        "probes",
        "requests",
        "settled",
        "silent_nodes",
        "stray_lines",
        "window_waits",
    ],
    "mirobot_async.bus.BusTiming": [
        "answer_timeout",
        "homing_bounds",
        "planner_window",
        "probe_interval",
        "reply_grace",
        "settle",
        "window_poll",
    ],
    "mirobot_async.bus.Controller": [
        "arm_state",
        "bus_address",
        "bus_baud",
        "delete_file",
        "enable_pins",
        "home",
        "list_files",
        "pin_modes",
        "read_file",
        "read_pins",
        "request",
        "restart",
        "run_file",
        "run_file_number",
        "set_bus_address",
        "set_bus_baud",
        "set_pin_modes",
        "set_thresholds",
        "set_trigger_files",
        "software_version",
        "stop_file",
        "version",
        "wait_idle",
        "write_file",
        "write_pins",
    ],
    "mirobot_async.bus.ControllerBus": [
        "arm",
        "close",
        "connect_arm",
        "controller",
        "open",
        "stats",
        "timing",
    ],
    "mirobot_async.bus.ControllerVersion": [
        "arm",
        "controller",
    ],
}
"""The public members of the public classes (inherited ones included: ``Mirobot``'s come from
its command mixins), pinned; a new one is added here on purpose."""


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


def _members(cls: type) -> dict[str, object]:
    """The public members of ``cls`` and of its mirobot_async bases (the nearest wins)."""
    members: dict[str, object] = {}
    for klass in reversed(cls.__mro__):
        if klass.__module__.split(".")[0] == "mirobot_async":
            members.update(vars(klass))
    return members


def _pinnable() -> Iterator[tuple[str, type]]:
    for module_name in ("mirobot_async", "mirobot_async.bus"):
        module = importlib.import_module(module_name)
        for name in sorted(module.__all__):
            obj = getattr(module, name)
            if (
                inspect.isclass(obj)
                and obj.__module__.split(".")[0] == "mirobot_async"
                and not issubclass(obj, (BaseException, enum.Enum))
            ):
                yield f"{module_name}.{name}", obj


def test_public_classes_have_exactly_the_pinned_members() -> None:
    found = {
        where: members
        for where, cls in _pinnable()
        if (members := sorted(n for n in _members(cls) if not n.startswith("_")))
    }
    assert found == PINNED_MEMBERS


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
            for attr, member in _members(obj).items():
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
