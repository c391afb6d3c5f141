import os

# Offscreen rendering and viewer-less runs: no display in tests unless a test sets one up.
os.environ.pop("DISPLAY", None)
os.environ.pop("WAYLAND_DISPLAY", None)
os.environ.setdefault("MUJOCO_GL", "egl")

import pytest

from so101sim import Simulation


@pytest.fixture
def sim() -> Simulation:
    """A fresh simulation of the shipped model, arm at its rest pose, time 0."""
    return Simulation()
