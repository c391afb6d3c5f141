"""Choosing MuJoCo's OpenGL backend, which must happen before ``mujoco`` is first imported.

With no display (a server, CI, ssh), offscreen rendering needs EGL (Mesa renders it on the
CPU when there is no GPU). If ``MUJOCO_GL`` is already set, it is left alone.
"""

from __future__ import annotations

import os
import sys


def headless() -> bool:
    """True on Linux when no X11/Wayland display is available."""
    return sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )


def select_backend() -> str | None:
    """Set ``MUJOCO_GL=egl`` when there is no display and nothing was chosen; return the choice."""
    if "MUJOCO_GL" not in os.environ and headless() and "mujoco" not in sys.modules:
        os.environ["MUJOCO_GL"] = "egl"
    return os.environ.get("MUJOCO_GL")


select_backend()
