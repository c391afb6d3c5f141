"""The private model a video is drawn with (:func:`render_model`), and the ``draft`` preset's
simplified meshes: their manifest, matching a model to the file its draft version comes from
(:func:`draft_source`, by file or by a content fingerprint), and building that draft version
(the model builder's recipe of the file or scene, with the draft meshes as an
:class:`~so101sim.model.build.Addition`, made each time: this module keeps its own caches).

The ``draft`` preset swaps the visual meshes for simplified ones shipped in
``so101sim/data/draft_meshes`` (about 5000 triangles each), or, for frames no larger than
:data:`SMALL_FRAME_PX` on their longer side (the images a policy is trained on), in
``so101sim/data/draft_meshes_small`` (about 800: a CPU rasteriser draws such a frame about
twice as fast, and at that size the two sets look alike), and turns off multisampling and
reflections (the renderer turns off shadows); ``full`` keeps the model's look. The physics
model is never changed.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import hashlib
import json
import logging
import threading
import weakref
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..errors import ModelError, SettingError
from ..model.arm import OFFICIAL
from ..model.build import Addition, ModelRecipe, build, recipe, recipe_of
from ..model.load import load_model, loaded_models, model_dir, model_source
from ..model.trim import is_physics_only
from ..scenes import scene_builder
from .settings import check_quality

log = logging.getLogger(__name__)

SMALL_FRAME_PX = 256
"""Frames whose longer side is at most this many pixels are drawn with the smaller meshes."""

COLLISION_GROUP = 3
"""The shipped model's collision mesh geoms are in this geom group (never drawn); a scene's
own mesh objects (drawn and colliding, in group 0) are kept."""
SHIPPED_MODEL_FILES = ("scene.xml", "so101_new_calib.xml", "so101_old_calib.xml")
"""The shipped MJCF files, in :func:`so101sim.model.model_dir`."""

# What drawing a model's state depends on: its tree, geoms, materials, meshes, cameras, lights.
_DRAWN_FIELDS = (
    "body_parentid", "body_pos", "body_quat", "body_ipos", "body_iquat",
    "jnt_type", "jnt_bodyid", "jnt_pos", "jnt_axis",
    "geom_type", "geom_bodyid", "geom_pos", "geom_quat", "geom_size", "geom_rgba",
    "geom_group", "geom_matid", "geom_dataid", "geom_contype", "geom_conaffinity",
    "mat_rgba", "mat_texid", "mesh_vertnum", "mesh_facenum", "mesh_vert", "mesh_face",
    "mesh_pos", "mesh_quat", "cam_pos", "cam_quat", "cam_fovy", "light_pos", "light_dir",
    "light_diffuse",
)  # fmt: skip
_fingerprints: weakref.WeakKeyDictionary[mujoco.MjModel, str] = weakref.WeakKeyDictionary()
_render_lock = threading.Lock()
_draft_cache: dict[tuple[str, int, bool], mujoco.MjModel | None] = {}
_scene_drafts: weakref.WeakKeyDictionary[mujoco.MjModel, dict[bool, mujoco.MjModel | None]] = (
    weakref.WeakKeyDictionary()
)


def draft_mesh_dir(small: bool = False) -> Path:
    """The folder of the simplified visual meshes used by the ``draft`` preset (``small``:
    those for frames up to :data:`SMALL_FRAME_PX`)."""
    return (
        Path(__file__).parent.parent / "data" / ("draft_meshes_small" if small else "draft_meshes")
    )


@functools.cache
def _draft_manifest(small: bool = False) -> dict[str, dict[str, Any]]:
    path = draft_mesh_dir(small) / "manifest.json"
    if not path.is_file():
        return {}
    return json.loads(path.read_text())["meshes"]


@functools.cache
def _sha256(path: str, mtime_ns: int) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


# ---------------------------------------------------------------------------- compiling a draft
def _has_draft(spec: mujoco.MjSpec, mesh: Any, small: bool = False) -> bool:
    """Whether the manifest has a draft of ``mesh`` made from this very file (by SHA-256)."""
    entry = _draft_manifest(small).get(Path(mesh.file).name)
    original = Path(spec.modelfiledir or ".") / (spec.meshdir or "") / mesh.file
    if entry is None or not original.is_file():
        return False
    return _sha256(str(original), original.stat().st_mtime_ns) == entry["original_sha256"]


def _add_draft_meshes(spec: mujoco.MjSpec, small: bool = False) -> dict[str, str]:
    """Add the draft version of each mesh that has one; return {mesh name: draft mesh name}."""
    swapped: dict[str, str] = {}
    for mesh in [m for m in spec.meshes if _has_draft(spec, m, small)]:
        draft = spec.add_mesh()
        draft.name = f"{mesh.name}__draft"
        draft.file = str(draft_mesh_dir(small) / Path(mesh.file).name)
        draft.scale = mesh.scale
        swapped[mesh.name] = draft.name
    return swapped


def _use_draft_meshes(spec: mujoco.MjSpec, swapped: dict[str, str]) -> None:
    """Point the visual mesh geoms at their drafts and drop the collision mesh geoms (group 3,
    never drawn; a scene's mesh objects, drawn and colliding, stay)."""
    for geom in list(spec.geoms):
        if geom.type != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        if (geom.contype or geom.conaffinity) and geom.group == COLLISION_GROUP:
            spec.delete(geom)
        elif geom.meshname in swapped:
            geom.meshname = swapped[geom.meshname]


def _delete_unused_meshes(spec: mujoco.MjSpec) -> None:
    used = {g.meshname for g in spec.geoms}
    for mesh in [m for m in spec.meshes if m.name not in used]:
        spec.delete(mesh)


class _NoDraft(Exception):
    """No mesh of the spec has a shipped draft version (raised by the draft's edit, inside the
    builder, and caught by :func:`_build_draft`: nothing to build)."""


def _draft_meshes(spec: mujoco.MjSpec, small: bool) -> None:
    """The draft edit: visual mesh geoms use the shipped simplified meshes whose originals
    match (by SHA-256), collision geoms are left out."""
    swapped = _add_draft_meshes(spec, small)
    if not swapped:
        raise _NoDraft
    _use_draft_meshes(spec, swapped)
    _delete_unused_meshes(spec)


def _build_draft(r: ModelRecipe, small: bool = False) -> mujoco.MjModel | None:
    """The draft version of recipe ``r`` (a file, or a scene's recipe), built by the model
    builder each time (``keep=False``: this module caches it), for drawing only; None if no
    mesh has a draft version."""
    draft = Addition(
        "draft-small" if small else "draft", functools.partial(_draft_meshes, small=small)
    )
    try:
        return build(dataclasses.replace(r, keep=False).with_additions(draft))
    except _NoDraft:
        return None


def _compile_draft(source: Path, small: bool = False) -> mujoco.MjModel | None:
    """The draft version of the file ``source`` as it is (its own actuators: drawing only), or
    None if nothing matches."""
    return _build_draft(recipe(source, arm=OFFICIAL), small)


def _cached_draft(source: Path, small: bool = False) -> mujoco.MjModel | None:
    """The draft version of ``source``, compiled once per file version (None: none)."""
    key = (str(source), source.stat().st_mtime_ns, small)
    with _render_lock:
        if key not in _draft_cache:
            try:
                _draft_cache[key] = _compile_draft(source, small)
            except ModelError as exc:  # keep the model's meshes
                log.warning("draft meshes not used for %s: %s", source, exc)
                _draft_cache[key] = None
        return _draft_cache[key]


# ---------------------------------------------------------------------------- matching a model
def _drawing_fingerprint(model: mujoco.MjModel, *, cache: bool = False) -> str:
    """A content hash of everything that drawing ``model`` depends on (compiled mesh data
    included): two models with the same fingerprint draw the same pictures."""
    if cache and model in _fingerprints:
        return _fingerprints[model]
    h = hashlib.sha256(bytes(model.names))
    h.update(np.array([model.nq, model.nbody, model.ngeom, model.nmesh, model.nmat]).tobytes())
    for name in _DRAWN_FIELDS:
        h.update(np.ascontiguousarray(getattr(model, name)).tobytes())
    out = h.hexdigest()
    if cache:
        _fingerprints[model] = out
    return out


def _shipped_meshes(model: mujoco.MjModel) -> list[str]:
    """The model's meshes that are shipped SO-101 meshes with a draft version: same name
    and same number of faces as the original in the draft manifest."""
    manifest = _draft_manifest()
    out = []
    for i in range(model.nmesh):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MESH, i) or ""
        entry = manifest.get(f"{name}.stl")
        if entry is not None and int(model.mesh_facenum[i]) == entry["original_faces"]:
            out.append(name)
    return out


