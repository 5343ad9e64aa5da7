"""The blocking facade's generated types match the asyncio class, and a user's type checker
sees real types through them."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from mirobot_async.sync import _stubgen as stubgen


def test_the_stub_is_generated_from_the_current_asyncio_class() -> None:
    assert stubgen.STUB_PATH.read_text() == stubgen.render_stub(), (
        "mirobot_async/sync/__init__.pyi is stale: run python -m mirobot_async.sync._stubgen"
    )


def test_every_public_member_of_the_asyncio_class_is_typed_in_the_stub() -> None:
    from mirobot_async import Mirobot

    text = stubgen.STUB_PATH.read_text()
    for name in dir(Mirobot):
        if not name.startswith("_"):
            assert f"def {name}(" in text, name
    assert "-> Any" not in text


CACHE = Path(__file__).resolve().parents[2] / ".mypy_cache"
"""mypy's incremental cache: the project's own (``mypy`` at the repository's root, which CI runs
first), so the package's modules are read from it, not checked again (0.5 s, not 10 s of CPU);
only the user's script, new each time, is checked."""

USER_CODE = """
from mirobot_async.sync import Mirobot

with Mirobot.connect("/dev/ttyUSB0") as arm:
    reveal_type(arm.status())
    reveal_type(arm.statuses(0.2))
    reveal_type(arm.stream(["G0 X1"]))
    arm.move_joints(j7=3)
"""


@pytest.mark.skipif(
    shutil.which("mypy") is None and not Path(sys.prefix, "bin", "mypy").exists(),
    reason="mypy is not installed (the dev extra)",
)
def test_a_users_type_checker_reveals_real_types(tmp_path: Path) -> None:
    script = tmp_path / "user.py"
    script.write_text(USER_CODE)
    done = subprocess.run(
        [sys.executable, "-m", "mypy", "--strict", "--cache-dir", str(CACHE), str(script)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        cwd=Path(__file__).resolve().parents[2],  # where an editable install keeps the sources
    )
    out = done.stdout
    assert 'Revealed type is "mirobot_async._core.replies.StatusReport"' in out, out
    assert "BlockingIterator[mirobot_async._core.replies.StatusReport]" in out, out
    assert 'Revealed type is "mirobot_async._client.streaming.StreamResult"' in out, out
    assert 'Unexpected keyword argument "j7"' in out, out
