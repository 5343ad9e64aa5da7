"""The link goes away, or never was a port: the port closed or the emulator killed mid-stream
fails every pending call within a second with :class:`MirobotConnectionError` (on both serial
implementations, reported once, nothing reaching the event loop's exception handler) and every
later call at once; a path that is no port fails at once, naming it; and a port opened for a
connection that failed (building its transport failed, the open timed out or was cancelled) is
closed.
"""

from __future__ import annotations

import asyncio
import gc
import logging
import os
import threading
import time
from pathlib import Path
from typing import Any

import psutil
import pytest
from fault_harness import (
    SLOW_MOVES,
    Spawn,
    finishes_within,
    monitor,
)
from waiting import wait_for, wait_until

from mirobot_async import (
    Mirobot,
    MirobotConnectionError,
    MirobotLinkLostError,
    StatusReport,
)
from mirobot_async.testing import EmulatorProcess

pytestmark = [pytest.mark.timeout(60), pytest.mark.usefixtures("no_leftover_tasks")]


@pytest.mark.emulator_process
@pytest.mark.mirobot_emulator(time_scale=1)
@pytest.mark.parametrize("how", ["close", "kill"])
async def test_link_cut_fails_every_pending_call_within_a_second(
    emu: EmulatorProcess, ready_arm: Mirobot, how: str, spawn: Spawn
) -> None:
    arm = ready_arm
    # Keep the pty's number: a pty's /dev/pts/N disappears when the emulator's side closes, but
    # the number is free for the next pty opened on the machine (another test's emulator) only
    # once every side is closed; connecting to a reused number below would reach that emulator.
    held = None if "://" in emu.url else os.open(emu.url, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        await cut_the_link(emu, arm, how, spawn)
    finally:
        if held is not None:
            os.close(held)


async def cut_the_link(emu: EmulatorProcess, arm: Mirobot, how: str, spawn: Spawn) -> None:
    """The link-cut scenario on a connected, unlocked ``arm`` (see the test above)."""
    reports: list[StatusReport] = []
    stream = spawn(arm.stream(SLOW_MOVES))
    await wait_until(lambda: arm.pending_count >= 4, 10, "4 calls pending")
    await emu.control("ignore-status 1000")  # so that status() is surely pending at the cut
    asked = arm.stats.status_requests
    calls = {
        "stream": stream,
        "status": spawn(arm.status(timeout=30)),
        "move": spawn(arm.move_joints(j1=45, speed=600, timeout=30)),
        "wait_idle": spawn(arm.wait_idle(timeout=30)),
        "monitor": spawn(monitor(arm, reports)),
        "send": spawn(arm.send("M3 S1", timeout=30)),  # queued behind the stream's lines
        "settings": spawn(arm.settings(timeout=30)),  # "$$" waits for an idle link
    }
    await wait_until(lambda: arm.stats.status_requests > asked, 10, "a status request")
    assert not any(task.done() for task in calls.values())
    start = time.monotonic()
    if how == "kill":
        emu.kill()
    else:
        await emu.control("close")
    _, pending = await asyncio.wait(calls.values(), timeout=3.0)  # each allows itself 30 s
    elapsed = time.monotonic() - start
    for task in pending:
        task.cancel()
    if pending:
        await asyncio.wait(pending)
    late = [name for name, task in calls.items() if task in pending]
    assert not late, f"still pending {elapsed:.2f} s after the cut: {late}"
    for name, task in calls.items():
        error = task.exception()
        assert isinstance(error, MirobotConnectionError), (name, error)
    assert arm.closed
    for call in (arm.send("M3 S1"), arm.status(), arm.move_joints(j1=1)):
        # at once: not after a status timeout (2 s) or never; the link is named as lost
        assert isinstance(await finishes_within(1.5, call), MirobotLinkLostError)
    # the port is gone with the emulator: connecting again fails at once, and clearly
    await emu.stop()
    start = time.monotonic()
    with pytest.raises(MirobotConnectionError, match="could not open"):
        async with Mirobot.connect(emu.url):
            pass
    assert time.monotonic() - start < 2.0  # not after the connect timeout (5 s)


def process_gone(pid: int) -> bool:
    """True once process ``pid`` has exited (a zombie not reaped yet has closed its pty end)."""
    try:
        return psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


@pytest.mark.emulator_process
@pytest.mark.mirobot_emulator(time_scale=1)  # G4 P5 takes 5 s: its reply is owed
@pytest.mark.parametrize("implementation", ["fast", "original"])
@pytest.mark.parametrize("noticed_by", ["read", "write"])
async def test_a_lost_link_reaches_no_exception_handler_and_is_reported_once(
    emu: EmulatorProcess,
    implementation: Any,
    noticed_by: str,
    caplog: pytest.LogCaptureFixture,
) -> None:
    """Killing the emulator: the calls fail with MirobotLinkLostError, and that is all.

    Nothing reaches the event loop's exception handler: no "Fatal write error on serial
    transport" (a write that hits the dead pty first), no "Task exception was never retrieved
    ... 'NoneType' object has no attribute 'connection_lost'" (the serial transport's clean-up
    run twice), and the client logs no WARNING for a loss that a waiting call reports.
    """
    loop = asyncio.get_running_loop()
    reported: list[dict[str, Any]] = []
    previous = loop.get_exception_handler()
    loop.set_exception_handler(lambda _loop, context: reported.append(context))
    try:
        with caplog.at_level(logging.DEBUG, logger="mirobot_async"):
            async with Mirobot.connect(emu.url, implementation=implementation) as arm:
                await arm.unlock()
                if noticed_by == "read":
                    call = asyncio.ensure_future(arm.send("G4 P5"))  # owed a reply
                    await wait_until(lambda: arm.pending_count == 1, 10, "one call pending")
                    emu.kill()
                    with pytest.raises(MirobotLinkLostError, match="was lost"):
                        await asyncio.wait_for(call, 2)
                else:
                    emu.kill()
                    # blocking: the event loop must not see the hangup yet
                    wait_for(lambda: process_gone(emu.pid), 5, "the emulator to exit")
                    with pytest.raises(MirobotLinkLostError, match="was lost"):
                        await asyncio.wait_for(arm.send("M3 S1"), 2)
                with pytest.raises(MirobotLinkLostError):
                    await arm.send("M3 S2")
        # Let the transport's clean-up tasks finish, then collect: a task that failed
        # unretrieved reports itself when it is garbage-collected.
        others = asyncio.all_tasks() - {asyncio.current_task()}
        if others:
            await asyncio.wait(others, timeout=2)
        gc.collect()
        await asyncio.sleep(0)  # one loop turn: the exception handler's callbacks run
    finally:
        loop.set_exception_handler(previous)
    assert reported == []
    loud = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert loud == [], [r.getMessage() for r in loud]


@pytest.mark.emulator_process
@pytest.mark.mirobot_emulator(time_scale=1)
async def test_link_lost_with_the_original_pyserial_asyncio(emu: EmulatorProcess) -> None:
    async with Mirobot.connect(emu.url, implementation="original") as arm:
        await arm.unlock()
        dwell = asyncio.ensure_future(arm.send("G4 P5"))
        await wait_until(lambda: arm.pending_count == 1, 10, "one call pending")
        emu.kill()
        start = time.monotonic()
        with pytest.raises(MirobotLinkLostError):
            await asyncio.wait_for(dwell, 3.0)
        assert time.monotonic() - start < 3.0  # the dwell alone would take 5 s


@pytest.mark.parametrize("kind", ["missing", "missing-dir", "dangling-link", "directory", "file"])
async def test_connect_to_a_path_that_is_no_port_fails_at_once(tmp_path: Path, kind: str) -> None:
    path = {
        "missing": Path("/dev/ttyMIROBOT-does-not-exist"),
        "missing-dir": tmp_path / "nowhere" / "ttyUSB0",
        "dangling-link": tmp_path / "mirobot",
        "directory": tmp_path,
        "file": tmp_path / "not-a-tty",
    }[kind]
    if kind == "dangling-link":
        path.symlink_to(tmp_path / "gone")
    elif kind == "file":
        path.write_text("ok\n")
    start = time.monotonic()
    with pytest.raises(MirobotConnectionError) as info:
        async with Mirobot.connect(str(path)):
            pass
    assert time.monotonic() - start < 2.0  # not after the connect timeout (5 s)
    assert str(path) in str(info.value)
    assert "could not open" in str(info.value)


class _PortSpy:
    """Wraps ``serial.serial_for_url``: records each port opened and whether it was closed."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, *, hang: bool = False) -> None:
        import serial

        self.ports: list[Any] = []
        self.opening = False
        self.release = threading.Event()  # with ``hang``, the open waits for it
        original = serial.serial_for_url

        def opener(*args: Any, **kwargs: Any) -> Any:
            self.opening = True
            if hang:  # an open that hangs until the test lets it finish
                assert self.release.wait(10), "the test never let the open finish"
            port = original(*args, **kwargs)
            self.ports.append(port)
            return port

        monkeypatch.setattr(serial, "serial_for_url", opener)


async def test_a_port_is_closed_when_building_its_transport_fails(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from mirobot_async._client import transport

    spy = _PortSpy(monkeypatch)

    def broken(*args: Any, **kwargs: Any) -> Any:
        raise OSError("no transport today")

    monkeypatch.setattr(transport, "_PolledSerialTransport", broken)
    with pytest.raises(MirobotConnectionError, match="no transport today"):
        await transport.SerialLink.open("loop://", on_data=lambda _: None, on_lost=lambda _: None)
    assert len(spy.ports) == 1
    assert not spy.ports[0].is_open


async def test_a_port_opened_after_the_open_timed_out_is_closed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from mirobot_async._client import transport

    spy = _PortSpy(monkeypatch, hang=True)  # opened only after the open's timeout of 0.05 s
    with pytest.raises(MirobotConnectionError, match="within"):
        await transport.SerialLink.open(
            "loop://", on_data=lambda _: None, on_lost=lambda _: None, timeout=0.05
        )
    assert not spy.ports  # still opening
    spy.release.set()
    await wait_until(lambda: spy.ports and not spy.ports[0].is_open, 10, "the late port closed")
    assert len(spy.ports) == 1
    assert not spy.ports[0].is_open


async def test_a_port_opened_after_the_open_was_cancelled_is_closed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from mirobot_async._client import transport

    spy = _PortSpy(monkeypatch, hang=True)
    opening = asyncio.create_task(
        transport.SerialLink.open("loop://", on_data=lambda _: None, on_lost=lambda _: None)
    )
    await wait_until(lambda: spy.opening, 5, "the open under way (in its thread)")
    opening.cancel()  # the open hangs yet
    with pytest.raises(asyncio.CancelledError):
        await opening
    assert not spy.ports  # still opening
    spy.release.set()
    await wait_until(lambda: spy.ports and not spy.ports[0].is_open, 10, "the late port closed")
    assert len(spy.ports) == 1
    assert not spy.ports[0].is_open
