"""Tests of so101sim.gl: choosing a headless OpenGL backend and saying what to install."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from so101sim import gl


def loader_for(*available: str):
    """A fake dlopen that loads only the libraries whose names contain one of ``available``."""

    def load(name: str) -> bool:
        return any(a in name for a in available)

    return load


def test_egl_is_preferred_when_it_loads():
    assert gl.choose_headless_backend(loader_for("libEGL", "libOSMesa")) == "egl"


def test_osmesa_is_the_fallback_when_egl_does_not_load():
    assert gl.choose_headless_backend(loader_for("libOSMesa")) == "osmesa"


def test_none_when_neither_loads():
    assert gl.choose_headless_backend(loader_for()) is None


def test_select_backend_sets_mujoco_gl_only_when_headless_and_unset(monkeypatch):
    monkeypatch.setattr(gl, "selection", gl.selection)  # restored afterwards
    monkeypatch.setattr(gl, "_chosen", gl._chosen)
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(gl.sys, "platform", "linux")
    monkeypatch.setattr(gl, "_mujoco_imported", lambda: False)
    assert gl.select_backend(loader_for("libOSMesa")) == "osmesa"
    assert "chose osmesa" in gl.selection
    # already set: left alone
    assert gl.select_backend(loader_for("libEGL")) == "osmesa"
    monkeypatch.delenv("MUJOCO_GL")
    assert gl.select_backend(loader_for()) is None
    assert "neither libEGL nor libOSMesa loads" in gl.selection
    assert "libosmesa6" in gl.backend_help("no context")


def test_a_display_leaves_the_default(monkeypatch):
    monkeypatch.setattr(gl, "selection", gl.selection)
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.setattr(gl.sys, "platform", "linux")
    assert gl.select_backend(loader_for("libEGL")) is None
    assert "display" in gl.selection


def test_a_mujoco_gl_set_outside_so101sim_is_left_alone(monkeypatch):
    monkeypatch.setattr(gl, "selection", gl.selection)
    monkeypatch.setattr(gl, "_chosen", None)
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    assert gl.prepare_for_rendering(loader_for("libEGL")) == "osmesa"
    assert "set outside so101sim" in gl.selection


@pytest.mark.parametrize(("imported", "called"), [(False, "select"), (True, "switch")])
def test_prepare_for_rendering_sets_mujoco_gl_or_switches_the_context(
    monkeypatch, imported, called
):
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(gl.sys, "platform", "linux")
    monkeypatch.setattr(gl, "_mujoco_imported", lambda: imported)
    monkeypatch.setattr(gl, "select_backend", lambda loader: "select")
    monkeypatch.setattr(gl, "ensure_offscreen_backend", lambda loader: "switch")
    assert gl.prepare_for_rendering() == called


def _run_python(code: str) -> str:
    """Run ``code`` in a fresh interpreter with no display and MUJOCO_GL unset; its stdout."""
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY")}
    env.pop("WAYLAND_DISPLAY", None)
    env.pop("PYOPENGL_PLATFORM", None)
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_importing_sets_no_environment_variable():
    code = "import os, so101sim.gl, so101sim.recording; print(os.environ.get('MUJOCO_GL'))"
    assert _run_python(code) == "None"


@pytest.mark.slow
@pytest.mark.parametrize("mujoco_first", [False, True])
def test_rendering_chooses_a_backend_when_asked_for(mujoco_first):
    code = (
        ("import mujoco\n" if mujoco_first else "")
        + "import os\n"
        + "from so101sim import Simulation\n"
        + "from so101sim.recording import FrameRenderer, VideoSettings\n"
        + "sim = Simulation()\n"
        + "fr = FrameRenderer(sim.model, VideoSettings(width=32, height=24, quality='draft'))\n"
        + "print(os.environ.get('MUJOCO_GL'), fr.render(sim.data).std() > 5)\n"
        + "fr.close()\n"
    )
    backend, drawn = _run_python(code).split()
    assert backend in ("egl", "osmesa") and drawn == "True"


@pytest.mark.parametrize(
    ("name", "software"),
    [("llvmpipe (LLVM 15.0.6, 256 bits)", True), ("NVIDIA H100/PCIe/SSE2", False), ("", True)],
)
def test_software_rendering_is_read_from_gl_renderer(monkeypatch, name, software):
    monkeypatch.setattr(gl, "renderer_string", lambda: name)
    assert gl.software_rendering() is software


def test_this_machine_can_render_offscreen():
    assert gl.renderer_string()  # a GL context starts (Mesa's llvmpipe on a CPU-only machine)


def test_a_worker_rasterises_in_its_own_thread_unless_a_count_is_set(monkeypatch):
    monkeypatch.delenv("LP_NUM_THREADS", raising=False)
    gl.one_rasterizer_thread()
    assert os.environ["LP_NUM_THREADS"] == "0"
    monkeypatch.setenv("LP_NUM_THREADS", "3")
    gl.one_rasterizer_thread()
    assert os.environ["LP_NUM_THREADS"] == "3"
