import atexit
import os
import shutil
import tempfile

# Offscreen rendering and viewer-less runs: no display in tests unless a test sets one up.
os.environ.pop("DISPLAY", None)
os.environ.pop("WAYLAND_DISPLAY", None)
os.environ.setdefault("MUJOCO_GL", "egl")
# Compiled models are cached in a folder of this test session, not the user's cache, removed
# when the session ends (pytest-xdist's workers inherit the variable and share the folder).
if "SO101SIM_CACHE_DIR" not in os.environ:
    _CACHE = tempfile.mkdtemp(prefix="so101sim-test-cache-")
    os.environ["SO101SIM_CACHE_DIR"] = _CACHE
    atexit.register(shutil.rmtree, _CACHE, ignore_errors=True)

import subprocess

import pytest

from so101sim import Simulation


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``-n auto``: one worker more than the cores. Many tests wait (a browser's frame, a
    subprocess, a window): a third worker on two cores fills those waits (the suite 285 s with
    two workers, 249 s with three, 258 s with four, on the 2-core VM, side by side)."""
    return (os.cpu_count() or 1) + 1


# The modules that take longest (CPU seconds measured one by one on the 2-core VM, 10-63 s
# each), run first: pytest-xdist hands out whole modules (--dist loadfile) and by default the
# ones with the most tests first, which left a module of one 35 s test to the end while the
# other workers sat idle (the suite's last 15-20 s). Browser, Ray, fit and subprocess modules
# alternate so that workers do not all wait on the same thing at once. A module missing from
# this list only runs later; nothing depends on the order.
HEAVY_FIRST = (
    "fidelity/test_fidelity_load_friction.py",  # 205 s on one core (2026-11-29): the longest
    "studio/test_studio_page.py",
    "fidelity/test_fidelity_calibration.py",
    "envs/test_distributed.py",
    "studio/test_studio_compare.py",
    "viewer/test_viewer.py",
    "fidelity/test_fidelity_fit.py",
    "studio/test_studio.py",
    "envs/test_vector_ray.py",
    "envs/test_envs_memory.py",
    "envs/test_envs.py",
    "recording/test_recording_signals.py",
    "model/test_modelcache.py",
    "lab/test_script_arm.py",
    "studio/test_studio_safety.py",
    "robot/test_robot.py",
    "fidelity/test_fidelity_windows.py",
    "test_exit.py",
    "cli/test_cli_fuzz.py",
    "test_examples.py",
    "preflight/test_variants.py",
    "lab/test_handin.py",
)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The :data:`HEAVY_FIRST` modules first, in that order; the others after, as collected
    (with ``--no-loadscope-reorder`` pytest-xdist keeps this order)."""
    rank = {f"tests/{name}": i for i, name in enumerate(HEAVY_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))


@pytest.fixture
def sim() -> Simulation:
    """A fresh simulation of the shipped model, arm at its rest pose, time 0."""
    return Simulation()


@pytest.fixture(scope="session")
def xvfb():
    """A virtual X display for the real viewer (Xvfb is installed by .ci/run)."""
    if shutil.which("Xvfb") is None:
        pytest.skip("Xvfb is not installed (apt-get install -y xvfb)")
    read_fd, write_fd = os.pipe()
    # Xvfb picks a free display number and writes it to write_fd. -noreset: by default an X
    # server resets when its last client leaves and drops the connections that come meanwhile
    # ("X11: Failed to open display"): between two `xdotool search` polls a viewer that is still
    # starting would be one of them, now and then, on a busy machine.
    screen = ("-screen", "0", "1024x768x24")
    proc = subprocess.Popen(
        ["Xvfb", "-displayfd", str(write_fd), *screen, "-nolisten", "tcp", "-noreset"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        pass_fds=(write_fd,),
    )
    os.close(write_fd)
    with os.fdopen(read_fd) as f:
        num = f.readline().strip()
    if not num:
        proc.kill()
        pytest.fail("Xvfb did not start")
    yield f":{num}"
    proc.terminate()
    proc.wait(timeout=10)
