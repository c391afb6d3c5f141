"""Simulated cameras added to a scene at load time with ``mujoco.MjSpec``.

A :class:`CameraSpec` says where a simulated camera sits (metres, in the world or on the
gripper), where it looks and its field of view; :data:`PRESET_CAMERAS` has ``front`` (in front
of the arm, looking back at it and the space it works in, like the usual LeRobot table set-up)
and ``wrist`` (on the gripper, looking along the jaws at what they grasp, like the common SO-101
wrist-camera mount). :func:`so101sim.scenes.build_model` compiles a scene with them; the
``draft`` render preset finds the same scene with simplified meshes
(:func:`so101sim.scenes.scene_builder`).

Frames come from :class:`so101sim.recording.FrameRenderer` with ``camera=<name>``; the
robot's cameras (:class:`so101sim.robot.SO101SimFollower`) are built on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from ..errors import CameraError, ModelError
from ..validation import check_count, check_range

MAX_CAMERA_PIXELS = 4096
"""The largest camera width or height accepted, in pixels."""

CAMERA_BODIES = ("world", "gripper")
"""Where a camera can be mounted: fixed in the world, or on the gripper (moves with it)."""


@dataclass(frozen=True)
class CameraSpec:
    """A simulated camera: ``pos`` (metres) in the frame of ``body`` ("world" or "gripper"),
    looking at ``lookat`` (same frame), ``up`` the direction that is up in the picture,
    vertical field of view ``fovy`` (degrees), and the frames it delivers (``width`` ×
    ``height`` at ``fps``)."""

    name: str
    pos: tuple[float, float, float]
    lookat: tuple[float, float, float]
    body: str = "world"
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    fovy: float = 60.0
    width: int = 640
    height: int = 480
    fps: float = 30.0

    def validated(self) -> CameraSpec:
        """Return self if every field is valid, else raise CameraError saying what to use."""
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise CameraError(
                f"camera name {self.name!r} is not valid; expected a name of letters, digits "
                "and underscores, such as 'front'"
            )
        if self.body not in CAMERA_BODIES:
            raise CameraError(
                f"camera {self.name!r}: body = {self.body!r}; expected one of "
                f"{', '.join(CAMERA_BODIES)}"
            )
        for what in ("pos", "lookat", "up"):
            v = getattr(self, what)
            if len(v) != 3:
                raise CameraError(f"camera {self.name!r}: {what} = {v!r}; expected 3 numbers")
            for x in v:
                check_range(
                    x, f"camera {self.name!r} {what}", low=-100, high=100, error=CameraError
                )
        if np.linalg.norm(np.subtract(self.lookat, self.pos)) < 1e-6:
            raise CameraError(f"camera {self.name!r} looks at its own position; move lookat")
        check_range(self.fovy, f"camera {self.name!r} fovy", low=1, high=170, error=CameraError)
        for what in ("width", "height"):
            check_count(
                getattr(self, what),
                f"camera {self.name!r} {what}",
                minimum=16,
                maximum=MAX_CAMERA_PIXELS,
                unit=" pixels",
                error=CameraError,
            )
        check_range(self.fps, f"camera {self.name!r} fps", low=1, high=240, error=CameraError)
        return self

    def xyaxes(self) -> tuple[float, ...]:
        """The camera frame's x (right) and y (up) axes in its body's frame: MuJoCo cameras
        look along their -z axis."""
        forward = np.subtract(self.lookat, self.pos, dtype=float)
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, self.up)
        if np.linalg.norm(right) < 1e-9:  # looking straight along "up": pick another up
            right = np.cross(forward, (1.0, 0.0, 0.0))
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        return (*right.tolist(), *up.tolist())


WRIST_LENS_M = (0.0025, 0.0609, 0.0120)
"""Where the wrist camera's lens sits in the gripper's frame (metres): the centre of the lens
hole of the SO-ARM100 repository's 32x32 UVC wrist mount (docs/cameras.md)."""
WRIST_AXIS = (0.0087, -0.4616, -0.8870)
"""The wrist camera's viewing direction in the gripper's frame: the mount's plate normal."""

PRESET_CAMERAS: dict[str, CameraSpec] = {
    # a USB webcam on the table in front of the arm, looking back at it (docs/cameras.md)
    "front": CameraSpec("front", pos=(0.5, 0.0, 0.42), lookat=(0.15, 0.0, 0.02), fovy=52.0),
    # the SO-ARM100 repository's 32x32 UVC wrist mount: the lens 61 mm beside the roll axis,
    # 12 mm behind the wrist-roll part, looking along the jaws, tilted 27.5 deg towards them
    "wrist": CameraSpec(
        "wrist",
        body="gripper",
        pos=WRIST_LENS_M,
        lookat=tuple(p + 0.1 * n for p, n in zip(WRIST_LENS_M, WRIST_AXIS, strict=True)),
        up=(0.0, 1.0, 0.0),
        fovy=75.0,
    ),
}
"""The cameras a config can name without saying where they are."""


def camera(name: str, **overrides: object) -> CameraSpec:
    """A preset camera (``front``, ``wrist``) with some fields changed, or a new camera when
    ``pos`` and ``lookat`` are given; validated."""
    if name in PRESET_CAMERAS:
        return replace(PRESET_CAMERAS[name], name=name, **overrides).validated()  # type: ignore[arg-type]
    if "pos" not in overrides or "lookat" not in overrides:
        raise CameraError(
            f"camera {name!r} is not a preset; give its pos and lookat (metres), or use one "
            f"of the presets {', '.join(PRESET_CAMERAS)}"
        )
    return CameraSpec(name=name, **overrides).validated()  # type: ignore[arg-type]


def add_camera(spec: mujoco.MjSpec, cam: CameraSpec) -> None:
    """Add ``cam`` to ``spec`` on its body (the world, or the gripper)."""
    if cam.body == "world":
        parent = spec.worldbody
    else:
        parent = spec.body(cam.body)
        if parent is None:
            raise ModelError(f"the model has no body {cam.body!r} to mount camera {cam.name!r}")
    c = parent.add_camera()
    c.name = cam.name
    c.pos = list(cam.pos)
    c.alt.type = mujoco.mjtOrientation.mjORIENTATION_XYAXES
    c.alt.xyaxes = list(cam.xyaxes())
    c.fovy = cam.fovy


def check_camera_names(spec: mujoco.MjSpec, cameras: tuple[CameraSpec, ...]) -> None:
    """Raise CameraError if two cameras share a name or one takes a name the model has."""
    names = [c.name for c in cameras]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise CameraError(f"camera {sorted(dup)[0]!r} is given twice; camera names must differ")
    for cam in cameras:
        if spec.camera(cam.name) is not None:
            raise CameraError(f"the model already has a camera {cam.name!r}; choose another name")


def camera_names(model: mujoco.MjModel) -> list[str]:
    """The named cameras of a model."""
    names = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, i) for i in range(model.ncam))
    return [n for n in names if n]


def fovy_to_focal(fovy: float, height: int) -> float:
    """The focal length in pixels of a camera with vertical field of view ``fovy`` degrees."""
    return height / (2 * math.tan(math.radians(fovy) / 2))
