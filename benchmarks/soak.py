"""Soak: stream many lines with concurrent status polling and check nothing is lost or leaks.

``python benchmarks/soak.py [--lines 1000000] [--poll-interval 0.05]`` (issue 7, section 3)

One emulator process (time scale 0: every line is acknowledged as soon as it is parsed) on a real
pty; the client streams ``--lines`` cheap non-motion lines (``M3 S<pwm>``) while another task polls
the status every ``--poll-interval`` seconds. Checked:

* **every line acknowledged exactly once, in order**: the stream's ``on_progress`` sees line
  numbers 1..N in order, each with the text that was sent and no error; the client's counters
  show exactly N more lines sent and acknowledged, none rejected, lost or discarded, no protocol
  violation;
* **in order on the robot's side too**: line ``i`` sets the pump PWM to ``i % 1001``, so every
  status report shows which line the firmware executed last. A report to a ``?`` written when
  ``a0`` lines were acknowledged and read when ``a1`` were must show the PWM of one of the lines
  ``a0-1 .. a1-1`` (a window far smaller than 1001 lines), so a line executed twice, skipped or
  out of order shows up as a wrong PWM;
* **no growth in pending state**: at the end nothing is owed a reply (``pending_count == 0``,
  ``bytes_in_flight == 0``, no outstanding ``?``, no waiter left);
* **no growth in memory**: RSS after the stream minus RSS after a warm-up stream stays below
  ``--max-rss-growth`` MB (psutil).

The test suite runs the 50,000-line variant (``tests/integration/test_soak.py``). Exit status 0
when every check passes, 1 otherwise.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import gc
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field

import psutil

from mirobot_async import LineResult, Mirobot
from mirobot_async.virtual import start_emulator

PWM_VALUES = 1001  # M3 S0 .. S1000
WARMUP_LINES = 5_000
MB = 1024 * 1024


def soak_line(index: int) -> str:
    """Line ``index`` (0-based) of the soak stream: sets the pump PWM to ``index % 1001``."""
    return f"M3 S{index % PWM_VALUES}"


def soak_lines(count: int) -> Iterator[str]:
    """The stream, generated lazily (a list of a million strings would dwarf any leak)."""
    return (soak_line(i) for i in range(count))


@dataclass
class SoakResult:
    """Figures and verdicts of one soak run; :attr:`problems` is empty when everything passed."""

    lines: int
    poll_interval: float
    implementation: str
    seconds: float = 0.0
    acknowledged: int = 0  # lines seen by on_progress, in order and without error
    statuses: int = 0  # status reports received by the poller
    status_checked: int = 0  # reports whose pump PWM matched the acknowledged window
    corrupted_statuses: int = 0
    rss_start_mb: float = 0.0  # after connecting and a warm-up stream
    rss_peak_mb: float = 0.0  # highest sample while streaming
    rss_end_mb: float = 0.0
    pending_count: int = -1
    bytes_in_flight: int = -1
    problems: list[str] = field(default_factory=list)

    @property
    def lines_per_s(self) -> float:
        return self.lines / self.seconds if self.seconds > 0 else 0.0

    @property
    def rss_growth_mb(self) -> float:
        return self.rss_end_mb - self.rss_start_mb

    @property
    def ok(self) -> bool:
        return not self.problems

    def problem(self, text: str) -> None:
        if len(self.problems) < 20:
            self.problems.append(text)
        elif len(self.problems) == 20:
            self.problems.append("... (more problems not listed)")

    def report(self) -> str:
        verdict = "PASS" if self.ok else "FAIL"
        lines = [
            f"soak {verdict}: {self.lines:,} lines in {self.seconds:.1f} s "
            f"({self.lines_per_s:,.0f} lines/s, serial layer {self.implementation!r})",
            f"  acknowledged in order: {self.acknowledged:,} / {self.lines:,}",
            f"  statuses polled every {self.poll_interval:g} s: {self.statuses:,} "
            f"({self.status_checked:,} matched the acknowledged window), "
            f"corrupted: {self.corrupted_statuses}",
            f"  RSS: start {self.rss_start_mb:.1f} MB, peak {self.rss_peak_mb:.1f} MB, "
            f"end {self.rss_end_mb:.1f} MB (growth {self.rss_growth_mb:+.2f} MB)",
            f"  pending at the end: {self.pending_count} lines, "
            f"{self.bytes_in_flight} bytes in flight",
        ]
        lines += [f"  problem: {p}" for p in self.problems]
        return "\n".join(lines)


def rss_mb() -> float:
    gc.collect()
    return float(psutil.Process().memory_info().rss) / MB


def _pwm_matches(pwm: int, acked_before: int, acked_after: int) -> bool:
    """Whether the last line the firmware executed, per ``pwm``, lies in the acknowledged window.

    Lines ``0 .. acked_before-1`` were acknowledged (so executed) before the ``?`` was written, and
    the report arrived before the reply of line ``acked_after``: the last executed line ``k`` is in
    ``acked_before-1 .. acked_after-1`` (``k == -1``: none yet, the PWM is still 0).
    """
    for k in range(max(acked_before - 1, -1), acked_after):
        if (k == -1 and pwm == 0) or (k >= 0 and k % PWM_VALUES == pwm):
            return True
    return False


async def _poll(
    arm: Mirobot,
    interval: float,
    first_line_acks: int,
    result: SoakResult,
    stop: asyncio.Event,
) -> None:
    """Poll the status until ``stop``; check each report's PWM against the acknowledged window."""
    stats = arm.stats
    while not stop.is_set():
        before = stats.lines_acknowledged - first_line_acks
        report = await arm.status()
        after = stats.lines_acknowledged - first_line_acks
        result.statuses += 1
        if _pwm_matches(report.pump_pwm, before, after):
            result.status_checked += 1
        else:
            result.problem(
                f"status shows pump PWM {report.pump_pwm}, but lines {before}..{after} had been "
                "acknowledged around it (a line lost, repeated or out of order)"
            )
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(interval):
                await stop.wait()


