"""Tests of so101sim.gl: choosing a headless OpenGL backend and saying what to install."""

from __future__ import annotations

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


@pytest.mark.parametrize(
    ("name", "software"),
    [("llvmpipe (LLVM 15.0.6, 256 bits)", True), ("NVIDIA H100/PCIe/SSE2", False), ("", True)],
)
def test_software_rendering_is_read_from_gl_renderer(monkeypatch, name, software):
    monkeypatch.setattr(gl, "renderer_string", lambda: name)
    assert gl.software_rendering() is software


def test_this_machine_can_render_offscreen():
    assert gl.renderer_string()  # a GL context starts (Mesa's llvmpipe on a CPU-only machine)
