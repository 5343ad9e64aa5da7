"""Third-party Mirobot clients drive the emulator unmodified (issue 11 item 4, issue 14).

* the vendor's SDK ``wlkata-mirobot-python`` 0.1.14, over the pty and over ``socket://`` from
  ``--listen 127.0.0.1:0``, on both firmware profiles;
* the community SDK ``mirobot-py`` 1.0.52 (it opens device paths only: the pty);
* the vendor's newer SDK ``wlkatapython`` 0.1.1, its direct-arm class (everything that does not
  need the controller box).

The first two need Python 3.10 (``mirobot-py`` imports ``bleak.discover``, gone from newer
``bleak``): a session fixture builds, once, a Python 3.10 venv with the pinned versions under
``~/.cache/mirobot-async-third-party/py310-<hash of the pins>`` (needs PyPI the first time). Each
test runs a small driver script from ``third_party/`` in that interpreter against an emulator
(``--reset-on-open``, as an arm whose DTR line resets it) and checks what the SDK parsed against
the raw status line on the wire and against the targets (whole motor steps: half a step).

Without Python 3.10 or PyPI the tests skip with one line saying how to enable them;
``MIROBOT_REQUIRE_THIRD_PARTY=1`` turns that skip into a failure (for CI).
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import importlib.util
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from mirobot_async._core.replies import parse_status
from mirobot_async.kinematics import DH_2021, DH_CLASSIC, forward
from mirobot_async.testing import run_emulator

pytestmark = pytest.mark.timeout(300)  # the first run builds the venv (PyPI); later ones < 30 s

PINS = (
    "wlkata-mirobot-python==0.1.14",
    "mirobot-py==1.0.52",
    "bleak==0.19.5",  # the last bleak with bleak.discover, which mirobot-py imports
    "dbus-fast==1.95.2",
    "async-timeout==4.0.3",
    "typing_extensions==4.16.0",
    "pyserial==3.5",
    "wlkatapython==0.1.1",
)
"""Everything the Python 3.10 venv holds, pinned (the venv's cache key is their hash)."""

REQUIRE_ENV = "MIROBOT_REQUIRE_THIRD_PARTY"
PY310_ENV = "MIROBOT_PY310"
ENABLE_HINT = (
    f"install Python 3.10 (pyenv install 3.10, or set {PY310_ENV}=/path/to/python3.10) "
    "and let the first run reach PyPI"
)
DRIVERS = Path(__file__).parent / "third_party"
TIME_SCALE = 50.0
"""Simulated seconds per wall second: homing takes ~0.2 s, moves tens of ms."""
DRIVER_TIMEOUT = 60.0
"""Seconds a driver script may take (they take 1-6 s; the SDKs' own waits have no limit)."""
ANGLE_TOLERANCE = 0.05
"""Degrees: the status angles are whole motor steps, within half a step of the target."""
POSE_TOLERANCE = 0.1
"""mm and degrees between a Cartesian target and the pose of the whole-step angles."""
JOINT_TARGET = (10.0, 20.0, 15.0, -5.0, 12.5, 30.0)
CARTESIAN_TARGET = (180.0, 20.0, 150.0, 0.0, 0.0, 0.0)
LINEAR_TARGET = (170.0, 0.0, 150.0, 0.0, 0.0, 0.0)


def unavailable(reason: str) -> None:
    """Skip (one line: why and how to enable), or fail when the environment requires these."""
    message = f"third-party SDK tests: {reason}; to enable: {ENABLE_HINT}"
    if os.environ.get(REQUIRE_ENV) == "1":
        pytest.fail(f"{message} ({REQUIRE_ENV}=1)", pytrace=False)
    pytest.skip(message)


def is_python310(python: str) -> bool:
    """Whether ``python`` runs and is 3.10 (a pyenv shim without 3.10 selected is not)."""
    try:
        done = subprocess.run(
            [python, "-c", "import sys; print(sys.version_info[:2] == (3, 10))"],
            capture_output=True, text=True, timeout=30,
        )  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return False
    return done.stdout.strip() == "True"


def find_python310() -> str | None:
    """``$MIROBOT_PY310``, else pyenv's newest 3.10, else ``python3.10`` on PATH."""
    candidates = [os.environ.get(PY310_ENV, "")]
    roots = [os.environ.get("PYENV_ROOT", ""), str(Path.home() / ".pyenv")]
    for root in filter(None, roots):
        found = sorted(glob.glob(os.path.join(root, "versions", "3.10.*", "bin", "python")))
        candidates.extend(reversed(found))
    candidates.append(shutil.which("python3.10") or "")
    return next((c for c in candidates if c and is_python310(c)), None)


def cache_root() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "mirobot-async-third-party"


@contextlib.contextmanager
def build_lock(root: Path) -> Iterator[None]:
    """One builder at a time across pytest-xdist workers (no lock where fcntl is missing)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    with open(root / ".lock", "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def venv_python(venv: Path) -> Path:
    return venv / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def build_venv(python: str, venv: Path) -> str | None:
    """Create ``venv`` with :data:`PINS` (in a temporary directory, renamed when complete);
    return why it failed, or None."""
    staging = venv.with_name(f"{venv.name}.building-{os.getpid()}")
    shutil.rmtree(staging, ignore_errors=True)
    try:
        subprocess.run(
            [python, "-m", "venv", str(staging)], capture_output=True, timeout=300, check=True
        )
        subprocess.run(
            [str(venv_python(staging)), "-m", "pip", "install", "-q",
             "--disable-pip-version-check", *PINS],
            capture_output=True, timeout=600, check=True,
        )  # fmt: skip
    except subprocess.CalledProcessError as err:
        shutil.rmtree(staging, ignore_errors=True)
        tail = (err.stderr or b"").decode("utf-8", "replace").strip().splitlines()[-1:]
        return f"building the Python 3.10 venv failed ({' '.join(tail) or err})"
    except (OSError, subprocess.TimeoutExpired) as err:
        shutil.rmtree(staging, ignore_errors=True)
        return f"building the Python 3.10 venv failed ({err})"
    staging.rename(venv)
    return None


@pytest.fixture(scope="session")
def py310() -> Path:
    """The cached Python 3.10 interpreter with the pinned SDKs (built on first use)."""
    python = find_python310()
    if python is None:
        unavailable("no Python 3.10 found")
    assert python is not None
    key = hashlib.sha256("\n".join(PINS).encode()).hexdigest()[:12]
    root = cache_root()
    root.mkdir(parents=True, exist_ok=True)
    venv = root / f"py310-{key}"
    with build_lock(root):
        if not venv_python(venv).exists():
            problem = build_venv(python, venv)
            if problem is not None:
                unavailable(problem)
    return venv_python(venv)


def wlkatapython_interpreter(request: pytest.FixtureRequest) -> str:
    """This interpreter when it has ``wlkatapython`` (e.g. 3.11 in the project's venv), else the
    3.10 venv, which has it too (built only then)."""
    if importlib.util.find_spec("Mirobot_robot") is not None:
        return sys.executable
    return str(request.getfixturevalue("py310"))


def run_driver(python: str | Path, script: str, url: str) -> list[dict[str, Any]]:
    """Run ``third_party/<script>`` against ``url``; return the steps it reported."""
    done = subprocess.run(
        [str(python), str(DRIVERS / script), url],
        capture_output=True,
        text=True,
        timeout=DRIVER_TIMEOUT,
        cwd=DRIVERS,
    )
    assert done.returncode == 0, f"{script} failed:\n{done.stdout}\n{done.stderr}"
    steps: list[dict[str, Any]] = json.loads(done.stdout.strip().splitlines()[-1])["steps"]
    return steps


def check_steps(steps: list[dict[str, Any]], firmware: str) -> dict[str, dict[str, Any]]:
    """Every step: the SDK read Idle, and what it parsed equals the raw status line on the wire
    (joint order, pose, PWMs), whose pose is the FK of its whole-step angles."""
    dh = DH_CLASSIC if firmware == "classic" else DH_2021
    by_name = {}
    for step in steps:
        raw = parse_status(step["raw"])
        name = step["name"]
        assert step["state"] == "Idle" == raw.state.value, (name, step)
        assert step["joints"] == pytest.approx(list(raw.joints), abs=1e-9), (name, step)
        assert step["pose"] == pytest.approx(list(raw.pose), abs=1e-9), (name, step)
        assert (step["pump_pwm"], step["valve_pwm"]) == (raw.pump_pwm, raw.valve_pwm), name
        assert list(raw.pose) == pytest.approx(list(forward(raw.joints, dh)), abs=2e-3), name
        by_name[name] = step
    return by_name


def near(values: list[float], target: tuple[float, ...], tolerance: float) -> bool:
    return all(abs(v - t) <= tolerance for v, t in zip(values, target, strict=True))


def check_scenario(steps: list[dict[str, Any]], firmware: str, pump_then: tuple[int, int]) -> None:
    """Home, joint move, Cartesian moves and PWMs ended where they were sent."""
    by_name = check_steps(steps, firmware)
    assert near(by_name["home"]["joints"], (0.0,) * 6, ANGLE_TOLERANCE), by_name["home"]
    assert near(by_name["joint"]["joints"], JOINT_TARGET, ANGLE_TOLERANCE), by_name["joint"]
    if "cartesian" in by_name:
        pose = by_name["cartesian"]["pose"]
        assert near(pose, CARTESIAN_TARGET, POSE_TOLERANCE), by_name["cartesian"]
        assert near(by_name["linear"]["pose"], LINEAR_TARGET, POSE_TOLERANCE), by_name["linear"]
    else:
        assert near(by_name["linear"]["pose"], CARTESIAN_TARGET, POSE_TOLERANCE), by_name
    assert by_name["pump"]["pump_pwm"] == 1000, by_name["pump"]
    last = steps[-1]
    assert (last["pump_pwm"], last["valve_pwm"]) == pump_then, last


@pytest.mark.parametrize(
    ("firmware", "link"), [("2021", "pty"), ("2021", "tcp"), ("classic", "pty"), ("classic", "tcp")]
)
def test_vendor_sdk_0_1_14(py310: Path, firmware: str, link: str) -> None:
    """The vendor's SDK: connect (its "%" reset), home, joint and Cartesian moves with its own
    wait for Idle, pump, gripper and valve; the same over the pty and over socket://."""
    with run_emulator(firmware, TIME_SCALE, listen=link) as emulator:  # it sends "%" itself
        if link == "tcp":
            assert emulator.url.startswith("socket://127.0.0.1:"), emulator.url
        steps = run_driver(py310, "vendor_sdk.py", emulator.url)
    check_scenario(steps, firmware, pump_then=(60, 40))


@pytest.mark.parametrize("firmware", ["2021", "classic"])
def test_mirobot_py(py310: Path, firmware: str) -> None:
    """The community SDK: connect (waits for the reset banner), home, moves, pump and valve."""
    with run_emulator(firmware, TIME_SCALE, extra_args=["--reset-on-open"], listen="pty") as emu:
        steps = run_driver(py310, "mirobot_py.py", emu.url)
    check_scenario(steps, firmware, pump_then=(1000, 40))


def test_wlkatapython_direct_arm(request: pytest.FixtureRequest) -> None:
    """The vendor's newer SDK without a controller box: homing through its pass-through, a
    joint move with its own blocking wait, a linear move, pump and gripper."""
    with run_emulator("2021", TIME_SCALE, extra_args=["--reset-on-open"], listen="pty") as emu:
        steps = run_driver(wlkatapython_interpreter(request), "wlkatapython_arm.py", emu.url)
    check_scenario(steps, "2021", pump_then=(60, 0))
