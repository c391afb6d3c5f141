"""How the studio's page looks: the model's own floor, sky and lights, the camera framed on the
arm beside the panel, and the panel docked at the side (collapsible) rather than over the arm.

mjviser draws a plane as viser's grey grid on white; :func:`model_floor` draws each plane of
the world instead with its material's texture (the shipped scene's blue checker), tiled as
MuJoCo tiles it, under a sky that fades from the skybox's colour to the model's haze
(:func:`model_sky`), and :func:`model_lights` puts the model's lights and headlight in place of
viser's defaults. Everything here reads the model: a scene with another floor gets its floor.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

FLOOR_SIZE = 8.0  # metres: the side of the floor drawn for an infinite plane
PANEL_WIDTH = 360  # pixels: the panel docked at the right
# The default view: the arm (about 0.45 m tall when raised) seen from the front-left, a little
# to the right of the look-at point so that it sits in the middle of the space the panel leaves
CAMERA_POSITION = (0.46, 0.35, 0.31)
CAMERA_LOOK_AT = (0.10, 0.0, 0.13)


def _rgb(values: Any) -> tuple[int, int, int]:
    r, g, b = (round(255 * float(np.clip(v, 0.0, 1.0))) for v in list(values)[:3])
    return (r, g, b)


def _texture(model: mujoco.MjModel, matid: int) -> np.ndarray | None:
    """The RGB(A) image of a material's 2D texture (top row first), or None."""
    if matid < 0:
        return None
    texid = int(model.mat_texid[matid, int(mujoco.mjtTextureRole.mjTEXROLE_RGB)])
    if texid < 0 or model.tex_type[texid] != int(mujoco.mjtTexture.mjTEXTURE_2D):
        return None
    w, h, nc = int(model.tex_width[texid]), int(model.tex_height[texid]), model.tex_nchannel[texid]
    if nc not in (3, 4):
        return None
    adr = int(model.tex_adr[texid])
    data = np.asarray(model.tex_data[adr : adr + w * h * nc], dtype=np.uint8)
    return np.flipud(data.reshape(h, w, nc))[..., :3]


def floor_mesh(model: mujoco.MjModel, geom: int) -> Any:
    """A trimesh square for plane ``geom``: its material's texture tiled as MuJoCo tiles it
    (``texrepeat`` per metre with ``texuniform``), or its flat colour."""
    # trimesh and PIL come with the optional web extra (viser): only the studio needs them
    import trimesh
    from PIL import Image

    sx, sy = (float(s) for s in model.geom_size[geom][:2])
    half_x = sx if sx > 0 else FLOOR_SIZE / 2
    half_y = sy if sy > 0 else FLOOR_SIZE / 2
    verts = np.array(
        [[-half_x, -half_y, 0], [half_x, -half_y, 0], [half_x, half_y, 0], [-half_x, half_y, 0]]
    )
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    mesh = trimesh.Trimesh(vertices=verts, faces=faces, process=False)
    matid = int(model.geom_matid[geom])
    image = _texture(model, matid)
    rgba = model.mat_rgba[matid] if matid >= 0 else model.geom_rgba[geom]
    if image is None:
        mesh.visual = trimesh.visual.ColorVisuals(
            mesh, face_colors=np.tile(np.asarray(rgba) * 255, (2, 1)).astype(np.uint8)
        )
        return mesh
    repeat = np.asarray(model.mat_texrepeat[matid], dtype=float)
    if not model.mat_texuniform[matid]:  # repeats over the whole plane, not per metre
        repeat = repeat / np.array([2 * half_x, 2 * half_y])
    uv = (verts[:, :2] - verts[0, :2]) * repeat
    material = trimesh.visual.material.PBRMaterial(
        baseColorFactor=np.asarray(rgba, dtype=float),
        baseColorTexture=Image.fromarray(image),
        metallicFactor=0.0,
        roughnessFactor=1.0 - 0.5 * float(model.mat_reflectance[matid]),
    )
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    return mesh


def model_floor(server: Any, model: mujoco.MjModel) -> int:
    """Draw each plane of a fixed body with its own material, in place of mjviser's grid
    (the same scene node's name replaces it); returns the number of planes drawn."""
    # mjviser: the optional web extra, only for the studio
    from mjviser.conversions import get_body_name, is_fixed_body

    drawn = 0
    for g in range(model.ngeom):
        body = int(model.geom_bodyid[g])
        if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE or not is_fixed_body(model, body):
            continue
        geom_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        name = f"/fixed_bodies/{get_body_name(model, body)}/{geom_name}"
        server.scene.add_mesh_trimesh(
            name,
            floor_mesh(model, g),
            cast_shadow=False,
            receive_shadow=0.35,
            position=tuple(model.geom_pos[g]),
            wxyz=tuple(model.geom_quat[g]),
        )
        drawn += 1
    return drawn


