"""Tests of so101sim.recording.draft: the render model and the draft preset's meshes."""

from __future__ import annotations

import copy
import json
import logging

import mujoco
import numpy as np
import pytest

from so101sim import Simulation, scene_path
from so101sim import recording as rec
from so101sim.model import load_model, model_source


def test_draft_uses_fewer_visual_triangles_and_keeps_the_bodies():
    sim = Simulation()
    full = rec.render_model(sim.model, "full", 640, 480)
    draft = rec.render_model(sim.model, "draft", 640, 480)
    assert (draft.nq, draft.nbody, draft.njnt) == (full.nq, full.nbody, full.njnt)

    def drawn_faces(m: mujoco.MjModel) -> int:
        visual = [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH]
        visual = [g for g in visual if m.geom_group[g] == 2]
        return sum(int(m.mesh_facenum[m.geom_dataid[g]]) for g in visual)

    assert drawn_faces(draft) < drawn_faces(full) / 5
    assert draft.vis.quality.offsamples == 0
    assert full.vis.quality.offsamples == sim.model.vis.quality.offsamples


def test_small_frames_are_drawn_with_the_smaller_meshes():
    from so101sim.recording.draft import SMALL_FRAME_PX

    sim = Simulation()

    def faces(m: mujoco.MjModel) -> int:
        return sum(int(m.mesh_facenum[i]) for i in range(m.nmesh))

    big = rec.render_model(sim.model, "draft", 640, 480)
    small = rec.render_model(sim.model, "draft", 128, 96)
    edge = rec.render_model(sim.model, "draft", SMALL_FRAME_PX, SMALL_FRAME_PX)
    assert (small.nq, small.nbody) == (big.nq, big.nbody)
    assert faces(small) < faces(big) / 3
    assert faces(edge) == faces(small)
    full_small = rec.render_model(sim.model, "full", 128, 96)  # "full" keeps the model's look
    assert faces(full_small) == faces(rec.render_model(sim.model, "full", 640, 480))


@pytest.mark.parametrize("small", [False, True], ids=["draft", "small"])
def test_shipped_draft_meshes_match_their_manifest(small):
    folder = rec.draft_mesh_dir(small)
    manifest = json.loads((folder / "manifest.json").read_text())["meshes"]
    stls = sorted(p.name for p in folder.glob("*.stl"))
    assert stls == sorted(manifest)
    total = 0
    for name, entry in manifest.items():
        data = (folder / name).read_bytes()
        faces = int(np.frombuffer(data, np.uint32, 1, 80)[0])
        assert faces == entry["faces"] <= entry["original_faces"]
        total += len(data)
    assert total < 3_000_000


def _draws_draft_meshes(m: mujoco.MjModel) -> bool:
    names = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_MESH, i) for i in range(m.nmesh)}
    return bool(names) and all(n.endswith("__draft") for n in names)


@pytest.mark.parametrize(
    "make",
    [
        pytest.param(lambda: mujoco.MjModel.from_xml_path(str(scene_path())), id="from_xml_path"),
        pytest.param(lambda: copy.copy(load_model()), id="copy"),
    ],
)
def test_draft_recognises_the_shipped_model_however_it_was_compiled(make, caplog):
    model = make()
    assert model_source(model) is None  # not the object load_model() returned
    with caplog.at_level(logging.WARNING, logger="so101sim.recording"):
        rm = rec.render_model(model, "draft", 64, 48)
    assert _draws_draft_meshes(rm)
    assert (rm.nq, rm.nbody) == (model.nq, model.nbody)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


def test_draft_warns_when_it_falls_back_to_the_models_own_meshes(caplog):
    edited = copy.copy(load_model())
    edited.geom_rgba[:, :3] = (0.9, 0.1, 0.1)  # edited after loading: drawn in red now
    with caplog.at_level(logging.WARNING, logger="so101sim.recording"):
        rm = rec.render_model(edited, "draft", 64, 48)
    assert not _draws_draft_meshes(rm)
    np.testing.assert_array_equal(rm.mesh_facenum, edited.mesh_facenum)
    [warning] = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert "falling back to the model's own meshes" in warning.getMessage()
    assert "load_model" in warning.getMessage()

    box = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><geom type='box' size='.1 .1 .1'/></worldbody></mujoco>"
    )
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="so101sim.recording"):
        rec.render_model(box, "draft", 64, 48)
    [warning] = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert "none of its meshes is a shipped SO-101 mesh" in warning.getMessage()