def _same_drawing(fingerprint: str) -> Path | None:
    """The file of a model ``load_model`` compiled, or of a shipped model, that draws as
    ``fingerprint`` says; None if there is none."""
    seen: set[Path] = set()
    for path, loaded in loaded_models():
        seen.add(path)
        if _drawing_fingerprint(loaded, cache=True) == fingerprint:
            return path
    for name in SHIPPED_MODEL_FILES:
        path = (model_dir() / name).resolve()
        if path in seen or not path.is_file():
            continue
        if _drawing_fingerprint(load_model(path), cache=True) == fingerprint:
            return path
    return None


def draft_source(model: mujoco.MjModel) -> tuple[Path | None, str]:
    """The MJCF file whose draft version draws ``model``, and why not if there is none.

    A model compiled by :func:`so101sim.model.load_model` is its file. Any other model (one
    compiled by ``mujoco.MjModel.from_xml_path`` directly, or a ``copy.copy`` of a loaded
    model) is matched by content, compiled mesh data included, against the models
    ``load_model`` has compiled and the shipped files (:data:`SHIPPED_MODEL_FILES`).
    """
    source = model_source(model)
    if source is not None:
        return source, ""
    if not _shipped_meshes(model):
        return None, (
            "none of its meshes is a shipped SO-101 mesh with a draft version (compared by "
            f"mesh name and face count with {draft_mesh_dir() / 'manifest.json'})"
        )
    source = _same_drawing(_drawing_fingerprint(model))
    if source is not None:
        return source, ""
    return None, (
        "it uses the shipped SO-101 meshes but was not compiled by so101sim.load_model(), and "
        "its bodies, geoms, materials or meshes differ from every model load_model() has "
        f"compiled and from the shipped {', '.join(SHIPPED_MODEL_FILES)} (changed after "
        "loading?); load the file with so101sim.load_model(path) to get the draft meshes"
    )


