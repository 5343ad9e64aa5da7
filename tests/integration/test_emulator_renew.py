"""``renew``: a running emulator becomes what a new process would be, and the pool built on it.

The equivalence is checked from a client's side against a process started for the purpose: the
same ``stats`` (all zero), the same bytes to a fresh client (banner, status, replies), after a
session that armed faults, moved the arm, changed the clock and left output unread. Then the
:class:`~mirobot_async.testing.EmulatorPool`: what it reuses, what it refuses to reuse, and
that no process outlives it (not even when its owner is SIGKILLed).
"""

from __future__ import annotations

import asyncio
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest
import serial
from waiting import wait_for

from mirobot_async import Mirobot
from mirobot_async.testing import EmulatorError, EmulatorPool, SyncEmulatorProcess

pytestmark = [pytest.mark.timeout(60), pytest.mark.emulator_process]  # the process itself

LINKS = ("pty", "tcp")
OPTIONS = ("--reset-on-open", "--fault", "drop-ok:1", "--seed", "3")  # banner at open, 1 drop


def stats(emulator: SyncEmulatorProcess) -> dict[str, int]:
    answer = emulator.control("stats")
    return {name: int(value) for name, value in (w.split("=") for w in answer.split()[2:])}


def process_gone(pid: int) -> bool:
    """True once ``pid`` has exited (a zombie left for its new parent counts as gone)."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rpartition(")")[2].split()[0] in ("Z", "X")
    except FileNotFoundError:
        return True


def conversation(url: str) -> bytes:
    """What a fresh client sees: open the port (pyserial), send ``?`` then ``$X``, and read
    until both are answered (the ``ok`` of the first line is dropped by ``drop-ok:1``)."""
    port = serial.serial_for_url(url, 115200, timeout=0.05)
    try:
        port.write(b"?\n")
        seen = b""
        deadline = time.monotonic() + 10
        while b">" not in seen:  # the status report (after the banner printed at open)
            assert time.monotonic() < deadline, seen
            seen += port.read(4096)
        port.write(b"$X\n")
        while not seen.endswith(b"ok\r\n"):  # the second line's ok: the first was dropped
            assert time.monotonic() < deadline, seen
            seen += port.read(4096)
        return seen
    finally:
        port.close()


def mess_up(emulator: SyncEmulatorProcess) -> serial.SerialBase:
    """Leave the emulator as a careless test would: faults armed, clock changed, the arm moved
    and busy, output unread in the port; return the client, still connected."""
    port = serial.serial_for_url(emulator.url, 115200, timeout=0.05)
    port.write(b"M50\n$X\nM21 G90 G1 X10 Y20 Z30 A0 B0 C0 F2000\n")
    wait_for(lambda: stats(emulator)["lines_in"] >= 3, 10, "the lines")
    for command in ("drop-ok 3", "stall 30", "split-bytes on", "delay 40", "time-scale 0.01"):
        emulator.control(command)
    port.write(b"M21 G91 G1 X-5 F100\n" + b"?" * 50)  # a slow move; the replies left unread
    wait_for(lambda: stats(emulator)["status_requests_in"] >= 50, 10, "the status requests")
    return port


@pytest.mark.parametrize("link", LINKS)
@pytest.mark.parametrize("firmware", ["2021", "classic", "2024"])
def test_a_renewed_emulator_is_a_new_process_to_its_client(link: str, firmware: str) -> None:
    with SyncEmulatorProcess("2021", 1.0, listen=link) as used:
        leftover = mess_up(used)
        try:
            url = used.renew(firmware, 0.0, extra_args=OPTIONS)
            assert used.url == url
            renewed_stats = stats(used)
            renewed_bytes = conversation(url)
            after = stats(used)
        finally:
            leftover.close()
        with SyncEmulatorProcess(firmware, 0.0, extra_args=OPTIONS, listen=link) as new:
            assert stats(new) == renewed_stats
            assert all(
                value == 0 for name, value in renewed_stats.items() if name != "bytes_out"
            ), renewed_stats  # bytes_out: the banner, written into the pty at power-on
            assert conversation(new.url) == renewed_bytes
            assert stats(new) == after
    assert after["dropped_oks"] == 1 and after["ports_opened"] == 1  # the renewed --fault


@pytest.mark.parametrize("link", LINKS)
def test_renew_drops_the_connected_client(link: str) -> None:
    with SyncEmulatorProcess("2021", 0.0, listen=link) as emulator:
        port = serial.serial_for_url(emulator.url, 115200, timeout=0.05)
        try:
            port.write(b"?\n")
            wait_for(lambda: stats(emulator)["status_requests_in"] == 1, 10, "the status request")
            emulator.renew("2021", 0.0)

            def cut() -> bool:
                try:
                    return port.read(4096) == b"" and not port.in_waiting
                except (serial.SerialException, OSError):
                    return True  # the link ended under the client

            wait_for(cut, 10, "the old client's link to end")
        finally:
            port.close()


def test_renew_keeps_the_url_of_a_new_port_in_the_command() -> None:
    with SyncEmulatorProcess("2021", 0.0, listen="tcp") as emulator:
        emulator.renew("classic", 2.5, extra_args=["--baud", "9600"])
        assert emulator.command[3:] == (
            "--firmware",
            "classic",
            "--time-scale",
            "2.5",
            "--listen",
            "127.0.0.1:0",
            "--baud",
            "9600",
            "--exit-on-stdin-eof",
        )
        assert emulator.url.startswith("socket://127.0.0.1:")


REFUSED = [
    (["--listen", "127.0.0.1:0"], "--listen cannot be renewed"),
    (["--link", "/tmp/x"], "--link cannot be renewed"),
    (["--exit-on-stdin-eof"], "--exit-on-stdin-eof cannot be renewed"),
    (["--baud", "0"], "--baud must be positive"),
    (["--bus", "2", "--reset-on-open"], "--reset-on-open cannot be used with --bus"),
    (["--fault", "nonsense"], "nonsense"),
    (["--help"], "not renew options"),
    (["--frobnicate"], "unrecognized arguments"),
]


def test_renew_refuses_what_only_a_new_process_or_nothing_can_be() -> None:
    with SyncEmulatorProcess("2021", 0.0) as emulator:
        before_url = emulator.url
        emulator.control("drop-ok 2")
        for args, reason in REFUSED:
            with pytest.raises(EmulatorError, match=reason):
                emulator.renew("classic", 0.0, extra_args=args)
            assert emulator.url == before_url
        with pytest.raises(EmulatorError, match="quot"):  # the server splits as a shell would
            emulator.control('renew --seed "1')
        port = serial.serial_for_url(before_url, 115200, timeout=0.05)  # unchanged, serving
        try:
            port.write(b"$X\n")
            wait_for(lambda: stats(emulator)["dropped_oks"] == 1, 10, "the armed drop")
        finally:
            port.close()


def test_a_server_with_a_link_is_not_renewed(tmp_path: os.PathLike[str]) -> None:
    link = os.path.join(tmp_path, "ttyMIROBOT")
    with SyncEmulatorProcess("2021", 0.0, extra_args=["--link", link], listen="pty") as emulator:
        with pytest.raises(EmulatorError, match="link"):
            emulator.renew()
        assert os.path.realpath(link) == os.path.realpath(emulator.url)


def test_exit_on_stdin_eof_answers_what_was_read_then_exits() -> None:
    command = [sys.executable, "-m", "mirobot_emulator", "--exit-on-stdin-eof"]
    with subprocess.Popen(
        command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    ) as process:
        assert process.stdin is not None and process.stdout is not None
        assert process.stdout.readline().startswith("/dev/")
        process.stdin.write("drop-ok\nstats\n")
        process.stdin.close()
        assert process.wait(10) == 0
        lines = process.stdout.read().splitlines()
    assert lines[0] == "ack drop-ok"
    assert lines[1].startswith("ack stats ")


# ------------------------------------------------------------------------------ the pool


def test_the_pool_lends_one_process_renewed_for_each_borrower() -> None:
    with EmulatorPool(start_spares=False) as pool:
        with pool.lend("2021", 0.0) as first:
            pid = first.pid
            first.control("drop-ok 5")
        with pool.lend("classic", 0.0, extra_args=["--baud", "115200"]) as second:
            assert second.pid == pid
            assert "--baud" in second.command and "classic" in second.command
            assert stats(second)["dropped_oks"] == 0
            with pool.lend("classic", 0.0) as third:  # two at once: a second process
                assert third.pid != pid
        assert (pool.started, pool.renewed) == (2, 1)
    assert process_gone(pid) and process_gone(third.pid)


@pytest.mark.parametrize("how", ["kill", "stop", "close"])
def test_the_pool_does_not_reuse_a_killed_stopped_or_closed_process(how: str) -> None:
    with EmulatorPool(start_spares=False) as pool:
        with pool.lend() as first:
            if how == "kill":
                first.kill()
            elif how == "stop":
                first.stop()
            else:
                first.control("close")
        with pool.lend() as second:
            assert second.pid != first.pid
        assert pool.renewed == 0
    wait_for(
        lambda: process_gone(first.pid) and process_gone(second.pid), 10, "both emulators to exit"
    )


def test_fresh_fixed_ports_and_a_size_of_zero_are_not_pooled() -> None:
    with EmulatorPool(start_spares=False) as pool:
        with pool.lend(fresh=True) as fresh:
            assert "--exit-on-stdin-eof" in fresh.command  # every process: none outlives pytest
        with pool.lend(extra_args=["--listen", "127.0.0.1:0"]) as listening:
            pass
        with pool.lend() as pooled:
            assert pooled.pid not in (fresh.pid, listening.pid)
    assert process_gone(fresh.pid) and process_gone(listening.pid)
    with EmulatorPool(max_idle=0) as unpooled:
        with unpooled.lend() as one:
            pass
        with unpooled.lend() as two:
            assert two.pid != one.pid
    assert process_gone(one.pid)


def test_a_spare_started_meanwhile_replaces_a_killed_process() -> None:
    with EmulatorPool(start_spares=True) as pool:
        with pool.lend() as first:
            first.kill()
        with pool.lend("classic") as second:  # the spare, renewed: no start waited for
            assert second.pid != first.pid
            assert pool.renewed == 1
            assert stats(second)["bytes_in"] == 0
        pids = [first.pid, second.pid]
    wait_for(lambda: all(process_gone(pid) for pid in pids), 10, "every emulator to exit")


def test_the_pool_serves_asyncio_tests_on_their_own_event_loops() -> None:
    """Each asyncio.run is a new event loop, as pytest-asyncio gives each test."""

    async def borrow(pool: EmulatorPool, firmware: str) -> tuple[int, str]:
        async with pool.lend_async(firmware, 0.0) as emulator:
            async with Mirobot.connect(emulator.url) as arm:
                await arm.unlock()
                status = await arm.status()
            assert (await emulator.control("stats")).startswith("ack stats ")
            returned = emulator
        with pytest.raises(EmulatorError, match="returned to its pool"):
            await returned.control("stats")
        with pytest.raises(EmulatorError, match="returned to its pool"):
            returned.kill()  # it may be serving someone else now
        return returned.pid, str(status.state.value)

    with EmulatorPool(start_spares=False) as pool:
        first = asyncio.run(borrow(pool, "2021"))
        second = asyncio.run(borrow(pool, "classic"))
    assert first[0] == second[0]
    assert first[1] == second[1] == "Idle"


def test_no_emulator_outlives_a_sigkilled_owner(tmp_path: os.PathLike[str]) -> None:
    script = textwrap.dedent(
        """
        import sys
        from mirobot_async.testing import EmulatorPool

        pool = EmulatorPool()
        lent = pool.acquire(listen=sys.argv[1])
        print(lent.pid, flush=True)
        sys.stdin.read()  # until killed
        """
    )
    pids = []
    for link in LINKS:
        owner = subprocess.Popen(
            [sys.executable, "-c", script, link], stdin=subprocess.PIPE, stdout=subprocess.PIPE
        )
        try:
            assert owner.stdout is not None
            pids.append(int(owner.stdout.readline()))
        finally:
            owner.send_signal(signal.SIGKILL)
            owner.wait()
            assert owner.stdin is not None and owner.stdout is not None
            owner.stdin.close()
            owner.stdout.close()
    wait_for(lambda: all(process_gone(pid) for pid in pids), 10, "the orphans to exit")
