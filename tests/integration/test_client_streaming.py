"""Pipelined streaming and concurrency against the real emulator process: every line is
answered once and in order, a stream stops at the first error (writing nothing after its reply
arrived), items that are no lines are bad lines, and a stream runs in a task through ``run()``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator

import pytest
from waiting import wait_until

from mirobot_async import (
    LineResult,
    Mirobot,
    MirobotCommandError,
    MirobotUsageError,
    MotionRefusedError,
    State,
)
from mirobot_async.testing import EmulatorProcess, WireSpy

pytestmark = [pytest.mark.timeout(60), pytest.mark.usefixtures("no_leftover_tasks")]


async def test_ten_thousand_lines_each_acknowledged_once_in_order(ready_arm: Mirobot) -> None:
    arm = ready_arm
    lines = [f"M3 S{i % 1001}" if i % 3 else "G4 P0" for i in range(10_000)]
    acked_before = arm.stats.lines_acknowledged
    numbers: list[int] = []
    stream = arm.stream(lines)
    async with contextlib.aclosing(aiter(stream)) as results:  # type: ignore[type-var]
        async for result in results:
            assert result.ok, result
            assert result.line == lines[result.number - 1]
            numbers.append(result.number)
    assert numbers == list(range(1, 10_001))
    assert stream.result.acknowledged == stream.result.sent == 10_000
    assert stream.result.ok
    assert arm.stats.lines_acknowledged - acked_before == 10_000
    assert arm.stats.replies_lost == 0 and arm.stats.protocol_violations == 0
    last_pump = max(i for i in range(10_000) if i % 3)
    assert (await arm.status()).pump_pwm == last_pump % 1001
    assert arm.pending_count == 0


async def test_streaming_keeps_the_receive_buffer_full_but_never_overfull(
    ready_arm: Mirobot, wire_spy: WireSpy
) -> None:
    arm = ready_arm
    peak = 0

    def spy(chunk: bytes) -> None:
        nonlocal peak
        peak = max(peak, arm.bytes_in_flight)  # the line being written is counted already

    wire_spy.write_hooks.append(spy)
    result = await arm.stream(f"M4 E{i % 1001}" for i in range(1_000))
    assert result.acknowledged == 1_000
    assert 100 < peak <= 127  # the firmware's ring holds 127 bytes (one of 128 slots stays free)


async def test_stream_with_status_polling_alongside(ready_arm: Mirobot) -> None:
    arm = ready_arm
    seen: list[State] = []

    async def monitor() -> None:
        async with contextlib.aclosing(arm.statuses(interval=0.001)) as reports:
            async for report in reports:
                seen.append(report.state)

    watcher = asyncio.create_task(monitor())
    try:
        result = await arm.stream(f"M3 S{i % 1001}" for i in range(1_000))
    finally:
        watcher.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await watcher
    assert result.ok and result.acknowledged == 1_000
    assert len(seen) > 5
    assert arm.stats.replies_lost == 0


async def test_stream_stops_at_the_first_error_unless_asked_to_continue(
    ready_arm: Mirobot,
) -> None:
    arm = ready_arm
    # The firmware answers as fast as lines arrive, so stop early with a long tail.
    result = await arm.stream(["M3 S1", "M99", *(f"M3 S{i}" for i in range(300))], validate=False)
    assert not result.ok and result.stopped
    assert result.errors[0].number == 2
    assert isinstance(result.errors[0].error, MirobotCommandError)
    assert result.sent < 302  # stopped sending; lines already in flight were still reported
    assert result.acknowledged == result.sent - 1
    lines = ["M3 S1", "M3 S2", "M99", "M3 S3", "M21 G90 G0 X170", "M3 S4"]
    result = await arm.stream(lines, continue_on_error=True, validate=False)
    assert result.sent == 6 and result.acknowledged == 4
    assert [r.number for r in result.errors] == [3, 5]
    assert isinstance(result.errors[1].error, MotionRefusedError)
    assert not result.stopped
    assert (await arm.status()).pump_pwm == 4
    with pytest.raises(MirobotCommandError):
        result.raise_for_errors()


async def test_stream_accepts_async_iterables_and_async_callbacks(ready_arm: Mirobot) -> None:
    arm = ready_arm

    async def lines() -> AsyncIterator[str]:
        for i in range(50):
            yield f"M4 E{i}\n"
            if i % 10 == 0:
                yield "   "  # blank lines are skipped
                await asyncio.sleep(0)  # an iterable that suspends (the behaviour under test)

    progress: list[LineResult] = []

    async def on_progress(result: LineResult) -> None:
        await asyncio.sleep(0)  # a callback that suspends (the behaviour under test)
        progress.append(result)

    result = await arm.stream(lines(), on_progress=on_progress)
    assert result.ok and result.acknowledged == 50 and len(progress) == 50
    assert [p.line for p in progress] == [f"M4 E{i}" for i in range(50)]


async def test_stream_reports_bad_lines_without_sending_them(ready_arm: Mirobot) -> None:
    arm = ready_arm
    result = await arm.stream(["M3 S1", "M3 S2 ?", "M3 S3"], continue_on_error=True)
    assert result.sent == 2 and result.acknowledged == 2
    assert isinstance(result.errors[0].error, MirobotUsageError)
    assert result.errors[0].number == 2
    assert (await arm.status()).pump_pwm == 3


async def test_settings_lines_in_a_stream_are_sent_response(
    ready_arm: Mirobot, wire_spy: WireSpy
) -> None:
    arm = ready_arm
    in_flight_at_write: list[tuple[str, int]] = []

    def spy(chunk: bytes) -> None:
        if chunk.endswith(b"\n"):  # a line (registered just before it is written)
            in_flight_at_write.append((chunk.decode().strip(), arm.pending_count - 1))

    wire_spy.write_hooks.append(spy)
    lines = [f"M3 S{i}" for i in range(20)] + ["$24=1400"] + [f"M4 E{i}" for i in range(20)]
    result = await arm.stream(lines)
    assert result.ok
    index = [c for c, _ in in_flight_at_write].index("$24=1400")
    assert in_flight_at_write[index][1] == 0  # nothing in flight when it was written
    assert in_flight_at_write[index + 1][1] == 0  # and nothing written until its reply
    assert (await arm.settings())[24] == 1400


async def test_twenty_tasks_at_once_each_get_their_own_replies_in_call_order(
    ready_arm: Mirobot, profile: str, caplog: pytest.LogCaptureFixture
) -> None:
    arm = ready_arm
    issued: list[str] = []
    info = {"classic": "", "2021": "Info, ", "2024": "Info,"}[profile]

    async def worker(n: int) -> None:
        for k in range(6):
            kind = (n + k) % 4
            line = [f"M3 S{n * 10 + k}", "M50", "M99", "$X"][kind]
            issued.append(line)
            if kind == 2:
                with pytest.raises(MirobotCommandError) as err:
                    await arm.send(line, validate=False)
                assert err.value.command == "M99"
            else:
                output = await arm.send(line)
                expected = [(), (f"{info}M50: Unlock each axis.",), None, ()][kind]
                assert output == expected, (line, output)

    with caplog.at_level(logging.DEBUG, logger="mirobot_async.wire"):
        await asyncio.gather(*(worker(n) for n in range(20)))
    sent_lines = [r.getMessage() for r in caplog.records if r.name == "mirobot_async.wire"]
    written = [m[3:] for m in sent_lines if m.startswith("-> ") and m != "-> ?"]
    assert written == issued
    assert arm.pending_count == 0
    assert arm.stats.lines_sent >= 120


@pytest.mark.mirobot_emulator(time_scale=1)
async def test_cancelling_a_stream_stops_sending_and_keeps_the_link_in_step(
    ready_arm: Mirobot,
) -> None:
    arm = ready_arm
    acknowledged: list[LineResult] = []
    stream = asyncio.ensure_future(arm.stream(["G4 P0.02"] * 200, on_progress=acknowledged.append))
    await wait_until(
        lambda: len(acknowledged) >= 5 and arm.pending_count >= 5, 10, "5 results and 5 pending"
    )
    stream.cancel()
    with pytest.raises(asyncio.CancelledError):
        await stream
    in_flight = arm.pending_count
    sent = arm.stats.lines_sent
    assert in_flight > 0 and sent < 200
    # the abandoned lines' replies are consumed and discarded; a new call gets its own
    assert await arm.send("M50") != ()
    assert arm.stats.replies_discarded == in_flight
    assert arm.stats.lines_sent == sent + 1
    assert arm.pending_count == 0


async def test_stream_items_of_other_types_are_bad_lines(
    ready_arm: Mirobot, wire_spy: WireSpy
) -> None:
    """13.13: an int, None or a bytearray in a stream raised a bare AssertionError."""
    arm = ready_arm
    mark = wire_spy.mark()
    items: list[object] = ["M3 S1", 5, None, bytearray(b"M3 S2"), b"M3 S3"]
    result = await arm.stream(items, continue_on_error=True)  # type: ignore[arg-type]
    assert result.sent == 3 and result.acknowledged == 3
    assert [r.number for r in result.errors] == [2, 3]
    assert all(isinstance(r.error, MirobotUsageError) for r in result.errors)
    assert wire_spy.lines(mark) == [b"M3 S1\n", b"M3 S2\n", b"M3 S3\n"]
    stopped = await arm.stream(["M3 S4", object(), "M3 S5"])  # type: ignore[list-item]
    assert stopped.stopped and stopped.sent == 1
    assert isinstance(stopped.errors[0].error, MirobotUsageError)
    assert (await arm.status(fresh=True)).pump_pwm == 4


@pytest.mark.emulator_process
async def test_stream_writes_nothing_after_the_failing_reply_arrived(
    ready_arm: Mirobot, emu: EmulatorProcess, wire_spy: WireSpy
) -> None:
    arm = ready_arm
    lines = ["M3 S0"] * 30 + ["G4 P0.3", "FOO BAR"] + ["M3 S0"] * 60
    failing = lines.index("FOO BAR") + 1
    written = 0
    written_when_error_arrived: int | None = None
    written_after_error = 0

    def write_spy(chunk: bytes) -> None:
        nonlocal written, written_after_error
        if not chunk.endswith(b"\n"):
            return  # a realtime byte, not a line
        written += 1
        if written_when_error_arrived is not None:
            written_after_error += 1

    def receive_spy(chunk: bytes) -> None:
        # runs right after the client handled the chunk (its replies dispatched)
        nonlocal written_when_error_arrived
        # an error reply: "error:", "Error, E1nn"; 2024: "FOO BAR" is GRBL's status error 1,
        # "Info,E100,..." (docs/2024-profile.md)
        if written_when_error_arrived is None and (b"rror" in chunk or b"Info,E" in chunk):
            written_when_error_arrived = written

    before = int((await emu.control("stats")).split("lines_in=")[1].split()[0])
    wire_spy.write_hooks.append(write_spy)
    wire_spy.receive_hooks.append(receive_spy)
    # validate=False: the firmware itself must refuse the line, so its error reply arrives
    result = await arm.stream(lines, validate=False)
    assert result.stopped and len(result.errors) == 1
    assert result.errors[0].number == failing
    assert isinstance(result.errors[0].error, MirobotCommandError)
    assert written_when_error_arrived is not None
    assert written_after_error == 0
    assert result.sent == written_when_error_arrived
    # the lines after the failing one that were already in flight fit the 128-byte buffer
    assert failing <= result.sent <= failing + 128 // len(b"M3 S0\n")
    assert arm.pending_count == 0  # every written line was answered, so the emulator has it
    after = int((await emu.control("stats")).split("lines_in=")[1].split()[0])
    assert after - before == result.sent


async def test_a_stream_runs_in_a_task_through_its_run_coroutine(ready_arm: Mirobot) -> None:
    arm = ready_arm
    task = asyncio.create_task(arm.stream(["M3 S0", "M3 S10"] * 10).run())
    result = await task
    assert result.ok and result.sent == result.acknowledged == 20
    stream = arm.stream(["M3 S0"])
    assert (await stream).acknowledged == 1
    with pytest.raises(MirobotUsageError, match="only once"):
        await stream.run()
