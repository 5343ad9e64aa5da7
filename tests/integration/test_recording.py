"""Recording a tape (``Mirobot.connect(record=FILE)``, ``mirobot ... --record FILE``): it holds
exactly the bytes the client wrote and the lines it received, in order, after a header that
says where they came from; it is closed with the connection however that ends; a recording
whose process is killed is readable up to its last whole line; and a virtual arm's tape
replays equal into the firmware model."""

from __future__ import annotations

import os
import platform
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from waiting import wait_for

from mirobot_async import Mirobot, MirobotConnectionError, MirobotLinkLostError
from mirobot_async._tapes.format import Marker, Printed, Tape, Written, read_tapes
from mirobot_async._tapes.replay import replay
from mirobot_async.testing import EmulatorProcess, InProcessArm, WireSpy

pytestmark = pytest.mark.timeout(90)

HEADER_FIELDS = {
    "id", "source", "clock", "link", "baud", "banner", "family", "family_evidence",
    "library_version", "os", "python", "started",
}  # fmt: skip


def _one_tape(path: Path) -> Tape:
    [tape] = read_tapes(path)
    return tape


def _lines(chunks: list[bytes]) -> list[bytes]:
    data = b"".join(chunks)
    return [line + b"\n" for line in data.split(b"\n")[:-1]]


def _check_against_spy(tape: Tape, spy: WireSpy) -> None:
    """The tape holds every write the client made, one event each, and every line received."""
    assert [e.data for e in tape.events if isinstance(e, Written)] == spy.writes
    printed = [e for e in tape.events if isinstance(e, Printed)]
    assert [e.data for e in printed if not e.partial] == _lines(spy.received)
    assert isinstance(tape.events[-1], Marker) and tape.events[-1].fields["end"] == "closed"
    times = [e.t for e in tape.events]
    assert times == sorted(times)


async def _session(url: str, path: Path, spy: WireSpy) -> None:
    async with Mirobot.connect(url, record=path, open_transport=spy.opener) as arm:
        await arm.home()
        await arm.move_joints(j1=20, j2=10)
        await arm.status()


async def test_a_virtual_arm_is_recorded_on_its_simulated_clock(
    profile: str, tmp_path: Path
) -> None:
    path = tmp_path / "session.jsonl"
    spy = WireSpy()
    with InProcessArm(profile, time_scale=0) as virtual:
        await _session(virtual.url, path, spy)
    tape = _one_tape(path)
    _check_against_spy(tape, spy)
    header = tape.header
    assert HEADER_FIELDS | {"time_scale"} <= set(header)
    assert header["source"] == "virtual" and header["link"] == "virtual"
    assert header["clock"] == "simulated" and header["time_scale"] == 0.0
    assert header["family"] == profile and header["family_evidence"] == "virtual arm"
    assert header["baud"] is None and header["id"].startswith("recorded ")
    assert header["python"] == platform.python_version()
    assert tape.end_t > 8  # simulated seconds: homing alone takes more (wall time: none)


@pytest.mark.emulator_process
async def test_an_emulator_process_over_a_pty_is_recorded_on_the_wall_clock(
    emu: EmulatorProcess, profile: str, tmp_path: Path
) -> None:
    path = tmp_path / "session.jsonl"
    spy = WireSpy()
    await _session(emu.url, path, spy)
    tape = _one_tape(path)
    _check_against_spy(tape, spy)
    header = tape.header
    assert header["source"] == "device" and header["clock"] == "wall"
    if "://" not in emu.url:
        assert header["link"] == "serial" and header["baud"] == 115200
    else:
        assert header["link"] == "tcp" and header["baud"] is None
    assert str(tmp_path) not in path.read_text().splitlines()[0]
    assert emu.url not in path.read_text()  # neither the pty's path nor a host
    # the pool's emulator printed its banner before the port was opened: no family is known
    # at the end of the connect unless a banner said it
    assert header["family"] in (None, profile)
    assert (header["family_evidence"] == "banner") == (header["family"] is not None)


async def test_the_file_is_closed_when_the_connect_fails(tmp_path: Path) -> None:
    path = tmp_path / "failed.jsonl"
    with pytest.raises(MirobotConnectionError):
        await Mirobot.connect("virtual://no-such-arm", record=path)
    tape = _one_tape(path)
    [end] = tape.events
    assert isinstance(end, Marker) and end.fields["end"] == "closed"


async def test_a_lost_link_ends_the_tape(tmp_path: Path) -> None:
    path = tmp_path / "lost.jsonl"
    with InProcessArm("2021", time_scale=0) as virtual:
        arm = await Mirobot.connect(virtual.url, record=path)
        await arm.status()
    with pytest.raises(MirobotLinkLostError):
        await arm.status()
    await arm.close()
    tape = _one_tape(path)
    end = tape.events[-1]
    assert isinstance(end, Marker) and end.fields["end"] == "lost"


def test_cli_record_writes_a_tape(
    cli: Callable[..., subprocess.CompletedProcess[str]], tmp_path: Path
) -> None:
    path = tmp_path / "cli.jsonl"
    result = cli("move", "joints", "j1=10", "--time-scale", "0", "--record", str(path))
    assert result.returncode == 0, result.stderr
    tape = _one_tape(path)
    assert tape.header["family_evidence"] == "given" and tape.header["link"] == "virtual"
    written = b"".join(e.data for e in tape.events if isinstance(e, Written))
    assert b"$H" in written and b"X10" in written


def test_a_killed_recording_is_readable_up_to_its_last_whole_line(tmp_path: Path) -> None:
    path = tmp_path / "killed.jsonl"
    command = [sys.executable, "-m", "mirobot_async", "monitor", "--time-scale", "0"]
    command += ["--interval", "0.001", "--record", str(path)]
    with subprocess.Popen(
        command,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        stdin=subprocess.DEVNULL,
        start_new_session=True,
    ) as proc:
        try:
            wait_for(
                lambda: path.exists() and path.read_text().count("\n") > 200,
                30,
                "200 lines of tape",
            )
        finally:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    tape = _one_tape(path)
    assert len(tape.events) > 199
    assert not any(isinstance(e, Marker) for e in tape.events)  # killed: no end marker
    assert any(isinstance(e, Printed) and e.data.startswith(b"<") for e in tape.events)


@pytest.mark.parametrize("scale", [50.0])
async def test_a_virtual_arms_tape_replays_equal(
    profile: str, scale: float, tmp_path: Path
) -> None:
    """Connect, home, a move, a status: the replay into a fresh firmware model prints the same
    lines in the same order; at time scale 1 at the same instants (loosely: the arm's clock loop
    wakes when the host lets it), faster than real time the instants are not compared (a host
    that stalls 0.1 s moves the arm's clock 1 s at time scale 10)."""
    path = tmp_path / "replay.jsonl"
    with InProcessArm(profile, time_scale=scale) as virtual:
        await _session(virtual.url, path, WireSpy())
    report = replay(_one_tape(path), profile)
    assert report.equal, str(report.difference)
    assert report.lines > 10
    assert report.instants == "none"  # at time scale 1: tests/realtime