async def soak(
    url: str,
    lines: int,
    poll_interval: float = 0.05,
    *,
    implementation: str = "fast",
    progress: bool = False,
) -> SoakResult:
    """Run the soak against the emulator at ``url`` (its pump PWM must be settable: unlocked)."""
    result = SoakResult(lines, poll_interval, implementation)
    async with Mirobot.connect(url, implementation=implementation) as arm:  # type: ignore[arg-type]
        await arm.unlock()
        await arm.stream(soak_lines(WARMUP_LINES))  # reach steady state before the RSS baseline
        await arm.send("M3 S0")  # the PWM before line 0 (see _pwm_matches)
        start_stats = _stat_tuple(arm)
        result.rss_start_mb = result.rss_peak_mb = rss_mb()
        sample_every = max(1, lines // 20)
        print_every = max(1, lines // 10)
        expected = 0

        def on_progress(line: LineResult) -> None:
            nonlocal expected
            index = expected
            expected += 1
            if line.number != index + 1 or line.line != soak_line(index) or not line.ok:
                result.problem(
                    f"line {index + 1}: got #{line.number} {line.line!r} (error {line.error!r}), "
                    f"expected {soak_line(index)!r}"
                )
            else:
                result.acknowledged += 1
            if expected % sample_every == 0:
                result.rss_peak_mb = max(
                    result.rss_peak_mb, psutil.Process().memory_info().rss / MB
                )
            if progress and expected % print_every == 0:
                print(f"  {expected:,} lines ...", file=sys.stderr, flush=True)

        stop = asyncio.Event()
        poller = asyncio.create_task(_poll(arm, poll_interval, start_stats[1], result, stop))
        started = time.perf_counter()
        try:
            outcome = await arm.stream(soak_lines(lines), on_progress=on_progress)
        finally:
            result.seconds = time.perf_counter() - started
            stop.set()
            await poller
        if not outcome.ok or outcome.acknowledged != lines or outcome.sent != lines:
            result.problem(
                f"stream result: sent {outcome.sent}, acknowledged {outcome.acknowledged}, "
                f"{len(outcome.errors)} errors, stopped={outcome.stopped}"
            )
        deltas = [now - then for now, then in zip(_stat_tuple(arm), start_stats, strict=True)]
        names = ("sent", "acknowledged", "rejected", "lost", "discarded", "violations", "corrupt")
        want = (lines, lines, 0, 0, 0, 0, None)
        for name, delta, wanted in zip(names, deltas, want, strict=True):
            if wanted is not None and delta != wanted:
                result.problem(f"client counter {name}: {delta}, expected {wanted}")
        result.corrupted_statuses = deltas[-1]
        # Pending state: the public count, and the state machine's own bookkeeping.
        result.pending_count = arm.pending_count
        result.bytes_in_flight = arm.bytes_in_flight
        leftovers = {
            "pending lines": arm.pending_count,
            "bytes in flight": arm.bytes_in_flight,
            "outstanding status requests": arm.status_requests_outstanding,
            "reply slots": arm.reply_slot_count,
            "status waiters": arm.status_waiter_count,
        }
        for name, count in leftovers.items():
            if count:
                result.problem(f"{name} left at the end: {count}")
        result.rss_end_mb = rss_mb()
        result.rss_peak_mb = max(result.rss_peak_mb, result.rss_end_mb)
    if result.acknowledged != lines:
        result.problem(f"on_progress saw {result.acknowledged} good lines of {lines}")
    if result.statuses == 0:
        result.problem("the poller received no status report")
    return result


def _stat_tuple(arm: Mirobot) -> tuple[int, ...]:
    s = arm.stats
    return (
        s.lines_sent,
        s.lines_acknowledged,
        s.lines_rejected,
        s.replies_lost,
        s.replies_discarded,
        s.protocol_violations,
        s.status_corrupted,
    )


async def run_soak(
    lines: int,
    poll_interval: float = 0.05,
    *,
    implementation: str = "fast",
    max_rss_growth_mb: float = 5.0,
    progress: bool = False,
) -> SoakResult:
    """Start an emulator (time scale 0), run :func:`soak` against it, judge the RSS growth."""
    async with start_emulator(time_scale=0) as url:
        result = await soak(
            url, lines, poll_interval, implementation=implementation, progress=progress
        )
    if result.rss_growth_mb >= max_rss_growth_mb:
        result.problem(
            f"RSS grew by {result.rss_growth_mb:.2f} MB (limit {max_rss_growth_mb:g} MB)"
        )
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=1_000_000, help="lines to stream")
    parser.add_argument(
        "--poll-interval", type=float, default=0.05, help="seconds between status polls"
    )
    parser.add_argument(
        "--implementation",
        choices=("fast", "original"),
        default="fast",
        help="serial layer: pyserial-asyncio-fast or pyserial-asyncio",
    )
    parser.add_argument(
        "--max-rss-growth", type=float, default=5.0, metavar="MB", help="RSS growth limit"
    )
    args = parser.parse_args(argv)
    if args.lines < 1 or not args.poll_interval >= 0:
        parser.error("--lines must be >= 1 and --poll-interval >= 0")
    result = asyncio.run(
        run_soak(
            args.lines,
            args.poll_interval,
            implementation=args.implementation,
            max_rss_growth_mb=args.max_rss_growth,
            progress=True,
        )
    )
    print(result.report())
    return 0 if result.ok else 1


if __name__ == "__main__":
    sys.exit(main())
