"""The simulated follower's cameras: frames of its scene, read as LeRobot reads its cameras.

A follower configured with ``cameras={"front": {}, "wrist": {"width": 224, "height": 224}}``
gets the preset cameras of :mod:`so101sim.scenes` (``front``: the usual LeRobot table view;
``wrist``: on the gripper, like the common SO-101 wrist-camera mount), or any camera given by
``pos``/``lookat``/``fovy``/``body``, added to its scene at load time with ``mujoco.MjSpec``
(:func:`scene_model`). Each entry may also say ``quality``: ``"auto"`` (the default: the
simplified draft meshes when OpenGL renders on the CPU, the full ones on a GPU), ``"draft"``
or ``"full"``.

:class:`CameraRig` draws them: ``get_observation()`` copies the joint state under the physics
lock (:meth:`CameraRig.snapshot`) and renders it after releasing the lock
(:meth:`CameraRig.render`), so the real-time physics thread is never held up by rendering. All
rendering happens on one private thread that owns the OpenGL contexts (an EGL context can be
current in only one thread at a time), whichever thread asks for a frame; it is a daemon
thread, stopped and joined by :meth:`CameraRig.close` (the robot's ``disconnect()``).

Each camera is also a :class:`SimCamera` with LeRobot's ``Camera`` reading methods
(``read``, ``async_read``, ``read_latest``) and ``width``/``height``/``fps``, so
``robot.cameras["front"].read()`` works as with a real camera.
"""

from __future__ import annotations

import copy
import queue
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..errors import CameraError, DeviceNotConnectedError, SettingError
from ..model.arm import ArmLike
from ..model.load import load_model
from ..recording.settings import QUALITY_CHOICES, VideoSettings
from ..scenes import (
    PRESET_CAMERAS,
    CameraSpec,
    build_model,
    camera,
    preset_scene,
    randomization,
    scene_additions,
)
from ..sim.simulation import Simulation

CAMERA_KEYS: tuple[str, ...] = (
    *(f.name for f in fields(CameraSpec) if f.name != "name"),
    "quality",
)
"""The keys a camera entry of a follower's config may hold."""

_VECTORS = ("pos", "lookat", "up")


@dataclass(frozen=True)
class RobotCameraSpec:
    """One camera of a follower: where it is and what it delivers (``spec``) and the render
    quality preset (``"auto"``, ``"draft"`` or ``"full"``)."""

    spec: CameraSpec
    quality: str = "auto"

    def settings(self) -> VideoSettings:
        """The frame renderer's settings for this camera."""
        s = self.spec
        return VideoSettings(
            width=s.width, height=s.height, fps=s.fps, camera=s.name, quality=self.quality,
            caption=False,
        )  # fmt: skip


def parse_cameras(cameras: Mapping[str, Any] | None) -> dict[str, RobotCameraSpec]:
    """A follower config's ``cameras`` as checked camera specs, by name.

    Each value is None or ``{}`` (a preset as it is), a :class:`~so101sim.scenes.CameraSpec`,
    or a dict of :data:`CAMERA_KEYS` (changes to a preset, or ``pos`` and ``lookat`` for a
    camera of one's own).

    Raises:
        CameraError: not a dict, an unknown key, a value that is not valid (the message names
            the camera and what is expected).
    """
    if cameras is None:
        return {}
    if not isinstance(cameras, Mapping):
        raise CameraError(
            f"cameras = {cameras!r} is not valid; expected a dict from camera name to its "
            f"settings, such as {{'front': {{}}, 'wrist': {{'width': 224, 'height': 224}}}}"
        )
    return {str(name): _parse_camera(name, value) for name, value in cameras.items()}


