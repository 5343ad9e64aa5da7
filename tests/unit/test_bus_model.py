"""The pure RS485 bus model (mirobot_emulator.bus): addressing, the controller's own commands,
files, GPIO, relay of the arm's replies, bus timing, and the Firmware-like clock interface."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirobot_emulator.bus import Bus, BusOptions
from mirobot_emulator.firmware import Firmware


def ask(bus: Bus, line: bytes, wait: float = 0.5) -> bytes:
    """Write ``line``, run the clock ``wait`` seconds, return what reached the host."""
    bus.receive(line)
    bus.advance(wait)
    return bus.read_output()


def lines_of(data: bytes) -> list[str]:
    return data.decode("ascii").split("\r\n")[:-1]


def settle(bus: Bus) -> bytes:
    bus.advance(math.inf)
    return bus.read_output()


# ---- addressing ---------------------------------------------------------------------------------


def test_power_on_is_silent_and_quiet() -> None:
    bus = Bus(3)
    assert bus.read_output() == b""
    assert bus.next_deadline() is None
    assert [node.address for node in bus.nodes] == [1, 2, 3]


@pytest.mark.parametrize("prefix", [b"@2", b"@02", b"@002"])
def test_padded_and_unpadded_addresses_are_the_same(prefix: bytes) -> None:
    bus = Bus(3)
    assert lines_of(ask(bus, prefix + b"O140?\r\n")) == ["02"]


def test_only_the_addressed_node_answers() -> None:
    bus = Bus(3)
    bus.controller(2).bluetooth_name = "two"
    assert lines_of(ask(bus, b"@2o150?\r\n")) == ["two"]
    assert ask(bus, b"@4o150?\r\n") == b""  # nobody at 4
    assert ask(bus, b"o150?\r\n") == b""  # no prefix: ignored by default
    assert ask(bus, b"@0o150?\r\n") == b""  # broadcast: ignored by default
    assert bus.lines_dropped == 2


def test_an_unprefixed_node_answers_bare_lines() -> None:
    bus = Bus(2, options=BusOptions(unprefixed=2))
    assert lines_of(ask(bus, b"o140?\r\n")) == ["02"]


def test_a_broadcast_is_executed_silently_when_enabled() -> None:
    bus = Bus(3, options=BusOptions(broadcast="execute"))
    assert ask(bus, b"@0o150=all\r\n") == b""
    assert {node.bluetooth_name for node in bus.nodes} == {"all"}
    assert ask(bus, b"@0M50\r\n") == b""  # the arms' replies are not relayed either
    assert all(not node.arm.locked for node in bus.nodes)


def test_address_change_takes_effect_after_its_ok() -> None:
    bus = Bus(2)
    assert lines_of(ask(bus, b"@1o14007\r\n")) == ["ok"]
    assert ask(bus, b"@1o140?\r\n") == b""
    assert lines_of(ask(bus, b"@7o140?\r\n")) == ["07"]
    assert lines_of(ask(bus, b"@7o14000\r\n")) == ["error"]


def test_a_node_at_another_baud_is_deaf_and_mute() -> None:
    bus = Bus(2)
    assert lines_of(ask(bus, b"@2o141=4\r\n")) == ["ok"]
    assert bus.controller(2).baud == 115200
    assert ask(bus, b"@2o140?\r\n") == b""
    assert lines_of(ask(bus, b"@1o141?\r\n")) == ["2"]


# ---- relay to the arm ---------------------------------------------------------------------------

SAFE_LINES = [
    b"?",
    b"$X",
    b"M50",
    b"G90",
    b"G91",
    b"M21 G90 G00 X5",
    b"M21 G91 G01 X-2 F500",
    b"M20 G90 G01 X190 Y0 Z220 F1000",
    b"M3 S1000",
    b"M3 S0",
    b"G4 P0.1",
    b"$$",
    b"$I",
    b"G999",
    b"!",
    b"~",
]


@settings(max_examples=40, deadline=None)
@given(
    profile=st.sampled_from(["2021", "classic"]),
    script=st.lists(
        st.tuples(st.sampled_from(SAFE_LINES), st.sampled_from([b"\r\n", b"\n"])), max_size=8
    ),
)
def test_forwarded_lines_get_exactly_the_arms_replies(
    profile: str, script: list[tuple[bytes, bytes]]
) -> None:
    bus = Bus(2, profile, homing_seconds=0.5)
    arm = Firmware(profile, homing_seconds=0.5)
    arm.read_output()
    for line, end in script:
        bus.receive(b"@2" + line + end)
        arm.receive(line + end)
        arm.advance(math.inf)
        expected = arm.read_output()
        assert settle(bus) == expected, line
    assert bus.nodes[1].arm.joints == arm.joints
    assert bus.nodes[0].arm.read_output() == b""  # node 1 heard nothing
    assert bus.collisions == 0


def test_realtime_reset_through_the_controller_relays_the_banner() -> None:
    bus = Bus(1)
    out = lines_of(ask(bus, b"@1%\r\n"))
    assert "Using reset pos!" in out


def test_a_hard_limit_alarm_is_relayed() -> None:
    bus = Bus(2)
    ask(bus, b"@2M50\r\n")
    bus.trigger_hard_limit(address=2)
    assert any("ALARM: Hard limit" in line for line in lines_of(settle(bus)))


# ---- the controller's own commands --------------------------------------------------------------


def test_version_readings() -> None:
    assert lines_of(ask(Bus(1), b"@1$V\r\n")) == ["EXbox 20210410", "Mirobot 20210516", "ok"]
    classic = Bus(2, ["2021", "classic"])
    assert lines_of(ask(classic, b"@2$v\r\n"))[1] == "Mirobot 20191228_2"
    assert lines_of(ask(Bus(1, options=BusOptions(version="exbox")), b"@1$V\r\n")) == [
        "EXbox 20210410",
        "ok",
    ]
    forwarded = lines_of(ask(Bus(1, options=BusOptions(version="forward")), b"@1$V\r\n"))
    assert "Bad number format" in forwarded[0]  # the arm's own answer: it has no $V
    assert lines_of(ask(Bus(1), b"@1o101\r\n")) == ["20210410"]


@pytest.mark.parametrize(
    ("style", "expected"), [("word", "State,Alarm,2"), ("number", "2")], ids=["word", "number"]
)
def test_o103_state_readings(style: str, expected: str) -> None:
    bus = Bus(1, options=BusOptions(o103=style))
    assert lines_of(ask(bus, b"@1O103\r\n")) == [expected]
    ask(bus, b"@1M50\r\n")
    idle = lines_of(ask(bus, b"@1O103\r\n"))
    assert idle == (["State,Idle,1"] if style == "word" else ["1"])


def test_classic_power_on_lock_is_state_2() -> None:
    bus = Bus(1, "classic")
    assert lines_of(ask(bus, b"@1O103\r\n")) == ["State,Idle,2"]


@pytest.mark.parametrize("command", [b"@1o105=8\r\n", b"@1O105\r\n", b"@1o105=9\r\n"])
def test_o105_homes_the_arm_and_answers_ok_at_once(command: bytes) -> None:
    bus = Bus(1, homing_seconds=1.0)
    assert lines_of(ask(bus, command, wait=0.1)) == ["ok"]
    assert lines_of(ask(bus, b"@1O103\r\n", wait=0.1)) == ["State,Home,3"]
    assert settle(bus) == b""  # the arm's own homing reply is consumed
    assert lines_of(ask(bus, b"@1O103\r\n")) == ["State,Idle,1"]
    assert bus.nodes[0].arm.joints[:6] == (0.0,) * 6


def test_o105_relay_reading_and_repeat_reading() -> None:
    relayed = Bus(1, homing_seconds=0.1, options=BusOptions(o105_reply="relay"))
    out = ask(relayed, b"@1o105=8\r\n", wait=0.01) + settle(relayed)
    assert lines_of(out)[0] == "Info, in homing moving...ok"
    repeat = Bus(1, options=BusOptions(o105="repeat"))
    assert lines_of(ask(repeat, b"@1o105=1\r\n")) == ["ok"]
    assert lines_of(ask(repeat, b"@1o105?\r\n")) == ["1"]
    assert lines_of(ask(repeat, b"@1o105=8\r\n")) == ["error"]


def test_bad_and_unknown_commands_answer_the_error_text() -> None:
    bus = Bus(1, options=BusOptions(error_text="Error: bad command"))
    assert lines_of(ask(bus, b"@1o999\r\n")) == ["Error: bad command"]
    assert lines_of(ask(bus, b"@1o105=11\r\n")) == ["Error: bad command"]
    assert lines_of(ask(bus, b"@1o151=12\r\n")) == ["Error: bad command"]


def test_settings_with_and_without_equals_and_trailing_padding() -> None:
    bus = Bus(1)
    assert lines_of(ask(bus, b"@1o150myrobot\r\n")) == ["ok"]
    assert lines_of(ask(bus, b"@1O150?\r\n")) == ["myrobot"]
    padded = b"@1o151=1234" + b" " * 19 + b"\r\n"  # micro:bit pads lines to 32 bytes
    assert lines_of(ask(bus, padded)) == ["ok"]
    assert lines_of(ask(bus, b"@1o151?\r\n")) == ["1234"]
    always = Bus(1, options=BusOptions(query_ok="always"))
    assert lines_of(ask(always, b"@1o151?\r\n")) == ["7676", "ok"]


# ---- files --------------------------------------------------------------------------------------


def test_run_the_preinstalled_test_program() -> None:
    bus = Bus(2)
    ask(bus, b"@1M50\r\n")
    assert lines_of(ask(bus, b"@1o110\r\n")) == ['["test"]']
    assert lines_of(ask(bus, b"@1o111test\r\n", wait=0.01)) == ["ok"]
    assert bus.nodes[0].running_file == "test"  # still feeding the arm (it takes ~20 ms)
    assert lines_of(ask(bus, b"@1O103\r\n", wait=0.05)) == ["State,Run,5"]
    assert settle(bus) == b""  # the program's replies are not relayed
    assert lines_of(ask(bus, b"@1O103\r\n")) == ["State,Idle,1"]
    assert bus.nodes[0].arm.joints[:6] == (0.0,) * 6
    assert bus.nodes[1].arm.joints == (0.0,) * 7  # the other arm did not move


def test_status_requests_work_while_a_program_runs() -> None:
    bus = Bus(1)
    ask(bus, b"@1M50\r\n")
    ask(bus, b"@1o111=test.gcode\r\n", wait=0.05)
    status = lines_of(ask(bus, b"@1?\r\n", wait=0.1))
    assert status[0].startswith("<Run,")
    assert status[1:] == ["ok", "ok"]


def test_loop_and_stop() -> None:
    bus = Bus(1)
    ask(bus, b"@1M50\r\n")
    assert lines_of(ask(bus, b"@1o112test\r\n", wait=20.0)) == ["ok"]
    assert bus.nodes[0].running_file == "test"  # still looping after several rounds
    assert lines_of(ask(bus, b"@1o117\r\n", wait=0.05)) == ["ok"]
    assert bus.nodes[0].running_file is None
    settle(bus)
    assert lines_of(ask(bus, b"@1O103\r\n")) == ["State,Idle,1"]


def test_download_read_delete_and_run_by_number() -> None:
    bus = Bus(1, options=BusOptions(o110="lines"))
    ask(bus, b"@1M50\r\n")
    assert lines_of(ask(bus, b"@1o121=07wave\r\n")) == ["ok"]
    assert lines_of(ask(bus, b"@1M21 G90 G00 X12\r\n")) == ["ok"]  # stored, not executed
    assert lines_of(ask(bus, b"@1o122\r\n")) == ["ok"]
    assert bus.nodes[0].arm.joints[0] == 0.0
    assert lines_of(ask(bus, b"@1o110\r\n")) == ["test", "07wave"]
    assert lines_of(ask(bus, b"@1o114=07wave\r\n")) == ["M21 G90 G00 X12"]
    assert lines_of(ask(bus, b"@1O116=7\r\n")) == ["ok"]
    settle(bus)
    assert bus.nodes[0].arm.joints[0] == pytest.approx(12.0, abs=0.01)
    assert lines_of(ask(bus, b"@1o113test\r\n")) == ["ok"]
    assert lines_of(ask(bus, b"@1o111test\r\n")) == ["error"]
    assert lines_of(ask(bus, b"@1O116=99\r\n")) == ["error"]


# ---- GPIO ---------------------------------------------------------------------------------------


def test_gpio_sdk_fields() -> None:
    bus = Bus(1)
    assert lines_of(ask(bus, b"@1o130=,,1,\r\n")) == ["ok"]  # D0 as a digital output
    assert lines_of(ask(bus, b"@1o130?\r\n")) == ["0,0,1,0", "ok"]
    assert lines_of(ask(bus, b"@1o131=,,1,\r\n")) == ["ok"]
    bus.nodes[0].pins.set_input("A0", 200)
    assert lines_of(ask(bus, b"@1o131?\r\n")) == ["200,0,1,0", "ok"]
    assert lines_of(ask(bus, b"@1o134=,,,test\r\n")) == ["ok"]
    assert lines_of(ask(bus, b"@1o134?\r\n")) == [",,,test", "ok"]
    assert lines_of(ask(bus, b"@1o130=1,2\r\n")) == ["error"]
    assert lines_of(ask(bus, b"@1o130=9,,,\r\n")) == ["error"]


def test_gpio_manual_reading() -> None:
    bus = Bus(1, options=BusOptions(gpio="manual"))
    assert lines_of(ask(bus, b"@1O131A0/2/>50/test\r\n")) == ["ok"]
    bus.nodes[0].pins.set_input("A0", 77)
    assert lines_of(ask(bus, b"@1O133A0?\r\n")) == ["77", "ok"]
    assert lines_of(ask(bus, b"@1O131D0/2\r\n")) == ["error"]  # no analog input on D0


# ---- timing -------------------------------------------------------------------------------------


@pytest.mark.parametrize("baud", [38400, 9600])
def test_reply_timing_at_the_bus_baud(baud: int) -> None:
    bus = Bus(4, baud=baud)
    request = b"@3?\r\n"
    bus.receive(request)
    request_end = len(request) * 10 / baud
    first = None
    line_end = None
    while line_end is None:
        deadline = bus.next_deadline()
        assert deadline is not None
        bus.advance(deadline - bus.now)
        out = bus.read_output()
        if out and first is None:
            first = bus.now
        if b"\n" in out:
            line_end = bus.now
    assert first is not None
    status_bytes = len(bus.nodes[2].arm.status_line()) + 2
    assert line_end - request_end == pytest.approx(
        bus.options.turnaround + status_bytes * 10 / baud, rel=1e-6
    )
    if baud == 38400:
        assert first - request_end < 0.1  # the clients' first-byte window
        assert line_end - request_end < 0.5  # ARD's first-line window


def test_replies_arrive_byte_by_byte_at_the_baud() -> None:
    bus = Bus(1)
    bus.receive(b"@1o101\r\n")
    bus.advance(8 * 10 / 38400 + 0.002 + 3.5 * 10 / 38400)
    assert bus.read_output() == b"202"
    assert settle(bus) == b"20210410\r\n"[3:]


def test_collisions_are_counted_when_the_host_does_not_wait() -> None:
    polite = Bus(4)
    for address in range(1, 5):
        ask(polite, f"@{address}?\r\n".encode())
    assert polite.collisions == 0
    rude = Bus(4)
    rude.receive(b"@1?\r\n@2?\r\n@3?\r\n")
    out = settle(rude)
    assert out.count(b"<") == 3  # delivered intact (serialised), but counted
    assert rude.collisions > 0


# ---- the Firmware-like interface ----------------------------------------------------------------


def test_advance_rejects_negative_time_and_keeps_every_arm_in_step() -> None:
    bus = Bus(3)
    with pytest.raises(ValueError, match="dt"):
        bus.advance(-1.0)
    bus.advance(1.25)
    assert bus.now == pytest.approx(1.25)
    assert all(node.arm.now == pytest.approx(1.25) for node in bus.nodes)


def test_reset_power_cycles_every_node() -> None:
    bus = Bus(2)
    ask(bus, b"@1o150=x\r\n")
    ask(bus, b"@2M50\r\n")
    bus.receive(b"@1?\r\n")  # lost with the power
    bus.reset()
    assert settle(bus) == b""  # nothing unsolicited: the banners are not relayed
    assert bus.nodes[0].bluetooth_name == "x"  # settings survive a restart
    assert lines_of(ask(bus, b"@1o150?\r\n")) == ["x"]


def test_constructor_and_option_validation() -> None:
    with pytest.raises(ValueError):
        Bus(0)
    with pytest.raises(ValueError):
        Bus(2, ["2021"])
    with pytest.raises(ValueError, match="baud"):
        Bus(1, baud=19200)
    with pytest.raises(ValueError, match="o103"):
        BusOptions(o103="text")
    assert BusOptions.parse(["o103=number", "turnaround=0.01", "relay-banner=yes"]) == BusOptions(
        o103="number", turnaround=0.01, relay_banner=True
    )
    with pytest.raises(ValueError, match="nonsense"):
        BusOptions.parse(["nonsense=1"])
    with pytest.raises(ValueError):
        BusOptions.parse(["unprefixed=one"])


@pytest.mark.parametrize(
    "name", ["receive", "advance", "read_output", "next_deadline", "reset", "trigger_hard_limit"]
)
def test_the_bus_takes_the_firmwares_place(name: str) -> None:
    import inspect

    firmware = inspect.signature(getattr(Firmware, name))
    bus = inspect.signature(getattr(Bus, name))
    for parameter in firmware.parameters.values():  # every call a server makes still works
        assert bus.parameters[parameter.name].kind == parameter.kind
        assert bus.parameters[parameter.name].default == parameter.default
    extra = [p for p in bus.parameters.values() if p.name not in firmware.parameters]
    assert all(p.default is not inspect.Parameter.empty for p in extra)
    assert isinstance(Bus(1).now, float)
