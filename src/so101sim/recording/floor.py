"""Infinite planes (the floor) drawn as a few large quads instead of MuJoCo's 200 × 200, for the
``draft`` preset: nearly the same pixels, at about half the cost of a small frame on a CPU
renderer.

MuJoCo's classic renderer draws a plane whose two half sizes are 0 as a grid of
``mjMAXPLANEGRID`` × ``mjMAXPLANEGRID`` (200 × 200) quads reaching past the far clipping plane,
moved under the camera in steps of two texture periods at each ``mjv_updateScene``, and a
finite plane as a grid whose spacing is its third size. A CPU rasteriser transforms all
160 000 vertices for every frame: about half the cost of a 160 × 120 camera image. The quads
are lit per vertex; under directional lights a plane's diffuse light is the same all over it,
so the grid's density changes nothing there. What it does change: the specular highlight
(lit per vertex on either grid: it differs where a camera looks almost straight down on the
bare floor) and which of two surfaces in the floor's own plane wins the depth test.

:func:`finite_planes` gives each infinite plane of a *render model* (a private copy: the physics
model is never touched) the size MuJoCo's renderer draws it at, with a spacing of half that
size, before the renderer's context is made; it changes nothing in a model with a point or
spot light (their light falls off across the plane) or a plane whose texture is not a
``texuniform`` 2-D one. After each ``mjv_updateScene``, :func:`as_infinite` puts back what an
infinite plane has in the scene and a finite one lacks: MuJoCo's re-centring under the camera,
its texture's phase (a finite plane's texture is anchored at its corner, an infinite one's at
its centre: the plane is shifted in its own frame by less than one texture period, which moves
no pixel of the plane itself) and the horizon haze, which MuJoCo draws for the first infinite
plane of the scene (a zero-size infinite plane is added at the floor's place: it covers no
pixel). ``tests/recording/test_floor.py`` compares the frames with MuJoCo's own grid.
"""

from __future__ import annotations

import logging
import math

import mujoco
import numpy as np

