"""The examples run as a student runs them (headless here) and do what they say."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def run(name: str) -> str:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    out = subprocess.run(
        [sys.executable, str(EXAMPLES / name)], env=env, capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_lab_motion_example_ends_at_the_start_pose():
    out = run("lab_motion.py")
    assert "t = 6.000 s" in out
    assert "'shoulder_lift': -97.9" in out


@pytest.mark.slow
def test_lab_hold_start_example():
    assert "held for 30.0 s" in run("lab_hold_start.py")


def test_clean_api_example():
    out = run("clean_api.py")
    assert "to_zero  1000 steps" in out and "ends t=6.000 s" in out
