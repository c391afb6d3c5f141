"""Drawing a simulation's state to RGB frames offscreen (:class:`FrameRenderer`), with an
optional one-line caption (:class:`Caption`).

Rendering uses ``mujoco.Renderer`` on a private copy of the model (see
:func:`so101sim.recording.draft.render_model`), fed the simulation's joint angles: the physics
model is never touched. The OpenGL backend is chosen when the first renderer starts
(:func:`so101sim.gl.prepare_for_rendering`).
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from .. import gl
from ..errors import RenderBackendError
from .draft import render_model
from .floor import as_infinite, finite_planes
from .framing import view_for_run, workspace_frames
from .settings import FREE_CAMERA, VideoSettings, check_camera, resolve_quality


class Caption:
    """Draws one line of text into the bottom-left of a frame: FreeType (through matplotlib's
    bundled font) rasterises the string into a small alpha mask, numpy blends it in."""

    def __init__(self, height: int) -> None:
        from matplotlib import font_manager  # imported here only to keep start-up fast
        from matplotlib.ft2font import FT2Font

        self.font = FT2Font(font_manager.findfont("DejaVu Sans Mono"))
        self.size = max(8.0, height / 30)
        self.margin = max(4, height // 60)
        self._last: tuple[str, np.ndarray] | None = None

    def _mask(self, text: str) -> np.ndarray:
        if self._last is not None and self._last[0] == text:
            return self._last[1]
        self.font.set_size(self.size, 72)
        self.font.set_text(text, 0.0)
        self.font.draw_glyphs_to_bitmap(antialiased=True)
        mask = np.asarray(self.font.get_image(), dtype=np.float32) / 255.0
        self._last = (text, mask)
        return mask

    def draw(self, frame: np.ndarray, text: str) -> None:
        """Draw ``text`` in white on a darkened box into ``frame`` (in place)."""
        mask = self._mask(text)
        h, w = frame.shape[:2]
        pad = self.margin
        mh, mw = min(mask.shape[0], h - 2 * pad), min(mask.shape[1], w - 2 * pad)
        if mh <= 0 or mw <= 0:
            return
        y0, x0 = h - pad - mh - pad // 2, pad
        box = frame[y0 - pad // 2 : y0 + mh + pad // 2, x0 - pad // 2 : x0 + mw + pad // 2]
        box[:] = (box * 0.45).astype(np.uint8)  # darken the text's background
        region = frame[y0 : y0 + mh, x0 : x0 + mw].astype(np.float32)
        a = mask[:mh, :mw, None]
        frame[y0 : y0 + mh, x0 : x0 + mw] = (region * (1 - a) + 255.0 * a).astype(np.uint8)


class FrameRenderer:
    """Draws the state of ``(model, data)`` to RGB frames with ``mujoco.Renderer`` on a private
    render model (see :func:`so101sim.recording.draft.render_model`).

    Raises:
        CameraError, RecordingError: bad settings.
        RenderBackendError: no OpenGL backend works here (the message says what to install).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        settings: VideoSettings | None = None,
        *,
        sweep: Sequence[np.ndarray] | None = None,
    ) -> None:
        self.settings = s = (settings or VideoSettings()).validated()
        self.sweep = sweep
        check_camera(model, s.camera)
        self.model = model
        gl.prepare_for_rendering()
        self.quality = resolve_quality(s.quality)
        self.render_model = render_model(model, self.quality, s.width, s.height)
        # draft: the floor drawn as a few quads, the same pixels (so101sim.recording.floor)
        self._planes = finite_planes(self.render_model) if self.quality == "draft" else ()
        self.render_data = mujoco.MjData(self.render_model)
        self.renderer = self._start_renderer()
        self.camera = self._camera()
        self.frame = np.empty((s.height, s.width, 3), dtype=np.uint8)
        self._caption = Caption(s.height) if s.caption else None

    def _start_renderer(self) -> mujoco.Renderer:
        s = self.settings
        try:
            renderer = mujoco.Renderer(self.render_model, height=s.height, width=s.width)
        except Exception as exc:  # EGL/OSMesa/GLFW failures come as many exception types
            raise RenderBackendError(gl.backend_help(exc)) from exc
        if self.quality == "draft":
            flags = renderer.scene.flags
            flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
            flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        return renderer

    def _camera(self) -> mujoco.MjvCamera | str:
        """A named camera of the model, or the free camera fitted to the run's ``sweep`` (the
        arm's joint positions over the run; when it is not known, over its whole workspace)."""
        s = self.settings
        if s.camera != FREE_CAMERA:
            return s.camera
        sweep = self.sweep if self.sweep is not None else workspace_frames(self.model)
        view = view_for_run(
            self.model,
            sweep,
            s.width,
            s.height,
            azimuth=s.azimuth,
            elevation=s.elevation,
            distance=s.distance,
            lookat=s.lookat,
            view=s.view,
        )
        camera = mujoco.MjvCamera()
        view.apply(camera)
        return camera

    def render(self, d: mujoco.MjData, caption: str | None = None) -> np.ndarray:
        """The frame of ``d``'s current state (a reused (height, width, 3) uint8 array)."""
        rm, rd = self.render_model, self.render_data
        rd.time = d.time
        rd.qpos[:] = d.qpos
        if rm.nmocap:
            rd.mocap_pos[:] = d.mocap_pos
            rd.mocap_quat[:] = d.mocap_quat
        mujoco.mj_kinematics(rm, rd)
        mujoco.mj_comPos(rm, rd)
        mujoco.mj_camlight(rm, rd)
        self.renderer.update_scene(rd, camera=self.camera)
        as_infinite(self.renderer.scene, rm, self._planes)
        self.renderer.render(out=self.frame)
        if self.settings.title:
            caption = f"{self.settings.title}   {caption or ''}".rstrip()
        if self._caption is not None and caption:
            self._caption.draw(self.frame, caption)
        return self.frame

    def close(self) -> None:
        self.renderer.close()
