"""Bad input to the emulator process (issue 7, section 4): it never dies and always answers.

Hypothesis drives random G-code built from a grammar (words of the letters the firmware knows,
with numbers good and bad, ``$`` commands, ``$N=v`` settings, comments, CR/LF mixes, realtime
bytes), random settings, random bytes, and floods beyond the 128-byte receive buffer, into ONE
``mirobot-emulator`` process per profile over its pty with plain pyserial (not our
client). Every example starts from a known state: ``%`` (banner), a unique marker line, then
``$RST=*`` (settings, startup lines and build info back to the defaults; banner).

After each example:

* the process is alive and has logged no internal error (no traceback on its stderr);
* every output line has one of the firmware's reply shapes (an independent classifier below);
* while the input respects the receive buffer (at most 128 bytes unanswered: character counting,
  ``$`` lines sent alone), every line end got exactly one final reply (``ok`` or an error), and
  a line longer than 79 bytes after filtering one more per overflow (the firmware reports
  ``Line overflow`` at the 80th byte, drops it, and parses what follows as a new line);
* a ``?`` afterwards returns a well-formed status line.

Each test runs a few dozen examples (fast enough for every suite run; ``CI`` set: the
derandomised hypothesis profile); ``MIROBOT_FUZZ_SCALE=10`` runs ten times as many.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import re
import selectors
import subprocess
import sys
import tempfile
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest
import serial
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

# the emulator as a process and its links: run on the link lanes (MIROBOT_TEST_LINK=pty|tcp)
pytestmark = [pytest.mark.timeout(120), pytest.mark.emulator_process]

RX_BUFFER = 128
MAX_LINE = 79  # bytes of a line after filtering; the 80th overflows
REALTIME = frozenset(b"?!~%@")  # taken out of the stream wherever they are
REPLY_TIMEOUT = 5.0  # seconds without the expected output: the emulator failed to answer
HOLD_NUDGE = 0.1  # seconds without output while a reply is owed: send "~" (M0 pauses until it),
# again every HOLD_NUDGE while silent (a "~" that came before the pause is not one after it)

# ---- an independent classifier of the firmware's output lines ------------------------------------

_NUM = r"-?\d+\.\d{3}"
STRICT_STATUS = re.compile(
    rf"<(Idle|Alarm),Angle\(ABCDXYZ\):{_NUM}(?:,{_NUM}){{6}},"
    rf"Cartesian coordinate\(XYZ RxRyRz\):{_NUM}(?:,{_NUM}){{5}},"
    r"Pump PWM:\d+,Valve PWM:\d+,Motion_MODE:[01]>"
)
# Any status report, whatever the $10 mask selects: state, then fields of numbers and labels.
STATUS = re.compile(r"<(Idle|Run|Hold|Home|Alarm|Check|Door)(,[A-Za-z_ ()]+:?[-0-9.,:]*)*>")
FINAL = re.compile(
    r"ok|error: [^\r\n]+|Error, E1\d\d,[^\r\n]+|in homeing moving\.\.\.ok|"
    r"Info, in homing moving\.\.\.ok|"
    # the firmware prints this refusal without a line end: its ``ok`` follows on the same line
    r"GOAL OUT OF WORKSPACE, THERE IS NO VAILD VALUS FOR  THETA3!ok|"
    # the 2024 family (docs/2024-profile.md): GRBL's status errors "Info,E100..E110" and the
    # g-code errors "Error,E111..E117" / "Error,E000,Invalid gcode ID:<n>" end the line alone
    r"Info,E1(0\d|10),[^\r\n]+|Error,E(11[1-7]|000),[^\r\n]+"
)
OTHER = re.compile(
    "|".join(
        [
            r"",  # empty lines: before refusals, in the banner, before "Free memory"
            r"([01]{8})?ALARM: (Hard limit|Soft limit|Abort during cycle|Probe fail|Homing fail)",
            r"\[[^\r\n]*\]",  # feedback: $G, $#, $I, [Pgm End], [Caution: Unlocked] ...
            r"(Info, ?)?(M50: Unlock each axis\.|M20: Cartesian mode start\.|"
            r"M21: Angle mode start\.)",
            r"Locked status of each axis!",
            r"Soft limit triggered:[XYZABCD]",
            r"GOAL OUT OF WORKSPACE, THERE IS NO VAILD VALUS FOR  THETA3!",
            r"There is one angle out of limit!!!",
            r"Free memory: \d+",
            r"\$\d+=-?\d+(\.\d+)? \([^()\r\n]+\)",  # $$ dump
            r"\$N\d+=[^\r\n]*",  # $N: startup lines
            r"(\$[$#GINCXH]?|\$x=value|\$Nx=line|~|!|\?|ctrl-x) \([a-zA-Z# ]+\)",  # $ help
            # the banner
            r"Grbl 0\.9j \['\$' for help\]",
            r"Qinnew Robot \d{8}(_\d)? based on Grbl 0\.9j \['\$' for help\]",
            r"(D1|A1|A2|A3|D4|L|X offset|Y offset|Z offset|X|Y|Z|RX|RY|RZ): -?\d+",
            r"Initialized Cartesian coordinates and rotation: ",
            r"Using reset pos!",
            # the 2024 family: its one-line banner, alarms and refusals (an ok follows those),
            # the homing reply's first line
            r"WLKATA Robot started successfully\.Firmware version:Mirobot,\d{8}",
            r"Error,A10[1356],(Hard limit:[A-Z]?|Abort during cycle|Homing fail|"
            r"Locked status of each axis)",
            r"Error,A102,Soft limit:[XYZABCD]",
            r"Error,E118,The given location is outside the workspace\.",
            r"Error,E119,The angle of an axis is out of range\.",
            r"Info,in homing moving\.\.\.",
            # after a reset, each stored startup line (``$N0=G0X1``, ``$N1=M3S5`` from
            # DOLLAR_COMMANDS) printed with its reply glued on, or before a message line
            r"(G0X1|M3S5)(ok|error: [^\r\n]+)?",
        ]
    )
)
BANNER_END = "Using reset pos!"
BANNER_2024 = re.compile(r"WLKATA Robot started successfully\.Firmware version:\S+")
"""The 2024 family's banner: this one line (docs/2024-profile.md)."""