def model_sky(server: Any, model: mujoco.MjModel) -> None:
    """The background: the skybox's gradient from its top colour to the model's haze at the
    horizon (MuJoCo's look from a camera a little above the floor), and fog of the haze's
    colour beyond a few metres, so the floor's edge fades as MuJoCo's does."""
    haze = np.asarray(model.vis.rgba.haze[:3], dtype=float)
    column = np.linspace(np.clip(haze * 1.6, 0, 1), haze, 64)  # no skybox: the haze, lighter
    for t in range(model.ntex):
        if model.tex_type[t] == int(mujoco.mjtTexture.mjTEXTURE_SKYBOX):
            # a side face of the cube (+x, top row first): its upper half is the sky from
            # 45 degrees up down to the horizon
            w, nc, adr = int(model.tex_width[t]), int(model.tex_nchannel[t]), int(model.tex_adr[t])
            face = np.asarray(model.tex_data[adr : adr + w * w * nc]).reshape(w, w, nc)
            column = face[: w // 2, w // 2, :3].astype(float) / 255.0
            break
    image = (np.repeat(column[:, None, :], 4, axis=1) * 255).astype(np.uint8)
    server.scene.set_background_image(image, format="png")
    server.scene.configure_fog(2.5, 7.0, color=_rgb(haze))


def model_lights(server: Any, model: mujoco.MjModel, *, shadows: bool = True) -> list[Any]:
    """The model's lights (directional and spot/point) and its headlight (an ambient light and
    a light from the default view) in place of viser's defaults; returns their handles.
    ``shadows=False``: no light casts a shadow (a browser drawing on its CPU, without a GPU,
    then does about a third of the work: no shadow map each frame)."""
    server.scene.configure_default_lights(enabled=False)
    server.scene.configure_environment_map(hdri=None, environment_intensity=0.0)
    head = model.vis.headlight
    lights = [
        server.scene.add_light_ambient(
            "/lights/ambient",
            color=_rgb(np.ones(3)),
            intensity=float(np.mean(head.ambient)) * 2.0,
        )
    ]
    eye = np.asarray(CAMERA_POSITION) - np.asarray(CAMERA_LOOK_AT)
    lights.append(
        server.scene.add_light_directional(
            "/lights/headlight",
            color=_rgb(np.ones(3)),
            intensity=float(np.mean(head.diffuse)) * 2.0,
            wxyz=_pointing(-eye),
            position=tuple(eye * 3),
        )
    )
    for i in range(model.nlight):
        diffuse = float(np.mean(model.light_diffuse[i]))
        direction = np.asarray(model.light_dir[i], dtype=float)
        name = f"/lights/model_{i}"
        lights.append(
            server.scene.add_light_directional(
                name,
                color=_rgb(model.light_diffuse[i] / max(diffuse, 1e-6)),
                intensity=diffuse * 3.0,
                cast_shadow=shadows and bool(model.light_castshadow[i]),
                wxyz=_pointing(direction),
                position=tuple(model.light_pos[i]),
            )
        )
    return lights


def _pointing(direction: np.ndarray) -> tuple[float, float, float, float]:
    """The rotation (wxyz) that turns a directional light's -z (three.js: it shines along its
    local -z towards its target) to ``direction``."""
    d = np.asarray(direction, dtype=float)
    d = d / max(np.linalg.norm(d), 1e-9)
    quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(quat, -d)  # +z to -d, so -z to d
    return (float(quat[0]), float(quat[1]), float(quat[2]), float(quat[3]))


def frame_camera(server: Any) -> None:
    """The first view of the page: the whole arm, beside the panel."""
    cam = server.initial_camera
    cam.position = CAMERA_POSITION
    cam.look_at = CAMERA_LOOK_AT
    cam.up = (0.0, 0.0, 1.0)


def place_panel(server: Any) -> None:
    """Dock the panel at the right edge (the 3D view beside it, not under it); a docked
    panel collapses with its own button."""
    panel = server.gui.main_panel
    panel.dock_right()
    panel.set_width(PANEL_WIDTH)


def dress(server: Any, model: mujoco.MjModel, *, shadows: bool = True) -> list[Any]:
    """The model's floor, sky and lights (``shadows``: see :func:`model_lights`); the camera on
    the arm; the panel at the side. Returns the lights' handles."""
    model_floor(server, model)
    model_sky(server, model)
    lights = model_lights(server, model, shadows=shadows)
    frame_camera(server)
    place_panel(server)
    return lights
