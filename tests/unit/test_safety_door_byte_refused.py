"""``@`` (GRBL's safety-door byte) is a realtime byte: the firmware takes it out of the stream
wherever it is, even inside a comment, and holds its parser until ``~``. No line carrying it is
ever written, and the one validation (``check``, ``send()``, ``stream()``, ``run``) names it."""

from __future__ import annotations

import pytest

from mirobot_async._core.line import normalize_line
from mirobot_async._core.outgoing import encode_line
from mirobot_async._core.validation import check_line
from mirobot_async.errors import MirobotUsageError

LINES_WITH_AT = ["G0 X1 @", "@", "G4 P0 (@ note)", "M3 S10 ; mail me@home", b"G1 X1 F200 (@)"]


@pytest.mark.parametrize("line", LINES_WITH_AT)
def test_encode_line_refuses_the_safety_door_byte(line: str | bytes) -> None:
    with pytest.raises(MirobotUsageError, match=r"realtime byte '@'.*until '~'"):
        encode_line(line)


@pytest.mark.parametrize("line", LINES_WITH_AT)
def test_the_validation_names_the_safety_door_byte(line: str | bytes) -> None:
    problems = check_line(line)
    assert any("'@'" in problem and "safety door" in problem for problem in problems), problems


def test_the_parser_view_drops_it_like_the_other_realtime_bytes() -> None:
    assert normalize_line("G0 X1@0") == "G0X10"