def is_banner_end(line: str) -> bool:
    """The last line of a banner (classic and 2021: ``Using reset pos!``; 2024: its only one)."""
    return line == BANNER_END or BANNER_2024.fullmatch(line) is not None


def is_final(line: str) -> bool:
    """``ok`` or an error: the one final reply of a line."""
    return FINAL.fullmatch(line) is not None


def well_formed(line: str) -> bool:
    return (
        bool(FINAL.fullmatch(line) or STATUS.fullmatch(line) or OTHER.fullmatch(line))
        and "\r" not in line
    )


def test_the_classifier_knows_the_shapes() -> None:
    good = [
        "ok",
        "error: Unsupported command",
        "Error, E120,Unsupported command",
        "in homeing moving...ok",
        "Info, in homing moving...ok",
        "GOAL OUT OF WORKSPACE, THERE IS NO VAILD VALUS FOR  THETA3!ok",
        "ALARM: Hard limit",
        "[Reset to continue]",
        "['$H'|'$X' to unlock]",
        "[G0 G54 G17 G21 G90 G94 M0 M5 M9 T0 F200. S0.]",
        "Info, M50: Unlock each axis.",
        "M21: Angle mode start.",
        "Soft limit triggered:X",
        "$110=1800.000 (a-axis maximum rate, deg/min)",
        "$N0=G0X1",
        "$$ (view Grbl settings)",
        "ctrl-x (reset Grbl)",
        "<Idle,Angle(ABCDXYZ):0.000,0.000,0.000,0.000,0.000,0.000,0.000,"
        "Cartesian coordinate(XYZ RxRyRz):198.670,0.000,230.720,0.000,0.000,0.000,"
        "Pump PWM:0,Valve PWM:0,Motion_MODE:0>",
        "<Idle>",
        "Qinnew Robot 20191228_2 based on Grbl 0.9j ['$' for help]",
        "L: -25",
        "G0X1ok",
        "Initialized Cartesian coordinates and rotation: ",
        "",
    ]
    bad = ["ok ok", "okk", "error:", "<Idle", "Idle>", "ALARM: nope", "Soft limit triggered:Q"]
    assert all(well_formed(line) for line in good), [g for g in good if not well_formed(g)]
    assert not any(well_formed(line) for line in bad), [b for b in bad if well_formed(b)]
    assert [is_final(line) for line in good[:6]] == [True] * 6
    assert not is_final("G0X1ok")  # a startup line's reply: owed to no line sent
    assert STRICT_STATUS.fullmatch(good[17]) and not STRICT_STATUS.fullmatch(good[18])
    family_2024 = [  # docs/2024-profile.md
        ("WLKATA Robot started successfully.Firmware version:Mirobot,20240820", False),
        ("Info,E100,Expected command letter", True),
        ("Error,E112,Unsupported command", True),
        ("Error,E000,Invalid gcode ID:24", True),
        ("Error,A101,Hard limit:X", False),
        ("Error,A106,Locked status of each axis", False),
        ("Error,E118,The given location is outside the workspace.", False),
        ("Info,M50: Unlock each axis.", False),
        ("Info,in homing moving...", False),
    ]
    assert all(well_formed(line) and is_final(line) == final for line, final in family_2024)
    assert is_banner_end(family_2024[0][0])


