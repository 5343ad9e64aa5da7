"""Stream a G-code program while another task watches the status: the client shares one status
request between them and the polling never disturbs the lines in flight.

Usage::

    python examples/monitor_while_streaming.py                       # virtual arm, square.gcode
    python examples/monitor_while_streaming.py /dev/ttyUSB0 [FILE]   # a real arm (it moves!)
"""

import asyncio
import contextlib
import sys
from pathlib import Path

from mirobot_async import LineResult, Mirobot
from mirobot_async.virtual import start_emulator

HERE = Path(__file__).resolve().parent


async def watch(arm: Mirobot) -> None:
    """Print the tool position five times a second until cancelled."""
    async with contextlib.aclosing(arm.statuses(interval=0.2)) as statuses:
        async for report in statuses:
            x, y, z, *_ = report.pose
            print(f"    [monitor] {report.state.value:<5} x={x:7.2f} y={y:7.2f} z={z:7.2f}")


async def main(port: str | None, lines: list[str]) -> None:
    async with contextlib.AsyncExitStack() as stack:
        if port is None:
            port = await stack.enter_async_context(start_emulator(time_scale=10, in_process=True))
            print(f"no port given: using an embedded virtual Mirobot on {port}")
        arm = await stack.enter_async_context(Mirobot.connect(port))
        await arm.home()

        def progress(line: LineResult) -> None:
            print(f"[stream] line {line.number}: {line.line}" + ("" if line.ok else " REFUSED"))

        watcher = asyncio.create_task(watch(arm))
        try:
            result = await arm.stream(lines, on_progress=progress)
            await arm.wait_idle()
        finally:
            watcher.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await watcher
        print(f"done: {result.acknowledged} lines acknowledged, final status:")
        print(await arm.status())
        result.raise_for_errors()


if __name__ == "__main__":
    port = sys.argv[1] if len(sys.argv) > 1 else None
    program = Path(sys.argv[2]) if len(sys.argv) > 2 else HERE / "square.gcode"
    asyncio.run(main(port, program.read_text().splitlines()))
