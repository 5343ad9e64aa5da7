"""Item 1: the sans-IO core alone (status parsing, command encoding, the connection's bytes)."""

from __future__ import annotations

import random
import time
from collections.abc import Callable

from figures import Config, Stat, Table, fmt_rate, rate, repeat

from mirobot_async._core import gcode
from mirobot_async._core.protocol import MirobotConnection
from mirobot_async._core.replies import State, StatusReport, format_status, parse_status

# ---- item 1: sans-IO core -------------------------------------------------------------------


def _sample_reports(n: int) -> list[StatusReport]:
    rng = random.Random(1)
    states = [State.IDLE, State.RUN, State.RUN, State.HOLD]
    reports = []
    for _ in range(n):
        reports.append(
            StatusReport(
                rng.choice(states),
                tuple(round(rng.uniform(-90, 90), 3) for _ in range(6)),  # type: ignore[arg-type]
                round(rng.uniform(0, 500), 3),
                tuple(round(rng.uniform(-250, 250), 3) for _ in range(6)),  # type: ignore[arg-type]
                rng.choice([0, 500, 1000]),
                rng.choice([0, 40, 65]),
                rng.choice([0, 1]),
            )
        )
    return reports


def _timed_loop(seconds: float, batch: Callable[[], int]) -> float:
    """Run ``batch`` (returns items done) until ``seconds`` have passed; return items per second."""
    done = 0
    start = time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        done += batch()
    return rate(done, elapsed)


def bench_parse_status(config: Config) -> Stat:
    lines = [format_status(r) for r in _sample_reports(1000)]

    def batch() -> int:
        for text in lines:
            parse_status(text)
        return len(lines)

    return repeat(config.reps, lambda: _timed_loop(config.sansio_seconds, batch))


def bench_encode(config: Config) -> Stat:
    rng = random.Random(2)
    joints = [tuple(round(rng.uniform(-25, 25), 2) for _ in range(6)) for _ in range(100)]
    poses = [
        (
            round(rng.uniform(150, 250), 2),
            round(rng.uniform(-50, 50), 2),
            round(rng.uniform(50, 200), 2),
        )
        for _ in range(100)
    ]

    def batch() -> int:
        for (j1, j2, j3, j4, j5, j6), (x, y, z) in zip(joints, poses, strict=True):
            gcode.move_joints(j1, j2, j3, j4, j5, j6)
            gcode.move_joints(j1, j2, speed=2000)
            gcode.move_pose(x, y, z, 0, 0, 0)
            gcode.move_pose(x, y, z, linear=True, speed=1500)
            gcode.set_pump(gcode.PUMP_SUCK)
        return 5 * len(joints)

    return repeat(config.reps, lambda: _timed_loop(config.sansio_seconds, batch))


def recorded_stream(lines: int, statuses_every: int = 10) -> bytes:
    """What the robot prints while a program streams and a poller asks ``?``: oks and statuses."""
    reports = _sample_reports(max(1, lines // statuses_every))
    out = bytearray()
    for i in range(lines):
        out += b"ok\r\n"
        if i % statuses_every == statuses_every - 1:
            out += format_status(reports[i // statuses_every]).encode("ascii") + b"\r\n"
    return bytes(out)


def bench_connection_bytes(config: Config) -> Stat:
    """Bytes/s through MirobotConnection.receive_data in pty-sized chunks, every event drained."""
    lines = 2000
    stream = recorded_stream(lines)
    rng = random.Random(3)
    cuts, pos = [], 0
    while pos < len(stream):
        size = rng.randint(16, 256)
        cuts.append(stream[pos : pos + size])
        pos += size

    def one() -> float:
        total, elapsed = 0, 0.0
        while elapsed < config.sansio_seconds:
            conn = MirobotConnection(rx_buffer_size=1 << 30)
            for _ in range(lines):
                conn.send_line(b"M3 S0")
            events = 0
            start = time.perf_counter()
            for chunk in cuts:
                conn.receive_data(chunk)
                for _event in conn.events():
                    events += 1
            elapsed += time.perf_counter() - start
            total += len(stream)
            assert conn.pending_count == 0 and events == lines + lines // 10, events
        return rate(total, elapsed)

    return repeat(config.reps, one)


def item_sansio(config: Config, table: Table) -> None:
    table.add("1", "Sans-IO: status lines parsed", bench_parse_status(config), fmt_rate)
    table.add("1", "Sans-IO: commands encoded", bench_encode(config), fmt_rate)
    table.add(
        "1",
        "Sans-IO: bytes through MirobotConnection",
        bench_connection_bytes(config),
        lambda v: fmt_rate(v, "B/s"),
        "oks + 1 status per 10, 16-256 B chunks",
    )
