"""Envelope files (``--envelope FILE``): the TOML loader reads every field and refuses every
malformed input with a message naming the file and the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from mirobot_async.envelope_file import describe_envelope, load_envelope
from mirobot_async.errors import MirobotUsageError
from mirobot_async.kinematics import DH_2021, DH_CLASSIC, JOINT_LIMITS

ROOT = Path(__file__).resolve().parents[2]


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "envelope.toml"
    path.write_text(text)
    return path


def test_the_example_file_loads_on_both_models() -> None:
    classic = load_envelope(ROOT / "examples" / "envelope.toml")
    assert classic.dh == DH_CLASSIC  # the default profile of the loader
    modern = load_envelope(str(ROOT / "examples" / "envelope.toml"), firmware="2021")
    assert modern.dh == DH_2021
    assert modern.x == (100.0, 300.0) and modern.z == (20.0, 300.0)
    assert modern.joint_limits[0] == (-100.0, 100.0)
    # the homed arm (all joints 0) is inside: the example does not refuse the first move
    assert classic.contains_joints((0, 0, 0, 0, 0, 0))
    assert modern.contains_joints((0, 0, 0, 0, 0, 0))


def test_every_field(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        "rail = [0, 500]\ntool = [0, 0, 60.5]\n"
        "[box]\nx = [100, 280]\ny = [-200.5, 200]\nz = [20, inf]\n"
        "[joints]\n1 = [-90, 90]\n3 = [-30, 60]\n",
    )
    envelope = load_envelope(path, firmware="2021")
    assert envelope.x == (100.0, 280.0)
    assert envelope.y == (-200.5, 200.0)
    assert envelope.z == (20.0, None)  # inf: the side is open
    assert envelope.rail == (0.0, 500.0)
    assert envelope.tool == (0.0, 0.0, 60.5)
    assert envelope.joint_limits[0] == (-90.0, 90.0)
    assert envelope.joint_limits[2] == (-30.0, 60.0)
    assert envelope.joint_limits[1] == tuple(JOINT_LIMITS[1])  # not narrowed
    assert describe_envelope(envelope) == (
        "box x 100..280 mm, y -200.5..200 mm, z 20..open mm; J1 -90..90 deg, J3 -30..60 deg; "
        "rail 0..500 mm"
    )


def test_an_empty_file_is_no_bound_at_all(tmp_path: Path) -> None:
    envelope = load_envelope(write(tmp_path, "# nothing\n"))
    assert not envelope.has_box
    assert envelope.rail is None
    assert describe_envelope(envelope) == "no box"


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("[box]\nx = [280, 100]\n", "box.x = [280, 100]: min is above max"),
        ("[box]\nz = [20]\n", "box.z = [20] must be [min, max]"),
        ("[box]\nz = [20, 30, 40]\n", "box.z = [20, 30, 40] must be [min, max]"),
        ('[box]\nz = ["20", 30]\n', "box.z = ['20', 30] must be [min, max], two numbers"),
        ("[box]\nz = [true, 30]\n", "box.z = [True, 30] must be [min, max], two numbers"),
        ("[box]\nz = 20\n", "box.z = 20 must be [min, max]"),
        ("[box]\nz = [nan, 30]\n", "box.z = [nan, 30]: only the min may be -inf"),
        ("[box]\nz = [inf, inf]\n", "box.z = [inf, inf]: only the min may be -inf"),
        ("[box]\nw = [0, 1]\n", "box.w: unknown key (allowed: x, y, z)"),
        ("box = [0, 1]\n", "box = [0, 1] must be a table ([box])"),
        ("[joints]\n7 = [0, 1]\n", "joints.7: unknown key (allowed: 1, 2, 3, 4, 5, 6)"),
        ("[joints]\nj1 = [0, 1]\n", "joints.j1: unknown key"),
        ("[joints]\n2 = [10, -10]\n", "joints.2 = [10, -10]: min is above max"),
        ("[joints]\n1 = [-200, 90]\n", "is wider than the firmware's J1 range"),
        ("[cylinder]\nr = [0, 1]\n", "cylinder: unknown key or table (allowed: box, joints"),
        ("speed = 3\n", "speed: unknown key or table"),
        ("rail = [500, 0]\n", "rail = [500, 0]: min is above max"),
        ("rail = 5\n", "rail = 5 must be [min, max]"),
        ("tool = [0, 0]\n", "tool = [0, 0] must be [x, y, z], three finite numbers"),
        ("tool = [0, 0, inf]\n", "tool = [0, 0, inf] must be [x, y, z]"),
        ("[box\n", "not a TOML file"),
    ],
)
def test_bad_input_names_the_file_and_the_key(tmp_path: Path, text: str, words: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(MirobotUsageError) as caught:
        load_envelope(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: "), message
    assert words in message, message


def test_a_missing_file_and_a_bad_profile(tmp_path: Path) -> None:
    missing = tmp_path / "nope.toml"
    with pytest.raises(MirobotUsageError, match=r"nope\.toml: cannot read the envelope"):
        load_envelope(missing)
    with pytest.raises(MirobotUsageError, match="firmware='2020'"):
        load_envelope(write(tmp_path, ""), firmware="2020")
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe[box]")
    with pytest.raises(MirobotUsageError, match=r"binary\.toml: not a TOML file"):
        load_envelope(binary)
