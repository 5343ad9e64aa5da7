"""Banners, status at rest, system commands and settings: byte for byte."""

from __future__ import annotations

from pathlib import Path

import pytest

from .harness import BANNER_END, Pair, Until


def test_power_on_banner(pair: Pair) -> None:
    pair.check()  # the power-on exchange is the first one compared


def test_reset_banner_and_status(pair: Pair) -> None:
    pair.status()
    pair.reset()
    pair.status()
    pair.reset()
    pair.check()


@pytest.mark.parametrize("command", ["$", "$$", "$I", "$G", "$#", "$N", "$X", "$Z", "$$$"])
def test_system_command(pair: Pair, command: str) -> None:
    pair.send(command + "\n")
    pair.status()
    pair.check()


def test_check_mode(pair: Pair) -> None:
    """``$C`` on, lines parsed but not run, ``?`` says Check, ``$C`` off resets (banner)."""
    pair.lines("$C", "M50", "M21 G90 X10 F2000", "G4 P0")
    pair.status()
    pair.send("$C\n", Until(terminals=1, text=BANNER_END))
    pair.status()
    pair.check()


def test_startup_lines(pair: Pair) -> None:
    """``$N0=`` / ``$N1=`` store lines run at every reset; ``$N`` lists them."""
    pair.lines("$N0=G91", "$N1=M3 S100", "$N")
    pair.reset()
    pair.send("$G\n")
    pair.status()
    pair.lines("$N0=", "$N1=", "$N")
    pair.check()


SETTINGS: dict[str, list[str]] = {
    "stepper": ["$0=20", "$1=25", "$2=3", "$3=7", "$4=1", "$5=1", "$6=1"],
    "report": ["$10=3", "$11=0.020", "$12=0.005", "$13=1"],
    "limits": [
        "$20=0",
        "$21=0",
        "$22=0",
        "$23=3",
        "$24=900",
        "$25=1000.5",
        "$26=100",
        "$27=5",
        "$28=1",
    ],
    "steps": [f"$10{i}=12.5" for i in range(7)],
    "rates": [f"$11{i}=1000" for i in range(7)],
    "accels": [f"$12{i}=20.25" for i in range(7)],
    "max-travel": [f"$13{i}=100" for i in range(7)],
    "min-travel": [f"$14{i}=100" for i in range(7)],
    "reset-distance": [f"$15{i}=10" for i in range(7)],
    "invalid": [
        "$0=-1",
        "$7=1",
        "$29=1",
        "$99=1",
        "$107=1",
        "$157=1",
        "$1000=1",
        "$10=abc",
        "$10=",
        "$=1",
        "$11=1e2",
        "$20=2",
        "$0=3.7",
    ],
}


@pytest.mark.parametrize("group", SETTINGS)
def test_setting_writes(pair: Pair, group: str) -> None:
    """Every setting written (each answered), then ``$$`` shows what was stored."""
    pair.lines(*SETTINGS[group])
    pair.send("$$\n")
    pair.check()


def test_status_during_reboot(pair: Pair) -> None:
    """A ``?`` that arrives while the banner after ``%`` is printed is answered first when the
    boot ends, before the lines that arrived with it; one that arrives 100 us after the ``%``
    is lost (the reset re-initialises the realtime flags), the empty lines after it are not."""
    pair.lines("M50")
    pair.send(b"%$I\nG4 P0\n?", Until(text=BANNER_END, terminals=2, statuses=1))
    pair.send(b"%?\n\n\n?", Until(text=BANNER_END, terminals=3, statuses=1, quiet=0.2))
    pair.status()
    pair.check()


MERGE_PROBES = {
    "0": b"??",
    **{str(gap): b"?" + b" " * gap + b"?" for gap in (40, 110, 140, 200)},
    **{f"reset-{gap}": b"%" + b" " * 10 + b"?" + b" " * gap + b"?" for gap in (300, 600)},
}


@pytest.mark.parametrize("probe", MERGE_PROBES.values(), ids=MERGE_PROBES.keys())
def test_status_requests_merge_while_a_report_is_printed(tmp_path: Path, probe: bytes) -> None:
    """Two ``?`` some filtered bytes apart (about 0.1 ms each): one that arrives while the first
    report is still being printed gets no report of its own (oracle: up to 12.5 ms for a
    175-byte report; after a ``%`` the banner is printed first: about 45 ms). Ours merges
    with its link paced at the arm's 115200 baud in real time
    (at other time scales the paced wire stretches or shrinks the gap in simulated time)."""
    both = Pair.spawn(tmp_path, our_flags=("--baud", "115200"), time_scale=1.0).connect()
    try:
        both.send(probe, Until(statuses=1, quiet=0.3))
        both.check()
    finally:
        both.close()