# ---------------------------------------------------------------------------- render models
def _draft_model(model: mujoco.MjModel, small: bool = False) -> mujoco.MjModel:
    """The draft version of ``model`` with the same bodies and joints, else ``model`` itself
    (with a logged warning saying why)."""
    scene = recipe_of(model) if scene_builder(model) is not None else None
    if scene is not None:  # a scene built with MjSpec (cameras, objects): rebuild it
        with _render_lock:
            drafts = _scene_drafts.setdefault(model, {})
            if small not in drafts:
                drafts[small] = _build_draft(scene, small)
            draft = drafts[small]
        if draft is not None and (draft.nq, draft.nbody) == (model.nq, model.nbody):
            return draft
    source, why = draft_source(model)
    if source is not None:
        draft = _cached_draft(source, small)
        if draft is not None and (draft.nq, draft.nbody) == (model.nq, model.nbody):
            return draft
        why = f"no shipped simplified mesh matches the meshes of {source}"
    log.warning(
        "draft preset: falling back to the model's own meshes (slower to draw on a "
        "CPU renderer; shadows and reflections are still off) because %s",
        why,
    )
    return model


def _drawable(model: mujoco.MjModel) -> mujoco.MjModel:
    """``model``, or for a physics-only model (no visual geoms) the full model of its file,
    which has the same bodies and joints."""
    if not is_physics_only(model):
        return model
    source = model_source(model)
    if source is None:
        raise SettingError(
            "this model was loaded with physics_only=True: it has no visual geoms to draw;"
            " load it with so101sim.load_model(path) to draw it"
        )
    return load_model(source)


def render_model(model: mujoco.MjModel, quality: str, width: int, height: int) -> mujoco.MjModel:
    """A private model to draw ``model``'s state with, at ``quality``, its offscreen buffer at
    least ``width`` × ``height``. Same bodies and joints as ``model``; the physics model itself
    is never changed.

    ``draft``: the simplified visual meshes (the smaller set for frames up to
    :data:`SMALL_FRAME_PX`; when ``model`` is, or draws the same as, a model
    compiled from a file whose meshes they were made from: see :func:`draft_source`), no
    multisampling, no reflections (shadows are turned off by the renderer); otherwise the
    model's own meshes, with a logged warning. ``full``: a copy of ``model`` as it is.
    """
    check_quality(quality)
    model = _drawable(model)
    small = max(width, height) <= SMALL_FRAME_PX
    rm = copy.copy(_draft_model(model, small) if quality == "draft" else model)
    rm.vis.global_.offwidth = max(int(rm.vis.global_.offwidth), width)
    rm.vis.global_.offheight = max(int(rm.vis.global_.offheight), height)
    if quality == "draft":
        rm.vis.quality.offsamples = 0
        rm.mat_reflectance[:] = 0.0
    return rm
