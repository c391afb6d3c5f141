"""Infinite planes (the floor) drawn as a few large quads instead of MuJoCo's 200 × 200, for the
``draft`` preset: the same pixels, at about half the cost of a small frame on a CPU renderer.

MuJoCo's classic renderer draws a plane whose two half sizes are 0 as a grid of
``mjMAXPLANEGRID`` × ``mjMAXPLANEGRID`` (200 × 200) quads reaching past the far clipping plane,
and a finite plane as a grid whose spacing is its third size. The quads are lit per vertex, and
under directional lights (the shipped scene's) lighting a plane is linear across it, so the
grid's density changes nothing; but a CPU rasteriser transforms and clips all 160 000 vertices
for every frame: about half the cost of a 160 × 120 camera image.

:func:`finite_planes` gives each infinite plane of a *render model* (a private copy: the physics
model is never touched) the size MuJoCo's renderer draws it at, with a spacing of half that
size, before the renderer's context is made. After each ``mjv_updateScene``,
:func:`as_infinite` puts back what an infinite plane has in the scene and a finite one lacks:
its texture's phase (a finite plane's texture is anchored at its corner, an infinite one's at
its centre: the plane is shifted in its own frame by less than one texture period, which moves
no pixel of the plane itself) and the horizon haze, which MuJoCo draws for the first infinite
plane of the scene (a zero-size infinite plane is added at the floor's place: it covers no
pixel). ``tests/recording/test_floor.py`` checks that the frames stay within one grey level.
"""

from __future__ import annotations

import mujoco
import numpy as np

GRID = 200
"""MuJoCo draws an infinite plane as this many quads along each side (``mjMAXPLANEGRID``)."""
_PLANE = int(mujoco.mjtGeom.mjGEOM_PLANE)
_GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)
_RGB = int(mujoco.mjtTextureRole.mjTEXROLE_RGB)


def _infinite(model: mujoco.MjModel) -> np.ndarray:
    planes = model.geom_type == _PLANE
    return np.flatnonzero(planes & (model.geom_size[:, 0] <= 0) & (model.geom_size[:, 1] <= 0))


def _texture_scale(model: mujoco.MjModel, geom: int) -> np.ndarray:
    """The texture repeat MuJoCo's renderer applies to ``geom`` (1 where it is not > 0)."""
    mat = int(model.geom_matid[geom])
    rep = model.mat_texrepeat[mat] if mat >= 0 else np.zeros(2)
    return np.where(rep > 0, rep, 1.0)


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
    for g in ids:
        mat = int(model.geom_matid[g])
        if mat >= 0 and model.mat_texid[mat, _RGB] >= 0 and not model.mat_texuniform[mat]:
            return ()
    zfar = float(model.vis.map.zfar * model.stat.extent)
    for g in ids:
        mat = int(model.geom_matid[g])
        rep = model.mat_texrepeat[mat] if mat >= 0 else np.zeros(2)
        # MuJoCo's grid step along each side: one texture period, else the grid's own
        step = np.where(rep > 0, 2.0 / np.where(rep > 0, rep, 1.0), 2.1 * zfar / (GRID - 2))
        half = (2.1 * zfar + 2.0 * step) / 2.0
        model.geom_size[g] = [half[0], half[1], float(half.max()) / 2.0]
    return tuple(int(g) for g in ids)


def as_infinite(scene: mujoco.MjvScene, model: mujoco.MjModel, planes: tuple[int, ...]) -> None:
    """After ``mjv_updateScene``: shift each plane of ``planes`` (from :func:`finite_planes` on
    ``model``) so its texture lies where the infinite plane's does, and add the zero-size
    infinite plane that makes MuJoCo draw the horizon haze."""
    if not planes:
        return
    marker = None
    for i in range(scene.ngeom):
        g = scene.geoms[i]
        if g.objtype != _GEOM or g.objid not in planes:
            continue
        half = model.geom_size[g.objid, :2]
        scale = _texture_scale(model, g.objid)
        period = 2.0 / scale
        shift = np.array(
            [(half[0] + 1.0 / scale[0]) % period[0], (-half[1] - 1.0 / scale[1]) % period[1], 0.0]
        )
        rot = np.asarray(g.mat, dtype=float).reshape(3, 3)
        if marker is None:
            marker = (np.array(g.pos, dtype=float), rot.flatten())
        g.pos[:] = g.pos + rot @ shift
    if marker is not None and scene.ngeom < scene.maxgeom:
        mujoco.mjv_initGeom(
            scene.geoms[scene.ngeom],
            _PLANE,
            np.zeros(3),
            marker[0],
            marker[1],
            np.zeros(4, dtype=np.float32),
        )
        scene.ngeom += 1
