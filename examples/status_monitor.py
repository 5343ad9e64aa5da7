"""Watch the arm's status a few times per second (Ctrl-C to stop).

Usage::

    python examples/status_monitor.py                 # an embedded virtual Mirobot
    python examples/status_monitor.py /dev/ttyUSB0    # a real arm (nothing moves)
    python examples/status_monitor.py /dev/ttyUSB0 50 # stop after 50 samples

Against the embedded virtual Mirobot it stops after 15 samples: it is homed first (the firmware
answers no status request while its homing switches are searched), then another task swings
joints 1 and 2 so that there is something to watch.
"""

import asyncio
import contextlib
import sys

from mirobot_async import Mirobot
from mirobot_async.virtual import start_emulator


async def something_to_watch(arm: Mirobot) -> None:
    await arm.move_joints(j1=60, j2=20, speed=2000)


async def main(port: str | None, samples: int | None) -> None:
    embedded = port is None
    async with contextlib.AsyncExitStack() as stack:
        if port is None:
            port = await stack.enter_async_context(start_emulator(time_scale=5, in_process=True))
            print(f"no port given: using an embedded virtual Mirobot on {port}")
            samples = samples or 15
        arm = await stack.enter_async_context(Mirobot.connect(port))
        if embedded:
            await arm.home()
        demo = asyncio.create_task(something_to_watch(arm)) if embedded else None

        count = 0
        async with contextlib.aclosing(arm.statuses(interval=0.2)) as statuses:
            async for report in statuses:
                count += 1
                j = " ".join(f"{angle:8.3f}" for angle in report.joints)
                x, y, z, *_ = report.pose
                print(f"{count:4} {report.state.value:<5} J {j}  xyz {x:7.2f} {y:7.2f} {z:7.2f}")
                if samples is not None and count >= samples:
                    break
        if demo is not None:
            await demo


if __name__ == "__main__":
    port = sys.argv[1] if len(sys.argv) > 1 else None
    samples = int(sys.argv[2]) if len(sys.argv) > 2 else None
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(main(port, samples))
