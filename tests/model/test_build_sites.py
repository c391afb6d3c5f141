"""Only the model builder compiles (issue 30): the recorder's draft meshes and the servo bench,
which compiled their own models, are built by ``model.build.build`` from a recipe
(tests/test_architecture.py::test_only_the_model_builder_compiles_models checks the source)."""

from __future__ import annotations

import mujoco
import pytest

from so101sim.errors import ModelError, SettingError
from so101sim.fidelity.bench import BenchBatch, BenchRig
from so101sim.model import cache as modelcache
from so101sim.model import load_model, scene_path
from so101sim.model.build import MadeSpec, build, compile_spec, made_recipe, recipe_of
from so101sim.model.load import loaded_models, model_source
from so101sim.recording.draft import _draft_model, render_model
from so101sim.scenes import SCENE_PRESETS, build_scene


def test_the_servo_bench_is_built_from_a_made_spec():
    bench = BenchBatch([BenchRig(0.1, 0.1), BenchRig(0.2, 0.15)], "official")
    r = recipe_of(bench.model)
    assert r is not None and isinstance(r.file, MadeSpec) and r.file.name == "servo bench"
    assert r.arm.name == "official" and not r.cacheable and r.path is None
    assert bench.model.nu == 2 and model_source(bench.model) is None
    assert all(m is not bench.model for _, m in loaded_models())  # in no cache
    again = BenchBatch([BenchRig(0.1, 0.1), BenchRig(0.2, 0.15)], "official")
    assert again.model is not bench.model  # made each time


def test_a_made_spec_that_does_not_compile_is_a_model_error_naming_it():
    def bad() -> mujoco.MjSpec:
        spec = mujoco.MjSpec()
        spec.worldbody.add_body(name="a").add_joint(name="j", type=mujoco.mjtJoint.mjJNT_HINGE)
        spec.worldbody.add_body(name="a")  # the same name twice
        return spec

    with pytest.raises(ModelError, match="the broken rig model does not compile"):
        build(made_recipe("broken rig", bad))


@pytest.mark.parametrize("small", [False, True])
def test_the_draft_of_a_file_and_of_a_scene_are_built_by_the_builder(small):
    size = 64 if small else 640
    for model in (load_model(), build_scene(SCENE_PRESETS["pick_cube"])):
        draft = _draft_model(model, small)  # what render_model copies
        r = recipe_of(draft)
        assert r is not None and r.additions[-1].key == ("draft-small" if small else "draft")
        assert not r.keep and (draft.nq, draft.nbody) == (model.nq, model.nbody)
        assert draft.ngeom < model.ngeom  # the collision meshes left out
        assert render_model(model, "draft", size, size).ngeom == draft.ngeom


def test_the_physics_only_trim_compiles_through_the_builder(tmp_path, monkeypatch):
    monkeypatch.setenv("SO101SIM_CACHE_DIR", str(tmp_path))
    calls = []

    def counting(spec: mujoco.MjSpec) -> mujoco.MjModel:
        calls.append(spec)
        return compile_spec(spec)

    full = mujoco.MjModel.from_xml_path(str(scene_path()))
    trimmed = modelcache.load_or_compile(
        scene_path(), lambda: full, physics_only=True, compile_spec=counting
    )
    assert calls and trimmed.ngeom < full.ngeom
    with pytest.raises(SettingError, match="needs compile_spec"):
        modelcache.load_or_compile(scene_path(), lambda: full, physics_only=True)
