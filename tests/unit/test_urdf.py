"""The URDF of ``mirobot urdf``: read by a URDF library (yourdfpy), its tool frame is the
flange frame of ``kinematics.forward`` within 0.05 mm at any joints, for both profiles."""

from __future__ import annotations

import io
import subprocess
import sys
import xml.etree.ElementTree as ET
from typing import TYPE_CHECKING

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mirobot_async import kinematics
from mirobot_async._urdf import FLANGE_LINK, JOINT_NAMES, TOOL_LINK, build_urdf, dh_of
from mirobot_async.errors import MirobotUsageError

if TYPE_CHECKING:
    import yourdfpy

PROFILES = ("2021", "classic")


@pytest.fixture(scope="module")
def models() -> dict[str, yourdfpy.URDF]:
    """yourdfpy's model of each profile's URDF. Imported here, not at the top: yourdfpy pulls in
    trimesh, scipy and networkx (1.5 s of CPU), which each pytest-xdist worker would pay at
    collection even when it runs none of these tests."""
    import yourdfpy

    return {p: yourdfpy.URDF.load(io.StringIO(build_urdf(p))) for p in PROFILES}


joints = st.tuples(
    *(
        st.floats(lo, hi, allow_nan=False, allow_infinity=False)
        for lo, hi in kinematics.JOINT_LIMITS
    )
)


@pytest.mark.parametrize("firmware", PROFILES)
@settings(max_examples=300)
@given(q=joints)
def test_flange_frame_matches_forward_kinematics(
    models: dict[str, yourdfpy.URDF], firmware: str, q: tuple[float, ...]
) -> None:
    model = models[firmware]
    model.update_cfg(np.radians(q))
    frame = model.get_transform(FLANGE_LINK, "base_link")
    pose = kinematics.forward(q, dh_of(firmware))
    position_mm = frame[:3, 3] * 1000.0
    assert np.abs(position_mm - np.asarray(pose[:3])).max() < 0.05
    rotation = kinematics.rpy_to_matrix(*pose[3:])
    # orientation: the flange axes agree to 1e-6 (0.05 mm at 50 mm from the flange)
    assert np.abs(frame[:3, :3] - rotation).max() < 1e-6


@pytest.mark.parametrize("firmware", PROFILES)
def test_zero_pose_is_the_protocol_s(models: dict[str, yourdfpy.URDF], firmware: str) -> None:
    """PROTOCOL 8.1: at q = 0 the flange is at (A1 + D4, 0, D1 + A2 + A3 + L)."""
    dh = dh_of(firmware)
    model = models[firmware]
    model.update_cfg(np.zeros(6))
    frame = model.get_transform(FLANGE_LINK, "base_link")
    expected = (dh.a1 + dh.d4, 0.0, dh.d1 + dh.a2 + dh.a3 + dh.l)
    # a nanometre: the model is shared by the module's tests, and reaching q = 0 from another
    # configuration leaves float noise (4e-7 mm seen)
    assert np.allclose(frame[:3, 3] * 1000.0, expected, atol=1e-6)


@pytest.mark.parametrize("firmware", PROFILES)
def test_joints_and_limits_are_the_firmware_s(
    models: dict[str, yourdfpy.URDF], firmware: str
) -> None:
    model = models[firmware]
    assert tuple(model.actuated_joint_names) == JOINT_NAMES
    for joint, (low, high) in zip(model.actuated_joints, kinematics.JOINT_LIMITS, strict=True):
        assert joint.type == "revolute"
        assert joint.limit is not None
        assert np.isclose(np.degrees(joint.limit.lower), low)
        assert np.isclose(np.degrees(joint.limit.upper), high)
        assert joint.limit.velocity > 0


def test_geometry_is_primitives_only(models: dict[str, yourdfpy.URDF]) -> None:
    """Our own cylinders and boxes: no mesh file is referenced."""
    root = ET.fromstring(build_urdf("2021"))
    shapes = {child.tag for geometry in root.iter("geometry") for child in geometry}
    assert shapes <= {"cylinder", "box"}
    assert not list(root.iter("mesh"))
    assert models["2021"].scene is not None
    assert len(models["2021"].scene.geometry) >= 10  # yourdfpy built every shape


def test_profiles_differ() -> None:
    assert build_urdf("2021") != build_urdf("classic")
    with pytest.raises(MirobotUsageError):
        build_urdf("2019")


def test_cli_prints_the_urdf_without_viser() -> None:
    """``mirobot urdf`` prints the document; it imports nothing of the view (viser)."""
    code = (
        "import sys; from mirobot_async._cli import main; status = main(['urdf', '--firmware', "
        "'classic']); assert 'viser' not in sys.modules, 'viser imported'; sys.exit(status)"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout == build_urdf("classic")


@pytest.mark.parametrize("firmware", PROFILES)
def test_tool0_points_out_of_the_flange(models: dict[str, yourdfpy.URDF], firmware: str) -> None:
    """ROS-Industrial: tool0's z is the approach direction, out of the flange (at the zero pose
    the tool hangs down), at the flange's point; x is the flange's x."""
    model = models[firmware]
    model.update_cfg(np.zeros(6))
    flange = model.get_transform(FLANGE_LINK, "base_link")
    tool = model.get_transform(TOOL_LINK, "base_link")
    assert np.allclose(tool[:3, 3], flange[:3, 3], atol=1e-12)
    assert np.allclose(tool[:3, 2], (0.0, 0.0, -1.0), atol=1e-9)  # down, out of the flange
    assert np.allclose(tool[:3, 0], flange[:3, 0], atol=1e-9)
    assert np.allclose(tool[:3, 2], -flange[:3, 2], atol=1e-9)


@pytest.mark.parametrize("firmware", PROFILES)
def test_every_link_with_a_shape_can_collide(
    models: dict[str, yourdfpy.URDF], firmware: str
) -> None:
    """Planners (MoveIt) check collisions on collision elements: every drawn link has them."""
    model = models[firmware]
    drawn = [link for link in model.robot.links if link.visuals]
    assert len(drawn) == 7  # the base and the six links
    for link in drawn:
        assert len(link.collisions) == len(link.visuals), link.name
