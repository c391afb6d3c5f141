"""The one model builder (issue 30 point 1): a recipe says what model to make, `build` makes
it once; load_model, the scenes, the preflight's sensor model and the twin go through it; no
lock is held while compiling (a build inside a build does not deadlock)."""

from __future__ import annotations

import copy
import threading

import mujoco
import pytest

from so101sim.model import load_model, scene_path, servo_model
from so101sim.model.build import Addition, build, recipe, recipe_of, recognise, servo_name
from so101sim.preflight.rollout import sensor_model
from so101sim.scenes import SCENE_PRESETS, build_scene, scene_builder


def test_load_model_is_the_builders_model_and_says_what_it_is():
    m = load_model()
    assert build(recipe()) is m
    r = recipe_of(m)
    assert r is not None and r.file == scene_path().resolve() and r.arm.name == "sts3215"
    assert servo_name(m) == "sts3215" and servo_model(m).startswith("sts3215 (STS3215 fitted")
    assert servo_name(load_model(arm="official")) == "official"
    assert recipe_of(sensor_model(scene_path())).additions[0].key.startswith("preflight")


def test_the_handouts_own_compile_is_recognised_and_an_edited_one_is_not():
    plain = mujoco.MjModel.from_xml_path(str(scene_path()))
    r = recognise(plain)
    assert r is not None and r.arm_key == "" and r.file == scene_path().resolve()
    assert servo_name(plain) == "official" and servo_name(copy.copy(plain)) == "official"
    plain.body_mass[3] *= 1.5  # an edited arm: not one so101sim can name
    assert recognise(plain) is None and servo_name(plain) == "unknown"


def test_scenes_build_through_it_uncached_and_can_be_made_again():
    scene = SCENE_PRESETS["pick_cube"]
    a, b = build_scene(scene), build_scene(scene)
    assert a is not b  # a scene may draw its objects at random: compiled each time
    assert recipe_of(a).additions[0].key is None
    assert scene_builder(a)().compile().ngeom == a.ngeom


def test_a_build_inside_a_build_and_two_threads_asking_at_once_do_not_deadlock(monkeypatch):
    monkeypatch.setenv("SO101SIM_NO_CACHE", "1")  # no disk entry: the edit runs each time
    inner: list[mujoco.MjModel] = []

    def edit(spec: mujoco.MjSpec) -> None:  # needs another model while being built
        inner.append(build(recipe(arm="official")))

    outer = recipe(arm="sts3215-12v", additions=(Addition(f"nested-{id(edit)}", edit),))
    got: list[mujoco.MjModel] = []
    threads = [threading.Thread(target=lambda: got.append(build(outer))) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=300)
    assert not any(t.is_alive() for t in threads), "the builder deadlocked"
    assert len(got) == 2 and got[0] is got[1]  # compiled once, the same model for both
    assert inner and inner[0] is load_model(arm="official")


def test_a_one_off_recipe_is_kept_in_no_cache():
    r = recipe(arm="sts3215-12v", keep=False)
    assert build(r) is not build(r)


def test_a_recipe_checks_its_file_and_profile():
    from so101sim.errors import ModelError, ProfileError

    with pytest.raises(ModelError, match="model file"):
        recipe("/nonexistent/scene.xml")
    with pytest.raises(ProfileError, match="sts3215"):
        recipe(arm="sts9999")