def _parse_camera(name: object, value: object) -> RobotCameraSpec:
    if not isinstance(name, str):
        raise CameraError(f"camera name {name!r} is not valid; expected a name such as 'front'")
    if isinstance(value, RobotCameraSpec):
        value = value.spec
    if isinstance(value, CameraSpec):
        return _checked(RobotCameraSpec(replace(value, name=name).validated()))
    if value is None:
        value = {}
    if not isinstance(value, Mapping):
        raise CameraError(
            f"camera {name!r} = {value!r} is not valid; expected a dict with some of "
            f"{', '.join(CAMERA_KEYS)} (or {{}} for the preset {', '.join(PRESET_CAMERAS)})"
        )
    unknown = sorted(str(k) for k in value if k not in CAMERA_KEYS)
    if unknown:
        raise CameraError(
            f"camera {name!r} has unknown setting {unknown[0]!r}; valid settings are "
            f"{', '.join(CAMERA_KEYS)}"
        )
    fields_ = {k: v for k, v in value.items() if k != "quality"}
    for key in _VECTORS:
        if key in fields_ and not isinstance(fields_[key], (str, bytes)):
            try:
                fields_[key] = tuple(fields_[key])
            except TypeError:
                raise CameraError(
                    f"camera {name!r}: {key} = {fields_[key]!r}; expected 3 numbers (metres)"
                ) from None
    quality = value.get("quality", "auto")
    return _checked(RobotCameraSpec(camera(name, **fields_), quality))


def _checked(cam: RobotCameraSpec) -> RobotCameraSpec:
    """``cam`` if a frame renderer accepts its size and quality, else CameraError."""
    if cam.quality not in QUALITY_CHOICES:
        raise CameraError(
            f"camera {cam.spec.name!r}: quality = {cam.quality!r}; expected one of "
            f"{', '.join(QUALITY_CHOICES)}"
        )
    try:
        cam.settings().validated()
    except SettingError as exc:
        raise CameraError(f"camera {cam.spec.name!r}: {exc}") from None
    return cam


def scene_model(
    cameras: Mapping[str, Any] | None,
    model: str | Path | None,
    scene: str | None = None,
    randomize: object = None,
    *,
    arm: ArmLike = None,
) -> mujoco.MjModel:
    """A follower's own physics model: ``model`` (the shipped scene by default) with the arm
    profile ``arm`` (None: the default), its cameras and the table and objects of the
    ``scene`` preset (see :data:`so101sim.scenes.SCENE_PRESETS`) added, compiled anew;
    without cameras or a scene, a private copy of the loaded model (the follower changes the
    gripper's force range on it). ``randomize``: the domain randomisation (a preset's name, a
    dict or a ``Randomization``) whose distractor boxes and textures are built in."""
    cams = parse_cameras(cameras)
    if scene is not None:
        extra = scene_additions(randomization(randomize))
        specs = [c.spec for c in cams.values()]
        return build_model(specs, model, scene=preset_scene(scene), extra=extra, arm=arm)
    if cams:
        return build_model([c.spec for c in cams.values()], model, arm=arm)
    return copy.copy(load_model(model, arm=arm))


@dataclass(frozen=True)
class _State:
    """What a frame shows, copied from the simulation's data under its lock (the fields
    :meth:`so101sim.recording.FrameRenderer.render` reads)."""

    time: float
    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray


class _RenderThread:
    """One daemon thread that runs every rendering call, so the OpenGL contexts it makes are
    only ever current in it."""

    def __init__(self, name: str) -> None:
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def call(self, fn: Callable[..., Any], *args: Any) -> Any:
        """``fn(*args)`` run on the render thread; its result, or its exception raised here."""
        if threading.current_thread() is self._thread:
            return fn(*args)
        future: Future[Any] = Future()
        self._queue.put((fn, args, future))
        return future.result()

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            fn, args, future = item
            try:
                future.set_result(fn(*args))
            except BaseException as exc:  # handed to the caller, who raises it
                future.set_exception(exc)

    def stop(self) -> None:
        """Let the thread finish the calls queued before, then join it."""
        self._queue.put(None)
        if threading.current_thread() is not self._thread:
            self._thread.join()


class SimCamera:
    """One of a follower's cameras, with LeRobot's ``Camera`` reading methods. Frames are
    (height, width, 3) uint8 RGB arrays of the scene's present state."""

    def __init__(self, rig: CameraRig, cam: RobotCameraSpec) -> None:
        self._rig = rig
        self.spec = cam.spec
        self.quality = cam.quality
        self.name = cam.spec.name
        self.width = int(cam.spec.width)
        self.height = int(cam.spec.height)
        self.fps = cam.spec.fps

    @property
    def is_connected(self) -> bool:
        """True while the robot is connected (its cameras render)."""
        return self._rig.is_open

    def read(self) -> np.ndarray:
        """A frame of the present state, rendered now.

        Raises:
            DeviceNotConnectedError: the robot is not connected.
        """
        return self._rig.read(self.name)

    def async_read(self, timeout_ms: float = 200.0) -> np.ndarray:
        """A new frame of the present state (rendering is synchronous: no wait, no timeout)."""
        return self.read()

    def read_latest(self, max_age_ms: int = 500) -> np.ndarray:
        """The last frame rendered (by ``get_observation`` or ``read``) if it is younger than
        ``max_age_ms`` of wall-clock time; else a new one."""
        return self._rig.latest(self.name, max_age_ms / 1000.0)


