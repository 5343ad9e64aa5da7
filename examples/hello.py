"""Hello, Mirobot: home the arm, wave joint 1, print where the tool is.

Usage::

    python examples/hello.py                 # an embedded virtual Mirobot
    python examples/hello.py /dev/ttyUSB0    # a real arm (it moves!)
"""

import asyncio
import contextlib
import sys

from mirobot_async import Mirobot
from mirobot_async.virtual import start_emulator


async def main(port: str | None) -> None:
    async with contextlib.AsyncExitStack() as stack:
        if port is None:
            port = await stack.enter_async_context(start_emulator(time_scale=10, in_process=True))
            print(f"no port given: using an embedded virtual Mirobot on {port}")
        arm = await stack.enter_async_context(Mirobot.connect(port))

        print("homing...")
        await arm.home()
        for angle in (30, -30, 0):
            await arm.move_joints(j1=angle, speed=3000)  # returns when the arm is there
            report = await arm.status()
            x, y, z, *_ = report.pose
            print(f"J1 = {report.joints[0]:6.1f} deg: tool at x={x:.1f} y={y:.1f} z={z:.1f} mm")
        await arm.move_pose(x=200, y=0, z=150)
        status = await arm.status()
        x, y, z, *_ = status.pose
        print(f"{status.state.value}: tool at x={x:.1f} y={y:.1f} z={z:.1f} mm")


if __name__ == "__main__":
    asyncio.run(main(sys.argv[1] if len(sys.argv) > 1 else None))
