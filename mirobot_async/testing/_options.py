"""What the plugin's command-line options and marker mean: the settings of a test's virtual arm
and the link of the session (the plugin's hooks and fixtures, in ``__init__``, ask here)."""

from __future__ import annotations

import dataclasses
import inspect
import os
from collections.abc import Callable
from typing import TYPE_CHECKING

from mirobot_async.errors import MirobotUsageError
from mirobot_async.virtual._control import (
    DEFAULT_FIRMWARE,
    DEFAULT_TIME_SCALE,
    LINK_ENV,
    default_link,
)

if TYPE_CHECKING:
    import pytest

__all__ = [
    "MARKER",
    "ArmSettings",
    "add_marker",
    "add_options",
    "links",
    "session_link",
    "settings",
]

MARKER = "mirobot_emulator"
FIXTURES = frozenset({"mirobot_emulator", "mirobot_emulator_process", "mirobot_virtual_arm"})
_MARKER_HELP = (
    "mirobot_emulator(firmware='2021', time_scale=0.0, extra_args=(), listen=None, fresh=False): "
    "settings of the virtual Mirobot behind the plugin's fixtures (fresh: a new process, not one "
    "renewed from the pool)"
)


def add_options(parser: pytest.Parser) -> None:
    """``--mirobot-firmware``, ``--mirobot-time-scale``, ``--mirobot-link``,
    ``--mirobot-pool-size``."""
    group = parser.getgroup("mirobot", "virtual Mirobot (mirobot-async)")
    group.addoption(
        "--mirobot-firmware",
        choices=("2021", "classic", "2024"),
        default=DEFAULT_FIRMWARE,
        help="firmware profile of the mirobot_emulator fixture (default: 2021)",
    )
    group.addoption(
        "--mirobot-time-scale",
        type=float,
        default=DEFAULT_TIME_SCALE,
        help="time scale of the mirobot_emulator fixture; 0 = instant motion (default: 0)",
    )
    group.addoption(
        "--mirobot-link",
        choices=("pty", "tcp", "both"),
        default=None,
        help="link of the mirobot_emulator fixture: pty, tcp or both (each test runs once per "
        "link); default $MIROBOT_TEST_LINK, else pty where ptys exist",
    )
    group.addoption(
        "--mirobot-pool-size",
        type=int,
        default=None,
        metavar="N",
        help="idle emulator processes kept per link between tests and renewed for the next "
        "(default 2; 0: a new process for every test)",
    )


def add_marker(config: pytest.Config) -> None:
    """Register the marker (so that ``--strict-markers`` knows it)."""
    config.addinivalue_line("markers", _MARKER_HELP)


def wants_asyncio(test: Callable[..., object], config: pytest.Config) -> bool:
    """Whether the ``async def`` ``test`` uses the plugin's fixtures or marker, has no async
    marker of its own (``asyncio``, ``anyio``, ``trio``), and pytest-asyncio is there to run it:
    README's example then runs as written in a project without ``asyncio_mode = "auto"``."""
    marks = {mark.name for mark in getattr(test, "pytestmark", [])}
    if not (MARKER in marks or FIXTURES & set(inspect.signature(test).parameters)):
        return False
    return not marks & {"asyncio", "anyio", "trio"} and config.pluginmanager.hasplugin("asyncio")


def session_link(config: pytest.Config) -> str | None:
    """The link chosen for the whole session (``--mirobot-link``, else ``$MIROBOT_TEST_LINK``):
    ``pty``, ``tcp``, or ``None`` for ``both`` or no choice."""
    chosen: str | None = config.getoption("--mirobot-link", None)
    if chosen is None:
        chosen = default_link() if os.environ.get(LINK_ENV, "").strip() else None
    return None if chosen == "both" else chosen


def links(metafunc: pytest.Metafunc) -> list[str] | None:
    """The links a test runs on (once per link), or ``None`` if it parametrises its link itself
    or uses none of the fixtures."""
    if "mirobot_link" not in metafunc.fixturenames:
        return None
    for mark in metafunc.definition.iter_markers("parametrize"):
        names = mark.args[0] if mark.args else ()
        if isinstance(names, str):
            names = [name.strip() for name in names.split(",")]
        if "mirobot_link" in names:
            return None
    chosen = metafunc.config.getoption("--mirobot-link") or default_link()
    return ["pty", "tcp"] if chosen == "both" else [chosen]


@dataclasses.dataclass(frozen=True, slots=True)
class ArmSettings:
    """A test's virtual arm: the marker's settings over the command line's."""

    firmware: str
    time_scale: float
    extra_args: tuple[str, ...] = ()
    listen: str | None = None
    fresh: bool = False


_KEYS = frozenset(field.name for field in dataclasses.fields(ArmSettings))


def settings(request: pytest.FixtureRequest) -> ArmSettings:
    """The settings of this test's arm (raises :class:`MirobotUsageError` for a bad marker)."""
    chosen = ArmSettings(
        request.config.getoption("--mirobot-firmware"),
        request.config.getoption("--mirobot-time-scale"),
    )
    marker = request.node.get_closest_marker(MARKER)
    if marker is None:
        return chosen
    if marker.args:
        raise MirobotUsageError(
            "@pytest.mark.mirobot_emulator takes keyword arguments only "
            "(firmware=, time_scale=, extra_args=, listen=, fresh=)"
        )
    unknown = set(marker.kwargs) - _KEYS
    if unknown:
        raise MirobotUsageError(
            f"@pytest.mark.mirobot_emulator: unknown argument(s) {', '.join(sorted(unknown))}"
        )
    kwargs = dict(marker.kwargs)
    kwargs["extra_args"] = tuple(kwargs.get("extra_args", ()))
    kwargs["fresh"] = bool(kwargs.get("fresh", False))
    return dataclasses.replace(chosen, **kwargs)