class CameraRig:
    """The cameras of a follower driving ``sim`` (whose model has them: see
    :func:`scene_model`). Nothing is rendered before :meth:`open`."""

    def __init__(self, sim: Simulation, cameras: Mapping[str, Any] | None) -> None:
        self._sim = sim
        self.specs = parse_cameras(cameras)
        self.cameras: dict[str, SimCamera] = {
            name: SimCamera(self, cam) for name, cam in self.specs.items()
        }
        self._worker: _RenderThread | None = None
        self._renderers: dict[str, Any] = {}
        self._latest: dict[str, tuple[float, np.ndarray]] = {}

    @property
    def features(self) -> dict[str, tuple[int, int, int]]:
        """``{name: (height, width, 3)}``: LeRobot's observation features of the cameras."""
        return {n: (c.height, c.width, 3) for n, c in self.cameras.items()}

    @property
    def is_open(self) -> bool:
        return self._worker is not None

    def open(self) -> None:
        """Start the render thread and a frame renderer per camera (a no-op without cameras).

        Raises:
            RenderBackendError: no OpenGL backend renders here (nothing is left running).
        """
        if not self.specs or self._worker is not None:
            return
        worker = _RenderThread(name="so101sim-cameras")
        try:
            worker.call(self._start_renderers)
        except BaseException:
            worker.call(self._close_renderers)
            worker.stop()
            raise
        self._worker = worker

    def _start_renderers(self) -> None:
        from ..recording.frames import FrameRenderer  # imported here only to keep start-up fast

        for name, cam in self.specs.items():
            self._renderers[name] = FrameRenderer(self._sim.model, cam.settings())

    @property
    def render_models(self) -> list[mujoco.MjModel]:
        """The models the cameras draw with (empty before :meth:`open`)."""
        return [r.render_model for r in self._renderers.values()]

    def _close_renderers(self) -> None:
        for r in self._renderers.values():
            r.close()
        self._renderers.clear()

    def close(self) -> None:
        """Close the renderers and join the render thread (a no-op when not open)."""
        worker, self._worker = self._worker, None
        if worker is None:
            return
        try:
            worker.call(self._close_renderers)
        finally:
            worker.stop()
            self._latest.clear()

    def snapshot(self) -> _State | None:
        """The state the cameras would show now (call it holding the simulation's lock); None
        without cameras."""
        if not self.specs:
            return None
        d = self._sim.data
        return _State(float(d.time), d.qpos.copy(), d.mocap_pos.copy(), d.mocap_quat.copy())

    def render(self, state: _State | None, names: list[str] | None = None) -> dict[str, Any]:
        """``{name: frame}`` of ``state`` for every camera (or ``names``): new (h, w, 3) uint8
        arrays. Call it without holding the simulation's lock.

        Raises:
            DeviceNotConnectedError: not open.
        """
        if state is None:
            return {}
        worker = self._worker
        if worker is None:
            raise DeviceNotConnectedError(
                "the cameras render only while the robot is connected; call connect() first"
            )
        frames = worker.call(self._draw, state, list(self.specs) if names is None else names)
        now = time.monotonic()
        self._latest.update({n: (now, f) for n, f in frames.items()})
        return frames

    def _draw(self, state: _State, names: list[str]) -> dict[str, np.ndarray]:
        return {n: self._renderers[n].render(state).copy() for n in names}

    def read(self, name: str) -> np.ndarray:
        """A frame of camera ``name`` showing the present state."""
        with self._sim.lock:
            state = self.snapshot()
        return self.render(state, [name])[name]

    def latest(self, name: str, max_age_s: float) -> np.ndarray:
        """The last frame of ``name`` if rendered less than ``max_age_s`` ago, else a new one."""
        last = self._latest.get(name)
        if last is not None and time.monotonic() - last[0] <= max_age_s and self.is_open:
            return last[1]
        return self.read(name)


__all__ = [
    "CAMERA_KEYS",
    "CameraRig",
    "RobotCameraSpec",
    "SimCamera",
    "parse_cameras",
    "scene_model",
]
