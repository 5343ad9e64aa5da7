"""Motion timing in simulated time: the oracle's ``-l`` log against our emulator's clock.

Each program is streamed (character counting) after the arm has settled, followed by ``G4 P0``,
whose ``ok`` comes once the planner is empty. Its time runs from the ``ok`` of its first line
(the first block is planned and starts) to the end of motion. On the oracle both instants come
from its simulated-time log (the end: the dwell's ``ok``). On ours the end is its last
``motion-ends`` instant (mapped exactly from its simulated clock); its start lies between the
wall time just before the first byte was written plus the first line's byte time (its last byte
cannot arrive earlier: one byte per 100 us simulated, the oracle harness's pace, modelled by ours)
and the wall time its ``ok`` was read, times the time scale. The test passes when that interval
comes within the tolerance of the oracle's time, and demands the interval be narrower than the
tolerance (else the measurement is repeated on a fresh pair, up to :data:`MEASUREMENTS` times,
and reported as too imprecise, e.g. on an overloaded host). The replies are compared byte for
byte too.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from .harness import HarnessError, Pair, is_terminal, lines_of, motion_ends, oracle_log


def circle(n: int, radius: float = 20.0) -> list[str]:
    """``n`` short straight Cartesian segments around a circle near the start pose.

    ``M20`` is set once, by the first line: a line that carries ``M20`` starts from where the
    arm *is* when it is parsed (the firmware resynchronises its position), so a program that
    repeats it follows a path that depends on how far ahead the host streams: with ``M20`` on
    every line the oracle took 7.340 s and our emulator 7.15-7.25 s depending on the host's
    load. Every line names ``A0 B0 C0``: without them the orientation is re-read from the arm's
    current (rounded) position (the oracle's own time then varied: 10.139 s and 9.867 s). With
    both, the oracle takes 7.201 s (six runs, one 7.163 s on a loaded host).
    """
    out = ["M20 G90 G1 X202 Y0 Z160 A0 B0 C0 F2000"]
    for i in range(1, n + 1):
        a = 2 * math.pi * i / n
        x, y = 182 + radius * math.cos(a), radius * math.sin(a)
        out.append(f"G1 X{x:.3f} Y{y:.3f} Z160 A0 B0 C0")
    return out


PROGRAMS: dict[str, tuple[list[str], float, float, float]] = {
    # name: (lines, relative tolerance, absolute tolerance in seconds, our time scale). Single
    # moves run slowly on ours (2x) so that the read latency of the first ok stays near 1 ms
    # simulated; long programs faster (the tolerance is then 100 ms or more).
    "joint-single": (["M21 G90 X30 F2000"], 0.01, 0.010, 2.0),
    "joint-six-axes": (["M21 G90 X10 Y-10 Z15 A-20 B-25 C30 F2000"], 0.01, 0.010, 2.0),
    "joint-short-segments": ([f"M21 G90 X{i * 0.5:g} F2000" for i in range(1, 61)], 0.02, 0.0, 2.0),
    "cart-g0": (["M20 G90 G0 X180 Y20 Z120 A0 B0 C0 F2000"], 0.02, 0.0, 2.0),
    "cart-g1": (["M20 G90 G1 X180 Y20 Z120 A0 B0 C0 F2000"], 0.02, 0.0, 2.0),
    "cart-g1-200-segments": (circle(200), 0.02, 0.0, 4.0),
}


def first_ok_wall(exchange_start: int, pair: Pair) -> float:
    """Wall time at which our emulator's first ``ok`` after offset ``exchange_start`` was read."""
    data = bytes(pair.ours.received)
    at = data.index(b"ok\r\n", exchange_start) + 4
    return next(wall for wall, size in pair.ours.arrivals if size >= at)


def program_times(
    pair: Pair, workdir: Path, program: list[str], scale: float
) -> tuple[float, float, float]:
    """Simulated seconds of ``program``: the oracle's, and ours as an interval (shortest,
    longest), measured as the module docstring says."""
    pair.lines("M50")
    pair.settle()
    logged_before = pair.oracle.received.count(b"\n")
    ours_start = len(pair.ours.received)
    exchange = pair.stream([*program, "G4 P0"])
    if sum(map(is_terminal, lines_of(exchange.oracle))) != len(program) + 1:
        raise HarnessError(f"the oracle did not answer every line: {exchange.oracle!r}")
    log = oracle_log(workdir)[logged_before:]
    oks = [stamp for stamp, text in log if is_terminal(text.encode())]
    oracle = oks[-1] - oks[0]
    ends = motion_ends(pair.ours)
    start = first_ok_wall(ours_start, pair)
    assert ends and ends[-1] > start, f"no end of motion after the program's start: {ends}"
    # The first line cannot be parsed before its last byte arrived: the wire (ours as the
    # oracle's harness) delivers one byte per 100 us simulated, so the start is no earlier.
    earliest = pair.first_write + len(program[0].encode() + b"\n") * BYTE_SECONDS / scale
    return oracle, (ends[-1] - start) * scale, (ends[-1] - earliest) * scale


BYTE_SECONDS = 100e-6
"""Simulated seconds per received byte (the oracle harness's documented input pace, which
our emulator models too: ``mirobot_emulator.firmware.wire``)."""


MEASUREMENTS = 3  # fresh attempts when our side's start interval is too wide (a loaded host)


@pytest.mark.timeout(240)  # the oracle slows down on a loaded host
@pytest.mark.parametrize("name", PROGRAMS)
def test_program_time(tmp_path: Path, name: str) -> None:
    program, relative, absolute, scale = PROGRAMS[name]
    for attempt in range(MEASUREMENTS):
        workdir = tmp_path / f"attempt{attempt}"
        pair = Pair.spawn(workdir, time_scale=scale).connect()
        try:
            oracle, shortest, longest = program_times(pair, workdir, program, scale)
            pair.status()
            pair.finish()
            replies = pair.differences()
        finally:
            pair.close()
        allowed = max(relative * oracle, absolute)
        if longest - shortest <= allowed / 2:
            break
    off = max(shortest - oracle, oracle - longest, 0.0)
    ours = (shortest + longest) / 2
    timing_ok = off <= allowed and longest - shortest <= allowed
    problems = (
        []
        if timing_ok
        else [
            f"{name}: oracle {oracle:.3f} s, ours {shortest:.3f}..{longest:.3f} s simulated "
            f"({(ours / oracle - 1) * 100:+.1f} %, allowed {allowed * 1000:.0f} ms)"
        ]
    )
    if replies:
        problems.append("oracle and emulator differ:\n" + "\n".join(replies))
    assert not problems, "\n".join(problems)
