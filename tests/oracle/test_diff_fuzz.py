"""Hypothesis-generated sequences of valid and invalid lines, compared on both.

Each example gets a freshly powered-on pair (the next one is started while the current example
runs, so that costs little); ``%`` is not an equivalent reset (the power-on lock and settings
survive it). Lines are sent one at a time, each waiting for its reply, with a ``G4 P0`` (wait
until motion ends) between them: what a line does while the arm moves depends on the instant
(``$`` commands are refused; M20/M21 resynchronise relative moves to the machine position), and
the planner's interplay is covered by the burst and stream scenarios. An example ends with
``G4 P0`` and ``?`` at rest. Shrinking is off to keep the time bounded: a failing example is
reported as generated, and all differing examples are reported together.
"""

from __future__ import annotations

from collections.abc import Generator, Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from .harness import Pair

NUMBER = st.one_of(
    st.integers(-12, 12).map(str),
    st.floats(-12, 12, allow_nan=False).map(lambda v: f"{v:.3f}"),
    st.sampled_from(["", "-", ".", "1e2", "--1", "0x1", "1.2.3"]),
)
AXIS = st.sampled_from(list("XYZABCD"))


@st.composite
def joint_move(draw: st.DrawFn) -> str:
    words = [
        draw(st.sampled_from(["M21", ""])),
        draw(st.sampled_from(["G90", "G91", ""])),
        draw(st.sampled_from(["G0", "G1", ""])),
    ]
    words += [f"{a}{draw(NUMBER)}" for a in draw(st.lists(AXIS, max_size=3, unique=True))]
    words.append(draw(st.sampled_from(["", "F2000", "F500", "F0"])))
    return " ".join(w for w in words if w)


@st.composite
def cartesian_move(draw: st.DrawFn) -> str:
    x = 200 + draw(st.integers(-15, 15))
    y = draw(st.integers(-15, 15))
    z = 170 + draw(st.integers(-15, 15))
    mode = draw(st.sampled_from(["G0", "G1"]))
    return f"M20 G90 {mode} X{x} Y{y} Z{z} A0 B0 C0 F{draw(st.sampled_from([1000, 2000]))}"


SYSTEM = st.sampled_from(["$G", "$#", "$X", "$N", "$I", "$20=0", "$20=1", "$11=0.05", "$$", "$7=1"])
OTHER = st.sampled_from(
    [
        "M50",
        "G4 P0",
        "G4 P0.1",
        "M3 S500",
        "M3 S0",
        "M4 E65",
        "M5",
        "G90",
        "G91",
        "M20",
        "M21",
        "F1000",
        "G17",
        "G21",
        "G54",
        "",
        "(comment)",
        "G5",
        "M99",
        "X",
        "Q1",
        "G1 G0 X1",
        "T1",
        "G4",
        "N10 G4 P0",
        "g91 x1",
    ]
)
LINE = st.one_of(
    joint_move(),
    cartesian_move(),
    SYSTEM,
    OTHER,
    st.text(alphabet="GMXYZFS0123456789 .-$=", max_size=12),
)


@pytest.fixture
def pairs(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Iterator[Pair]]:
    """Fresh pairs on demand, each started while the previous one is in use."""
    spare = [Pair.spawn(Path(tmp_path_factory.mktemp("pair")))]

    def supply() -> Generator[Pair, None, None]:
        while True:
            current = spare.pop()
            spare.append(Pair.spawn(Path(tmp_path_factory.mktemp("pair"))))
            try:
                yield current.connect()
            finally:
                current.close()

    fresh = supply()
    try:
        yield fresh
    finally:
        fresh.close()
        for left in spare:
            left.close()


EXAMPLES = 20


@pytest.mark.timeout(240)  # the oracle slows down on a loaded host
def test_random_lines(pairs: Iterator[Pair]) -> None:
    """Every differing example is collected (none is shrunk) and reported together."""
    found: list[str] = []

    @settings(
        max_examples=EXAMPLES,
        derandomize=True,
        deadline=None,
        database=None,
        phases=[Phase.explicit, Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(unlock=st.booleans(), lines=st.lists(LINE, min_size=1, max_size=8))
    def example(unlock: bool, lines: list[str]) -> None:
        pair = next(pairs)
        lines = ["M50", *lines] if unlock else lines
        for i, line in enumerate(lines):
            if i:
                pair.settle()
            pair.send(line + "\n", timeout=30)
        pair.settle()
        pair.status()
        pair.finish(quiet=0.1)
        diffs = pair.differences()
        if diffs:
            found.append(f"lines={lines!r}\n" + "\n".join(diffs))

    example()
    assert not found, f"{len(found)} of {EXAMPLES} examples differ:\n" + "\n\n".join(found)