GRID = 200
"""MuJoCo draws an infinite plane as this many quads along each side (``mjMAXPLANEGRID``)."""
_PLANE = int(mujoco.mjtGeom.mjGEOM_PLANE)
_GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)
_RGB = int(mujoco.mjtTextureRole.mjTEXROLE_RGB)
_TEX2D = int(mujoco.mjtTexture.mjTEXTURE_2D)
_DIRECTIONAL = int(mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
log = logging.getLogger(__name__)


def _infinite(model: mujoco.MjModel) -> np.ndarray:
    planes = model.geom_type == _PLANE
    return np.flatnonzero(planes & (model.geom_size[:, 0] <= 0) & (model.geom_size[:, 1] <= 0))


def finite_planes(model: mujoco.MjModel) -> tuple[int, ...]:
    """Give each infinite plane of the render model ``model`` the finite size MuJoCo's renderer
    draws it at (in place; call it before the renderer's context is made) and return their geom
    ids, for :func:`as_infinite`. Nothing is changed (and ``()`` returned) when a plane's texture
    is not ``texuniform`` (its phase could not be matched) or a plane is infinite along only one
    side."""
    planes = model.geom_type == _PLANE
    half_infinite = planes & ((model.geom_size[:, 0] <= 0) != (model.geom_size[:, 1] <= 0))
    ids = _infinite(model)
    if half_infinite.any() or not len(ids):
        return ()
    if (model.light_type != _DIRECTIONAL).any():
        return ()  # a point or spot light's falls off across the plane: per vertex, it matters
    for g in ids:
        mat = int(model.geom_matid[g])
        tex = int(model.mat_texid[mat, _RGB]) if mat >= 0 else -1
        if tex >= 0 and (model.tex_type[tex] != _TEX2D or not model.mat_texuniform[mat]):
            return ()
    zfar = float(model.vis.map.zfar * model.stat.extent)
    for g in ids:
        half = (2.1 * zfar + 2.0 * _grid_step(model, g)) / 2.0  # MuJoCo's grid's extent
        model.geom_size[g] = [half[0], half[1], float(half.max()) / 2.0]
    return tuple(int(g) for g in ids)


def _grid_step(model: mujoco.MjModel, geom: int) -> np.ndarray:
    """MuJoCo's step for an infinite plane's grid along each side: one texture period (2 /
    texrepeat), else 1/198 of the grid's width."""
    mat = int(model.geom_matid[geom])
    rep = model.mat_texrepeat[mat] if mat >= 0 else np.zeros(2)
    zfar = float(model.vis.map.zfar * model.stat.extent)
    return np.where(rep > 0, 2.0 / np.where(rep > 0, rep, 1.0), 2.1 * zfar / (GRID - 2))


def head(scene: mujoco.MjvScene) -> np.ndarray:
    """The scene's camera position (the middle of its two eyes)."""
    return 0.5 * (np.asarray(scene.camera[0].pos, float) + np.asarray(scene.camera[1].pos, float))


def as_infinite(scene: mujoco.MjvScene, model: mujoco.MjModel, planes: tuple[int, ...]) -> None:
    """After ``mjv_updateScene``: move each plane of ``planes`` (from :func:`finite_planes` on
    ``model``) where MuJoCo puts an infinite plane (under the camera, in steps of two grid
    steps) with its texture where the infinite plane's is, and add the zero-size infinite
    plane that makes MuJoCo draw the horizon haze.

    MuJoCo re-centres under the camera of the *previous* update (``mjv_updateScene`` updates
    the camera after the geoms); this uses this update's camera, so that a frame depends only
    on the state and the camera drawn, not on what was drawn before (a grid moved by two
    steps rounds the shading of some pixels a grey level the other way)."""
    if not planes:
        return
    camera = head(scene)
    marker = None
    found = 0
    for i in range(scene.ngeom):
        g = scene.geoms[i]
        gid = g.objid
        if gid not in planes or g.objtype != _GEOM:
            continue
        pos = np.asarray(g.pos, dtype=float)
        rot = np.asarray(g.mat, dtype=float).reshape(3, 3)  # columns: the plane's axes
        if marker is None:
            marker = (pos.copy(), rot.flatten())
        mat = int(model.geom_matid[gid])
        coarse = 2.1 * float(model.vis.map.zfar * model.stat.extent) / (GRID - 2)
        along = rot[:, :2].T @ (camera - pos)  # the camera from the plane, on its two axes
        offset = []
        for k, sign in ((0, 1.0), (1, -1.0)):  # along each of the plane's two axes
            # the texture repeat and the grid step as _grid_step gives them (float32 from a
            # material, as MuJoCo keeps its repeat), then the arithmetic in float64
            if mat >= 0:
                rep = model.mat_texrepeat[mat, k]
                scale = rep if rep > 0 else np.float32(1.0)
                step = float(2.0 / scale) if rep > 0 else float(np.float32(coarse))
            else:
                scale, step = 1.0, coarse
            phase = (sign * model.geom_size[gid, k] + sign / scale) % (2.0 / scale)
            centre = 2.0 * step * math.floor(0.5 * along[k] / step + 0.5)  # MuJoCo's re-centring
            offset.append(centre + phase)
        g.pos[:] = pos + rot[:, :2] @ np.asarray(offset)
        found += 1
        if found == len(planes):
            break
    if marker is None:
        return
    if scene.ngeom >= scene.maxgeom:
        log.debug("the scene is full (%d geoms): the horizon haze is not drawn", scene.maxgeom)
        return
    haze = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(haze, _PLANE, np.zeros(3), marker[0], marker[1], np.zeros(4, np.float32))
    haze.objtype, haze.objid, haze.segid = int(mujoco.mjtObj.mjOBJ_UNKNOWN), -1, -1
    haze.category = int(mujoco.mjtCatBit.mjCAT_DECOR)
    scene.ngeom += 1
