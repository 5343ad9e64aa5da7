"""The pendant's export: a plain file name in the folder fixed at start, never an existing
file unless the page's Overwrite box is ticked, never through a symbolic link."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("viser")

from mirobot_async._view.teach import export_name, write_export
from mirobot_async.errors import MirobotUsageError


@pytest.mark.parametrize(
    "name", ["", "  ", ".", "..", "../x.gcode", "/etc/x", "a/b.gcode", "a\\b", "~x", "x\0"]
)
def test_export_name_refuses_anything_but_a_file_name(name: str) -> None:
    with pytest.raises(MirobotUsageError, match="file name only"):
        export_name(name)


def test_export_name_keeps_a_file_name() -> None:
    assert export_name(" taught.gcode ") == "taught.gcode"


def test_write_export_keeps_an_existing_file_unless_asked(tmp_path: Path) -> None:
    path = tmp_path / "taught.gcode"
    write_export(path, "new\n", overwrite=False)
    assert path.read_text() == "new\n"
    with pytest.raises(FileExistsError):
        write_export(path, "other\n", overwrite=False)
    assert path.read_text() == "new\n"
    write_export(path, "other\n", overwrite=True)
    assert path.read_text() == "other\n"


def test_write_export_never_follows_a_link(tmp_path: Path) -> None:
    target = tmp_path / "elsewhere.txt"
    target.write_text("keep\n")
    link = tmp_path / "taught.gcode"
    link.symlink_to(target)
    for overwrite in (False, True):
        with pytest.raises(FileExistsError):
            write_export(link, "x\n", overwrite=overwrite)
    assert target.read_text() == "keep\n"