def test_the_finals_counter_knows_the_line_discipline() -> None:
    def owed(*pieces: bytes) -> int:
        counter = FinalsOwed()
        return sum(counter.feed(piece) for piece in pieces)

    assert owed(b"G0 X1\n", b"\r\n", b"") == 3
    assert owed(b"X" * 79 + b"\n") == 1
    assert owed(b"X" * 80 + b"\n") == 2  # the overflow, then the (empty) tail's reply
    assert owed(b"X" * 160 + b"\n") == 3
    assert owed(b"X" * 40, b" ?~(" + b"Y" * 50 + b")" + b"X" * 39 + b"\n") == 1
    assert owed(b"X" * 79 + b";" + b"Y" * 90 + b"\r") == 1
    assert owed(b"X" * 60, b"X" * 30) == 1  # the overflow comes before any line end


# ---- the emulator process and its port --------------------------------------------------------


class RawEmulator:
    """A ``mirobot-emulator`` process (time scale 0) and its port opened with pyserial."""

    def __init__(self, profile: str, *extra_args: str) -> None:
        self.profile = profile
        self._stderr = tempfile.TemporaryFile()  # noqa: SIM115 - closed by close()
        self.proc = subprocess.Popen(
            [
                *(sys.executable, "-m", "mirobot_emulator"),
                *("--firmware", profile, "--time-scale", "0", *extra_args),
            ],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=self._stderr,
        )
        assert self.proc.stdout is not None
        path = self.proc.stdout.readline().decode().strip()
        assert path.startswith("/dev/"), path
        self.port = serial.Serial(path, 115200, timeout=0)
        self._selector = selectors.DefaultSelector()
        self._selector.register(self.port.fileno(), selectors.EVENT_READ)
        self._buffer = b""
        self._markers = itertools.count()
        self.lines: list[str] = []  # every line read in the current example (for messages)

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.port.close()
        self._selector.close()
        if self.proc.poll() is None:
            self.proc.terminate()
        try:
            self.proc.wait(5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        if self.proc.stdout is not None:
            self.proc.stdout.close()
        self._stderr.close()

    def stderr(self) -> str:
        self._stderr.seek(0)
        return self._stderr.read().decode(errors="replace")

    def write(self, data: bytes) -> None:
        self.port.write(data)

    def read_line(self, timeout: float) -> str | None:
        """The next output line (without ``\\r\\n``), checked well-formed; None on timeout."""
        deadline = time.monotonic() + timeout
        while b"\r\n" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0 or not self._selector.select(left):
                if time.monotonic() >= deadline:
                    return None
                continue
            self._buffer += os.read(self.port.fileno(), 65536)
        raw, self._buffer = self._buffer.split(b"\r\n", 1)
        line = raw.decode("latin-1")
        self.lines.append(line)
        assert well_formed(line), f"malformed output line {line!r}; output so far {self.lines}"
        return line

    def read_until(self, predicate: Callable[[str], bool], what: str) -> str:
        while True:
            line = self.read_line(REPLY_TIMEOUT)
            assert line is not None, f"no {what} within {REPLY_TIMEOUT} s; output {self.lines}"
            if predicate(line):
                return line

    def restore(self) -> None:
        """Back to power-on defaults: ``%``, a unique marker, ``$RST=*``; check the status."""
        self.write(b"%")
        self.read_until(is_banner_end, "banner after %")
        marker = f"SYNC{next(self._markers)}"
        self.write(f"$I={marker}\n$I\n".encode())
        # (the classic build-info line continues after the user's text: "[...:SYNC0--...]")
        self.read_until(lambda line: line.startswith("[") and marker in line, "the marker line")
        self.read_until(is_final, "the marker's ok")
        self.write(b"$RST=*\n")
        self.read_until(is_banner_end, "banner after $RST=*")
        self.write(b"?")
        status = self.read_until(lambda line: line.startswith("<"), "a status line")
        assert STRICT_STATUS.fullmatch(status), status
        self.lines.clear()

    def check_alive(self) -> None:
        assert self.proc.poll() is None, f"the emulator died: {self.stderr()}"
        err = self.stderr()
        assert "Traceback" not in err and "internal error" not in err, err

    def status(self) -> str:
        """Write ``?`` and return the status line (after any output still owed)."""
        self.write(b"?")
        return self.read_until(lambda line: line.startswith("<"), "a status line after '?'")


@pytest.fixture(scope="module", params=["2021", "classic", "2024"])
def emulator(request: pytest.FixtureRequest) -> Iterator[RawEmulator]:
    """One emulator process per profile for the module's tests (all their examples): every
    example starts with :meth:`RawEmulator.restore` (reset, settings back to the defaults)."""
    emu = RawEmulator(str(request.param))
    try:
        yield emu
        emu.check_alive()
    finally:
        emu.close()


# ---- sending with character counting ------------------------------------------------------------


class FinalsOwed:
    """Counts the final replies owed for bytes sent, from the line discipline (PROTOCOL.md 2):
    one per line end, plus one per overflow. The state (the length of the line so far, inside
    a comment or not) carries from one :meth:`feed` to the next, as in the firmware."""

    def __init__(self) -> None:
        self._length = 0
        self._comment = b""  # b"(" or b";" while inside a comment

    def feed(self, data: bytes) -> int:
        owed = 0
        for byte in data:
            if byte in REALTIME:
                continue
            if byte in b"\r\n":
                owed += 1
                self._length, self._comment = 0, b""
            elif self._comment:
                if self._comment == b"(" and byte == ord(")"):
                    self._comment = b""
            elif byte <= 0x20 or byte == ord("/"):
                continue  # whitespace, control bytes, block delete: dropped
            elif byte in b"(;":
                self._comment = bytes([byte])
            elif self._length >= MAX_LINE:
                owed += 1  # "Line overflow"; this byte is dropped, a new line begins
                self._length, self._comment = 0, b""
            else:
                self._length += 1
        return owed


def finals_owed(chunks: list[Chunk]) -> int:
    counter = FinalsOwed()
    return sum(counter.feed(chunk.data) for chunk in chunks)


@dataclass
class Chunk:
    """Bytes that end with one or more line ends; ``alone``: a ``$`` line, sent with nothing
    else in flight and nothing after it until answered ($C and $RST reset the firmware)."""

    data: bytes
    alone: bool = False


def exchange(emu: RawEmulator, chunks: list[Chunk], *, may_reset: bool = False) -> int | None:
    """Send ``chunks`` within the receive buffer; check one final reply per line end.

    Returns the number of final replies, or None if the firmware reset (a banner) while lines
    were owed replies, which ``may_reset`` allows (a reset discards the input not yet read; only
    random bytes can hide a ``$C`` or ``$RST`` in a chunk). Fails if a reply is missing for
    REPLY_TIMEOUT seconds.
    """
    in_flight: deque[list[int]] = deque()  # [finals still owed, bytes]
    owed = FinalsOwed()
    alone = False
    bytes_in_flight = 0
    finals = 0
    queue = deque(chunks)
    silent_since = time.monotonic()
    nudged_at = 0.0
    # A "$C" leaving check mode or a "$RST=" prints its ok, then resets (banner): input sent
    # after that ok arrives after the reset and is not lost.
    banner_explained = False
    while queue or in_flight:
        while queue and not alone:
            chunk = queue[0]
            assert len(chunk.data) <= RX_BUFFER
            if chunk.alone and in_flight:
                break
            if bytes_in_flight + len(chunk.data) > RX_BUFFER:
                break
            queue.popleft()
            emu.write(chunk.data)
            finals_of_chunk = owed.feed(chunk.data)
            if finals_of_chunk:
                in_flight.append([finals_of_chunk, len(chunk.data)])
                bytes_in_flight += len(chunk.data)
                alone = chunk.alone
        if not in_flight:
            continue
        line = emu.read_line(0.05)
        if line is None:
            waited = time.monotonic() - silent_since
            if time.monotonic() - max(silent_since, nudged_at) > HOLD_NUDGE:
                emu.write(b"~")  # an M0 (program pause) waits for a cycle start
                nudged_at = time.monotonic()
            assert waited < REPLY_TIMEOUT, (
                f"no reply for {REPLY_TIMEOUT} s; {len(in_flight)} chunk(s) owed; "
                f"output {emu.lines}"
            )
            continue
        silent_since = time.monotonic()
        if is_banner_end(line) and not banner_explained:
            assert may_reset or not in_flight, f"a reset discarded input; output {emu.lines}"
            if in_flight:
                _flush(emu, queue)
                return None
        if not is_final(line):
            continue
        banner_explained = alone
        finals += 1
        assert in_flight, f"a final reply {line!r} owed to no line; output {emu.lines}"
        in_flight[0][0] -= 1
        if in_flight[0][0] == 0:
            _, size = in_flight.popleft()
            bytes_in_flight -= size
            alone = False
    return finals


def _flush(emu: RawEmulator, queue: deque[Chunk]) -> None:
    for chunk in queue:
        emu.write(chunk.data)


def settle(emu: RawEmulator, expected_finals: int, finals: int | None) -> str:
    """After an exchange: ``?`` gives a status line, and no extra final reply came before it."""
    status = emu.status()
    extra = [line for line in emu.lines if is_final(line)]
    assert len(extra) == expected_finals == finals, (len(extra), expected_finals, emu.lines)
    return status


# ---- strategies ---------------------------------------------------------------------------------

LETTERS = "GMXYZABCDFPSER"
DANGEROUS_SETTINGS = {20, 21, 22, *range(130, 147)}  # could let a move reach a limit switch

numbers = st.one_of(
    st.integers(-400, 400).map(str),
    st.integers(0, 200).map(str),
    st.floats(-1e4, 1e4, allow_nan=False).map(lambda f: f"{f:.3f}"),
    st.floats(-1e9, 1e9, allow_nan=False, allow_infinity=False).map(repr),
    st.sampled_from(["", "-", ".", "+", "1.2.3", "+5", "1e3", "--1", "0.0000001", "99999999999"]),
)
words = st.builds(
    lambda letter, number, lower: (letter.lower() if lower else letter) + number,
    st.sampled_from(LETTERS),
    numbers,
    st.booleans(),
)
comment_text = st.text(
    st.characters(min_codepoint=0x20, max_codepoint=0x7E, exclude_characters="()%!\r\n"),
    max_size=12,
)
comments = st.one_of(comment_text.map(lambda t: f"({t})"), comment_text.map(lambda t: f";{t}"))
line_ends = st.sampled_from(["\n", "\r", "\r\n", "\n\r", "\n\n"])
realtime = st.sampled_from(["?", "~"])  # "!" and "%" would stall or discard lines: flood test


def setting_line(*, safe: bool) -> st.SearchStrategy[str]:
    numbers_of_settings = st.integers(0, 255)
    if safe:
        numbers_of_settings = numbers_of_settings.filter(lambda n: n not in DANGEROUS_SETTINGS)
    values = st.one_of(
        st.integers(-100_000, 100_000).map(str),
        st.floats(-1e6, 1e6, allow_nan=False).map(lambda f: f"{f:.4f}"),
        st.sampled_from(["", "x", "1.2.3", "-0", "255", "65536", "0.5"]),
    )
    return st.builds(lambda n, v: f"${n}={v}", numbers_of_settings, values)


DOLLAR_COMMANDS = [
    "$",
    "$$",
    "$#",
    "$G",
    "$I",
    "$N",
    "$X",
    "$H",
    "$HH",
    "$H0",
    "$H3",
    "$H7",
    "$HE",
    "$M",
    "$C",
    "$N0=G0X1",
    "$N1=M3S5",
    "$N9=X",
    "$I=FUZZ",
    "$Q",
    "$RST=#",
    "$RST=?",
    "$$$",
    "$X1",
]


@st.composite
def decorate(draw: st.DrawFn, body: str, *, one_end: bool = False) -> str:
    """Random comments and realtime bytes around ``body``, then one or two line ends (one for
    ``$`` lines: a reset by ``$C`` or ``$RST=`` would discard the second)."""
    text = body
    if draw(st.booleans()):
        text = draw(comments) + text
    if draw(st.booleans()):
        text += draw(comments)
    for _ in range(draw(st.integers(0, 2))):
        at = draw(st.integers(0, len(text)))
        text = text[:at] + draw(realtime) + text[at:]
    return text[: RX_BUFFER - 2] + draw(st.sampled_from(["\n", "\r"]) if one_end else line_ends)


@st.composite
def gcode_chunks(draw: st.DrawFn) -> list[Chunk]:
    """Random valid-looking G-code, ``$`` commands and safe settings, one line a chunk."""
    chunks: list[Chunk] = []
    if draw(st.booleans()):  # unlocked and out of Alarm: moves are executed (instantly)
        chunks += [Chunk(b"$X\n", alone=True), Chunk(b"M50\n")]
    for _ in range(draw(st.integers(1, 12))):
        kind = draw(st.sampled_from(["gcode", "gcode", "gcode", "dollar", "setting", "empty"]))
        if kind == "gcode":
            separator = draw(st.sampled_from([" ", "", "  "]))
            body = separator.join(draw(st.lists(words, min_size=1, max_size=9)))
        elif kind == "dollar":
            body = draw(st.sampled_from(DOLLAR_COMMANDS))
        elif kind == "setting":
            body = draw(setting_line(safe=True))
        else:
            body = ""
        alone = kind in ("dollar", "setting")
        line = draw(decorate(body, one_end=alone))
        chunks.append(Chunk(line.encode("latin-1"), alone=alone))
    return chunks


FUZZ_SCALE = float(os.environ.get("MIROBOT_FUZZ_SCALE", "1"))
"""Examples per test are ``FUZZ_SCALE`` times the suite's few (e.g. 10 for a thorough run);
the counts are small so that the suite stays fast, CI's hypothesis profile derandomises them."""


def fuzz(max_examples: int) -> settings:
    """One process serves every example of a test: the function-scoped fixture is intended."""
    return settings(
        max_examples=max(1, round(max_examples * FUZZ_SCALE)),
        deadline=None,
        suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    )


# ---- the tests ----------------------------------------------------------------------------------


@fuzz(30)
@given(chunks=gcode_chunks())
def test_random_gcode_gets_one_well_formed_reply_per_line(
    emulator: RawEmulator, chunks: list[Chunk]
) -> None:
    emulator.restore()
    expected = finals_owed(chunks)
    finals = exchange(emulator, chunks)
    status = settle(emulator, expected, finals)
    assert STATUS.fullmatch(status), status
    emulator.check_alive()


@fuzz(20)
@given(
    lines=st.lists(
        st.one_of(setting_line(safe=False), st.sampled_from(["$$", "$#", "$G", "$I", "$N"])),
        min_size=1,
        max_size=10,
    ),
)
def test_random_settings_are_answered_and_the_status_survives(
    emulator: RawEmulator, lines: list[str]
) -> None:
    emulator.restore()
    chunks = [Chunk(line.encode() + b"\n", alone=True) for line in lines]
    finals = exchange(emulator, chunks)
    status = settle(emulator, len(chunks), finals)
    assert STATUS.fullmatch(status), status
    # with the settings as they are now, a dump, a reset (banner) and a status still work
    emulator.write(b"$$\n")
    emulator.read_until(is_final, "the $$ dump's ok")
    emulator.write(b"%")
    emulator.read_until(is_banner_end, "banner after %")
    assert STATUS.fullmatch(emulator.status())
    emulator.check_alive()


@fuzz(40)
@given(data=st.binary(max_size=RX_BUFFER).map(lambda b: b.replace(b"%", b"").replace(b"!", b"")))
def test_random_bytes_within_the_buffer_get_one_reply_per_line(
    emulator: RawEmulator, data: bytes
) -> None:
    emulator.restore()
    chunk = Chunk(data)
    finals = exchange(emulator, [chunk], may_reset=True)
    # (None: a "$C" leaving check mode, or "$RST=", reset the firmware)
    status = emulator.status() if finals is None else settle(emulator, finals_owed([chunk]), finals)
    assert STATUS.fullmatch(status), status
    emulator.check_alive()


@fuzz(12)
@given(
    data=st.one_of(
        st.binary(min_size=RX_BUFFER + 1, max_size=4096),
        st.lists(gcode_chunks(), min_size=3, max_size=8).map(
            lambda lists: b"".join(chunk.data for chunks in lists for chunk in chunks)
        ),
        st.builds(
            lambda line, n, rt: (line + rt) * n,
            st.binary(max_size=100),
            st.integers(2, 60),
            st.sampled_from([b"", b"!", b"%", b"?", b"~", b"\n", b"\r\n"]),
        ),
    ),
    pieces=st.integers(1, 4),
)
def test_a_flood_beyond_the_buffer_is_survived(
    emulator: RawEmulator, data: bytes, pieces: int
) -> None:
    """Far more than 128 bytes at once (bytes are lost, as on the arm): only survival matters."""
    emulator.restore()
    size = max(1, -(-len(data) // pieces))
    for start in range(0, len(data), size):
        emulator.write(data[start : start + size])
    emulator.write(b"~")  # in case the flood held the arm (a feed hold or M0)
    emulator.check_alive()
    emulator.restore()  # drains the output (checking every line), resets, reads a strict status
    emulator.check_alive()
