"""Framing a video: a free camera fitted to the space the arm sweeps during a run.

A camera view is MuJoCo's free camera (``lookat``, ``distance``, ``azimuth``, ``elevation``; the
model's vertical field of view). :func:`fit_view` takes the arm's joint positions at every frame
of a run and returns the view, for a given direction, that keeps every body of the arm inside
the frame with a margin; :func:`project` says where points land in a frame (the tests use it).

Directions: azimuth 0° looks along +x, 90° along +y; the SO-101 reaches towards +x, so
``front`` (azimuth 180°) faces it. Named views: ``front``, ``side`` (from the arm's right),
``top``, and ``default`` (azimuth 160°, elevation −20°: the viewer's opening view).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

import mujoco
import numpy as np

from ..errors import SettingError
from ..model.load import arm_index, arm_units
from ..validation import check_choice, check_range

ViewName = Literal["default", "front", "side", "top"]
"""The named views of a video's free camera (:data:`NAMED_VIEWS`)."""

NAMED_VIEWS: dict[str, tuple[float, float]] = {
    "default": (160.0, -20.0),
    "front": (180.0, -15.0),
    "side": (90.0, -10.0),
    "top": (180.0, -89.0),
}
"""View name -> (azimuth, elevation) in degrees."""

MARGIN = 0.08
"""Fraction of the half-frame kept free around the arm by :func:`fit_view`."""


@dataclass(frozen=True)
class CameraView:
    """A free camera: where it looks (metres, world frame), from how far (metres), and from
    which direction (degrees)."""

    lookat: tuple[float, float, float]
    distance: float
    azimuth: float
    elevation: float

    def apply(self, cam: mujoco.MjvCamera) -> None:
        """Set an ``MjvCamera`` (or a viewer's ``cam``) to this view."""
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self.lookat
        cam.distance = self.distance
        cam.azimuth = self.azimuth
        cam.elevation = self.elevation


def view_direction(name: ViewName) -> tuple[float, float]:
    """(azimuth, elevation) of a named view; SettingError lists the names."""
    return NAMED_VIEWS[check_choice(name, "view", NAMED_VIEWS)]


def _axes(azimuth: float, elevation: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The camera's forward, right and up unit vectors (MuJoCo's free-camera convention)."""
    a, e = math.radians(azimuth), math.radians(elevation)
    forward = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    up = np.array([-math.sin(e) * math.cos(a), -math.sin(e) * math.sin(a), math.cos(e)])
    return forward, np.cross(forward, up), up


def project(view: CameraView, points: np.ndarray, aspect: float, fovy: float = 45.0) -> np.ndarray:
    """Where ``points`` (N, 3) land in a frame of ``aspect`` = width / height, as (N, 2)
    coordinates from -1 (left, bottom) to 1 (right, top); beyond ±1 is outside the frame.
    Points behind the camera get ``inf``."""
    forward, right, up = _axes(view.azimuth, view.elevation)
    cam = np.asarray(view.lookat) - view.distance * forward
    rel = np.asarray(points, dtype=float).reshape(-1, 3) - cam
    depth = rel @ forward
    t = math.tan(math.radians(fovy) / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (rel @ right) / (depth * t * aspect)
        y = (rel @ up) / (depth * t)
    out = np.stack([x, y], axis=1)
    out[depth <= 1e-6] = np.inf
    return out


def arm_points(model: mujoco.MjModel, qpos_frames: Iterable[np.ndarray]) -> np.ndarray:
    """Points that outline the arm (and any other body) at each of ``qpos_frames`` (full
    ``qpos`` vectors): the origin of every body but the world and the eight corners of each of
    their geoms' bounding boxes (MuJoCo's ``geom_aabb``, in the geom's frame: tighter than its
    bounding sphere around a long part, so the fitted camera comes as close as the parts allow).
    Returns an (N, 3) array."""
    data = mujoco.MjData(model)
    bodies = np.arange(1, model.nbody)  # every body but the world (the floor is the world's)
    geoms = np.flatnonzero(model.geom_bodyid != 0)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    aabb = model.geom_aabb[geoms].reshape(-1, 6)
    corners = aabb[:, None, :3] + signs[None] * aabb[:, None, 3:]  # (geoms, 8, 3), geom frame
    chunks = []
    for q in qpos_frames:
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        chunks.append(data.xpos[bodies])
        if len(geoms):
            rot = data.geom_xmat[geoms].reshape(-1, 3, 3)
            world = data.geom_xpos[geoms][:, None, :] + np.einsum("gij,gkj->gki", rot, corners)
            chunks.append(world.reshape(-1, 3))
    return np.vstack(chunks) if chunks else np.zeros((0, 3))


WORKSPACE_SAMPLES = 200
"""Random poses :func:`workspace_frames` samples when the run's sweep is not known."""


