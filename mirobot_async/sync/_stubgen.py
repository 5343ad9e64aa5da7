"""Writes ``mirobot_async/sync/__init__.pyi``: the blocking facade's types, method by method.

The facade is generated from the asyncio class at import time (:mod:`mirobot_async.sync._facade`),
which a type checker cannot follow; this stub gives it the asyncio class's signatures with the
facade's return types (a coroutine's result, :class:`BlockingIterator` for an async generator,
:class:`BlockingContextManager` for an async context manager, the awaited result of an awaitable).
``python -m mirobot_async.sync._stubgen`` rewrites it; ``--check`` exits 1 when it is stale (a
unit test runs the check, so the stub cannot drift from the asyncio class).
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["render_stub"]

STUB_PATH = Path(__file__).with_name("__init__.pyi")
_IDENT = re.compile(r"\b[A-Za-z_][A-Za-z0-9_]*\b")
_BUILTINS = frozenset(
    {"None", "bool", "int", "float", "str", "bytes", "dict", "list", "tuple", "set", "object"}
)
_HEADER = '''"""Types of the blocking facade, method by method."""

# Generated from mirobot_async.Mirobot: do not edit by hand.
'''
_FIXED_IMPORTS = {
    "BlockingContextManager": "mirobot_async.sync._facade",
    "BlockingFacade": "mirobot_async.sync._facade",
    "BlockingIterator": "mirobot_async.sync._facade",
    "EventLoopThread": "mirobot_async.sync._loop",
    "Any": "typing",
    "Self": "typing",
}


def _defining_module(name: str, obj: object, fallback: str) -> str:
    """Where ``name`` is defined and exported (a class's module; an alias's ``__all__``)."""
    module = getattr(obj, "__module__", None)
    if isinstance(obj, type) and isinstance(module, str) and name == obj.__name__:
        return module
    for mod_name, mod in sorted(sys.modules.items()):
        exported = mod_name.startswith("mirobot_async") and name in getattr(mod, "__all__", ())
        if exported and getattr(mod, name, None) is obj:
            return mod_name
    return fallback


def _exporting_module(name: str, annotation: str, fallback: str) -> str:
    owners = sorted(
        mod_name
        for mod_name, mod in sys.modules.items()
        if mod_name.startswith("mirobot_async") and name in getattr(mod, "__all__", ())
    )
    for mod_name in owners:  # the defining module first (a class's own module)
        obj = getattr(sys.modules[mod_name], name)
        if getattr(obj, "__module__", None) == mod_name:
            return mod_name
    if owners:
        return owners[0]
    raise LookupError(f"{name!r} in {annotation!r} is not defined in {fallback}")


class _Imports:
    def __init__(self) -> None:
        self.by_module: dict[str, set[str]] = {}

    def note(self, annotation: str, namespace: dict[str, Any], fallback: str) -> None:
        for name in _IDENT.findall(annotation):
            if name in _BUILTINS:
                continue
            if name in _FIXED_IMPORTS:
                self.by_module.setdefault(_FIXED_IMPORTS[name], set()).add(name)
                continue
            if name in namespace:
                module = _defining_module(name, namespace[name], fallback)
            else:  # imported under TYPE_CHECKING: find the module that exports it
                module = _exporting_module(name, annotation, fallback)
            self.by_module.setdefault(module, set()).add(name)

    def render(self) -> str:
        lines = ["from __future__ import annotations", ""]
        lines.append("from mirobot_async._client.client import Mirobot as AsyncMirobot")
        groups = sorted(self.by_module.items(), key=lambda kv: (kv[0].startswith("mirobot"), kv[0]))
        for module, names in groups:
            lines.append(f"from {module} import {', '.join(sorted(names))}")
        return "\n".join(lines)


def _inner(annotation: str, *heads: str) -> str | None:
    """``X`` of ``Head[X]`` or ``Head[X, ...]`` for one of ``heads``; None otherwise."""
    for head in heads:
        if annotation.startswith(head + "[") and annotation.endswith("]"):
            body = annotation[len(head) + 1 : -1]
            depth = 0
            for index, char in enumerate(body):
                depth += char == "["
                depth -= char == "]"
                if char == "," and depth == 0:
                    return body[:index].strip()
            return body.strip()
    return None


def _awaited(return_type: str, namespace: dict[str, Any]) -> str | None:
    """The result type of awaiting an instance of ``return_type`` (a class with ``__await__``)."""
    cls = namespace.get(return_type)
    await_method = getattr(cls, "__await__", None)
    if not isinstance(cls, type) or await_method is None:
        return None
    annotation = inspect.signature(await_method).return_annotation
    if not isinstance(annotation, str) or not annotation.startswith("Generator["):
        return None
    parts = annotation[len("Generator[") : -1].rsplit(",", 1)
    return parts[-1].strip()


def _entered(return_type: str, namespace: dict[str, Any]) -> bool:
    """Whether ``return_type`` names an async context manager (the facade makes it a plain
    one: ``arm.view()``), looked up in ``namespace`` or, imported under TYPE_CHECKING, in the
    public root."""
    cls = namespace.get(return_type)
    if cls is None and return_type in getattr(sys.modules["mirobot_async"], "__all__", ()):
        cls = getattr(sys.modules["mirobot_async"], return_type)
    return isinstance(cls, type) and hasattr(cls, "__aenter__") and hasattr(cls, "__aexit__")


def _params(signature: inspect.Signature) -> str:
    out: list[str] = []
    kw_only_started = False
    for parameter in signature.parameters.values():
        if parameter.kind is parameter.KEYWORD_ONLY and not kw_only_started:
            out.append("*")
            kw_only_started = True
        text = parameter.name
        if parameter.kind is parameter.VAR_POSITIONAL:
            text, kw_only_started = "*" + text, True
        elif parameter.kind is parameter.VAR_KEYWORD:
            text = "**" + text
        if parameter.annotation is not parameter.empty:
            text += f": {parameter.annotation}"
        if parameter.default is not parameter.empty:
            text += " = ..."
        out.append(text)
    return ", ".join(out)


def _method(name: str, signature: inspect.Signature, returns: str, decorator: str = "") -> str:
    head = f"    {decorator}\n" if decorator else ""
    return f"{head}    def {name}({_params(signature)}) -> {returns}: ..."


def render_stub() -> str:
    """The stub's text for the facade of :class:`mirobot_async.Mirobot`."""
    from mirobot_async import Mirobot as wraps

    for module in (
        "_safety.envelope",
        "_client.streaming",
        "_client.wire",
        "_client.transport",
        "_client.condition",
        "_client.path_commands",
    ):
        importlib.import_module(f"mirobot_async.{module}")
    imports = _Imports()
    members: list[str] = []
    for name in dir(wraps):
        if name.startswith("_"):
            continue
        member = inspect.getattr_static(wraps, name)
        function: Callable[..., Any] = getattr(member, "__func__", member)
        namespace: dict[str, Any] = getattr(inspect.unwrap(function), "__globals__", {})
        fallback = getattr(function, "__module__", wraps.__module__)
        if isinstance(member, property):
            assert member.fget is not None
            returns = inspect.signature(member.fget).return_annotation
            imports.note(returns, member.fget.__globals__, member.fget.__module__)
            members.append(f"    @property\n    def {name}(self) -> {returns}: ...")
            if member.fset is not None:
                members.append(
                    f"    @{name}.setter\n    def {name}(self, value: {returns}) -> None: ..."
                )
            continue
        if isinstance(member, classmethod):  # connect(): the facade returns the connected arm
            signature = inspect.signature(function)
            for parameter in signature.parameters.values():
                if parameter.annotation is not parameter.empty:
                    imports.note(parameter.annotation, namespace, fallback)
            members.append(_method(name, signature, "Mirobot", "@classmethod"))
            continue
        if not callable(function):
            continue
        signature = inspect.signature(function)
        for parameter in signature.parameters.values():
            if parameter.annotation is not parameter.empty:
                imports.note(parameter.annotation, namespace, fallback)
        returns = signature.return_annotation
        assert isinstance(returns, str), f"{name}: annotations must be strings"
        raw = inspect.unwrap(function)
        if inspect.isasyncgenfunction(raw) and getattr(function, "__wrapped__", None):
            # an @asynccontextmanager: a plain context manager in the facade
            item = _inner(returns, "AsyncIterator", "AsyncGenerator") or "Any"
            returns = f"BlockingContextManager[{item}]"
        elif inspect.isasyncgenfunction(raw):
            item = _inner(returns, "AsyncIterator", "AsyncGenerator") or "Any"
            returns = f"BlockingIterator[{item}]"
        elif not inspect.iscoroutinefunction(raw) and _entered(returns, namespace):
            imports.note(returns, namespace, fallback)
            returns = f"BlockingContextManager[{returns}]"
        elif not inspect.iscoroutinefunction(raw):
            returns = _awaited(returns, namespace) or returns
            if returns != signature.return_annotation:
                namespace = {
                    **namespace,
                    **vars(sys.modules[namespace[signature.return_annotation].__module__]),
                }
        imports.note(returns, namespace, fallback)
        members.append(_method(name, signature, returns))
    instance = wraps()
    for name, value in sorted(vars(instance).items()):
        if name.startswith("_"):
            continue
        annotation = _instance_annotation(wraps, name, value)
        imports.note(
            annotation, {**_all_globals(wraps), type(value).__name__: type(value)}, wraps.__module__
        )
        members.append(f"    {name}: {annotation}")
    imports.note("Any", {}, "typing")
    imports.note("Self", {}, "typing")
    for fixed in ("BlockingContextManager", "BlockingFacade", "BlockingIterator"):
        imports.note(fixed, {}, "")
    imports.note("EventLoopThread", {}, "")
    body = "\n\n".join(members)
    return (
        f"{_HEADER}\n{imports.render()}\n\n"
        '__all__ = [\n    "BlockingContextManager",\n    "BlockingFacade",\n'
        '    "BlockingIterator",\n    "EventLoopThread",\n    "Mirobot",\n]\n\n\n'
        "class Mirobot(BlockingFacade, wraps=AsyncMirobot):\n"
        '    """The blocking mirobot_async.Mirobot (see the module docstring)."""\n\n'
        f"    def __init__(self, {_params(inspect.signature(wraps))}) -> None: ...\n\n"
        "    def __enter__(self) -> Self: ...\n\n"
        "    def __exit__(self, *exc_info: object) -> None: ...\n\n"
        f"{body}\n"
    )


def _all_globals(wraps: type[Any]) -> dict[str, Any]:
    merged: dict[str, Any] = {}
    for klass in reversed(wraps.__mro__):
        module = sys.modules.get(klass.__module__)
        if module is not None:
            merged.update(vars(module))
    return merged


def _instance_annotation(wraps: type[Any], name: str, value: object) -> str:
    """The type of an attribute the asyncio object sets on itself (from its assignment)."""
    for klass in wraps.__mro__:
        source_file = inspect.getsourcefile(klass) if klass is not object else None
        if source_file is None:
            continue
        match = re.search(rf"self\.{name}: ([^=\n]+) =", Path(source_file).read_text())
        if match:
            return match.group(1).strip()
    return type(value).__name__


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mirobot_async.sync._stubgen")
    parser.add_argument("--check", action="store_true", help="exit 1 if the stub is stale")
    args = parser.parse_args(argv)
    text = render_stub()
    if args.check:
        current = STUB_PATH.read_text() if STUB_PATH.exists() else ""
        if current != text:
            print(f"{STUB_PATH} is stale: run python -m mirobot_async.sync._stubgen")
            return 1
        return 0
    STUB_PATH.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
