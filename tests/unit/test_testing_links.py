"""The emulator's link in mirobot_async.testing: ``listen=`` and ``$MIROBOT_TEST_LINK``."""

from __future__ import annotations

import pytest

from mirobot_async.errors import MirobotUsageError
from mirobot_async.testing import emulator_command
from mirobot_async.virtual._control import LINK_ENV, default_link, link_args


def test_listen_values(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(LINK_ENV, raising=False)
    assert link_args("pty") == []
    assert link_args("tcp") == ["--listen", "127.0.0.1:0"]
    assert link_args("0.0.0.0:7000") == ["--listen", "0.0.0.0:7000"]
    assert link_args("[::1]:0") == ["--listen", "[::1]:0"]
    for bad in ("", "udp", "host:", "host:port"):
        with pytest.raises(MirobotUsageError, match="listen="):
            link_args(bad)


def test_the_environment_chooses_the_default(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(LINK_ENV, "TCP")
    assert default_link() == "tcp"
    assert emulator_command("2021", 0)[-3:-1] == ["--listen", "127.0.0.1:0"]
    assert "--listen" not in emulator_command("2021", 0, listen="pty")  # explicit wins
    monkeypatch.setenv(LINK_ENV, "serial")
    with pytest.raises(MirobotUsageError, match=LINK_ENV):
        default_link()
    monkeypatch.delenv(LINK_ENV)
    assert default_link() in ("pty", "tcp")