def workspace_frames(model: mujoco.MjModel, samples: int = WORKSPACE_SAMPLES) -> list[np.ndarray]:
    """``qpos`` vectors of random in-limit arm poses (seeded: the same every time), standing in
    for the run's sweep when it is not known before the run (a script recorded as it runs):
    a view fitted to them keeps the arm in frame whatever it does."""
    idx = arm_index(model)
    rng = np.random.default_rng(0)
    frames = []
    for _ in range(samples):
        q = model.qpos0.copy()
        q[idx.qpos] = rng.uniform(idx.lower, idx.upper)
        frames.append(q)
    return frames


def sweep_frames(model: mujoco.MjModel, targets: np.ndarray, every: int = 25) -> list[np.ndarray]:
    """``qpos`` vectors for every ``every``-th row of ``targets`` (arm units, (n, 6), e.g. a
    motion's commanded path) and the last: the sweep of a run known before it runs."""
    idx = arm_index(model)
    units = arm_units(model)
    rows = np.asarray(targets, dtype=float)[[*range(0, len(targets), every), -1]]
    frames = []
    for q_arm in units.to_radians(rows):
        q = model.qpos0.copy()
        q[idx.qpos] = q_arm
        frames.append(q)
    return frames


def body_positions(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """The origins of every body but the world at joint positions ``qpos``: (nbody - 1, 3)."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    return data.xpos[1:].copy()


def fit_view(
    points: np.ndarray,
    *,
    aspect: float,
    azimuth: float = NAMED_VIEWS["default"][0],
    elevation: float = NAMED_VIEWS["default"][1],
    fovy: float = 45.0,
    margin: float = MARGIN,
) -> CameraView:
    """The view from (``azimuth``, ``elevation``) that keeps every point inside the frame,
    ``margin`` of the half-frame free at the edges, and as close as that allows."""
    aspect = check_range(aspect, "aspect", low=0.05, high=20.0)
    margin = check_range(margin, "margin", low=0.0, high=0.5)
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    if not len(pts) or not np.isfinite(pts).all():
        raise SettingError("no finite points to frame; expected the arm's positions")
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    lookat = (lo + hi) / 2
    forward, right, up = _axes(azimuth, elevation)
    rel = pts - lookat
    # the frame edge in camera space is |x| <= (1 - margin) * tan(fovy/2) * aspect * depth;
    # solve for the distance each point needs, and take the largest
    t = math.tan(math.radians(fovy) / 2) * (1.0 - margin)
    along = rel @ forward
    need_x = np.abs(rel @ right) / (t * aspect) - along
    need_y = np.abs(rel @ up) / t - along
    distance = float(max(need_x.max(), need_y.max(), np.abs(along).max() + 0.05, 0.05))
    return CameraView(tuple(float(v) for v in lookat), distance, float(azimuth), float(elevation))


def view_for_run(
    model: mujoco.MjModel,
    qpos_frames: Sequence[np.ndarray],
    width: int,
    height: int,
    *,
    azimuth: float | None = None,
    elevation: float | None = None,
    distance: float | None = None,
    lookat: Sequence[float] | None = None,
    view: ViewName = "default",
) -> CameraView:
    """The camera for a video of ``qpos_frames``: the named ``view``'s direction (or the given
    azimuth/elevation), fitted to the arm's sweep; ``distance`` and ``lookat`` override the
    fitted ones."""
    az0, el0 = view_direction(view)
    az = az0 if azimuth is None else check_range(azimuth, "azimuth", low=-360.0, high=360.0)
    el = el0 if elevation is None else check_range(elevation, "elevation", low=-90.0, high=90.0)
    fitted = fit_view(
        arm_points(model, qpos_frames),
        aspect=width / height,
        azimuth=az,
        elevation=el,
        fovy=float(model.vis.global_.fovy),
    )
    if distance is not None:
        distance = check_range(distance, "distance", low=0.01, high=100.0, unit=" m")
    if lookat is not None:
        if len(lookat) != 3:
            raise SettingError(f"lookat = {lookat!r}; expected three numbers X,Y,Z in metres")
        lookat = tuple(check_range(v, "lookat", low=-100.0, high=100.0) for v in lookat)
    return CameraView(
        tuple(lookat) if lookat is not None else fitted.lookat,
        distance if distance is not None else fitted.distance,
        az,
        el,
    )
