"""Domain randomisation (scenes/randomize.py, ``gym.make(..., randomize=...)``): seeded, it
changes what each family says and nothing else (the arm's joints, their order and units, the
timestep, the control rate and the start poses stay)."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import so101sim.envs
import so101sim.units
from so101sim.errors import SettingError
from so101sim.scenes import RANDOMIZE_PRESETS, Randomization, randomization

ID = "so101sim/PickCube-v0"


def rollout(env, seed: int, steps: int = 12) -> list[dict]:
    obs, _ = env.reset(seed=seed)
    out = [obs]
    action = np.array([10.0, -60.0, 60.0, 40.0, 0.0, 30.0], dtype=np.float32)
    for _ in range(steps):
        obs, *_ = env.step(action)
        out.append(obs)
    return out


def model_arrays(m: mujoco.MjModel) -> dict[str, np.ndarray]:
    names = ("geom_rgba", "light_diffuse", "cam_fovy", "geom_size", "body_mass", "geom_friction",
             "actuator_biasprm", "dof_damping", "jnt_range", "opt.timestep")  # fmt: skip
    return {n: np.array(m.opt.timestep if n == "opt.timestep" else getattr(m, n)) for n in names}


def test_presets_and_dicts_are_checked():
    assert randomization(None) == randomization("none") == Randomization()
    assert not randomization("none").active and randomization("light").active
    assert set(RANDOMIZE_PRESETS) == {"none", "light", "full"}
    assert randomization({"preset": "light", "colors": 0.3}).colors == 0.3
    with pytest.raises(SettingError, match="none, light, full"):
        randomization("heavy")
    with pytest.raises(SettingError, match="no family 'paint'"):
        randomization({"paint": 1})
    with pytest.raises(SettingError, match="object_mass"):
        randomization({"object_mass": 2.0})


def test_none_changes_nothing_and_the_same_seed_gives_the_same_scene():
    plain = rollout(gym.make(ID), 4)
    none = rollout(gym.make(ID, randomize="none"), 4)
    for a, b in zip(plain, none, strict=True):
        for k in a:
            np.testing.assert_array_equal(a[k], b[k])
    a, b = gym.make(ID, randomize="full"), gym.make(ID, randomize="full")
    ra, rb = rollout(a, 9), rollout(b, 9)
    assert a.unwrapped.randomization == b.unwrapped.randomization
    for x, y in zip(ra, rb, strict=True):
        np.testing.assert_array_equal(x["agent_pos"], y["agent_pos"])
    first = a.unwrapped.randomization
    a.reset(seed=10)
    assert a.unwrapped.randomization != first  # another seed, another scene
    a.reset(seed=9)
    assert a.unwrapped.randomization == first  # and back: draws never pile up


def test_each_family_changes_what_it_says_and_nothing_else():
    base = gym.make(ID)
    base.reset(seed=2)
    ref = model_arrays(base.unwrapped.model)
    ref_obs = rollout(base, 2)
    changes = {
        "colors": {"geom_rgba"},
        "lighting": {"light_diffuse"},
        "camera_fovy_deg": {"cam_fovy"},
        "object_mass": {"body_mass"},
        "friction": {"geom_friction"},
        "object_size": {"geom_size", "body_mass"},
        "actuators": {"actuator_biasprm", "dof_damping"},  # the stiffness is -biasprm[1]
    }
    for family, touched in changes.items():
        env = gym.make(ID, randomize={family: 0.3 if family != "camera_fovy_deg" else 5.0})
        inner = env.unwrapped
        assert inner.action_space == base.unwrapped.action_space
        assert inner.observation_space == base.unwrapped.observation_space
        assert inner.control_hz == base.unwrapped.control_hz
        assert list(inner.sim.pose()) == list(base.unwrapped.sim.pose())  # joint order
        obs = rollout(env, 2)
        got = model_arrays(inner.model)
        for name, value in ref.items():
            same = np.array_equal(value, got[name])
            assert same != (name in touched), (family, name)
        start, ref_start = obs[0]["environment_state"], ref_obs[0]["environment_state"]
        np.testing.assert_array_equal(start[:2], ref_start[:2])  # the start poses stay
        np.testing.assert_allclose(obs[0]["agent_pos"], ref_obs[0]["agent_pos"], atol=1e-9)
        moved = not all(
            np.array_equal(a["agent_pos"], b["agent_pos"])
            for a, b in zip(obs, ref_obs, strict=True)
        )
        physical = family in ("object_mass", "friction", "object_size", "actuators")
        if family in ("colors", "lighting", "camera_fovy_deg"):
            assert not moved, family  # the look changes nothing of the physics
        elif family == "actuators":
            assert moved and physical


def test_distractors_are_built_into_the_scene_and_placed_clear_of_the_cube():
    env = gym.make(ID, randomize={"distractors": 3})
    m = env.unwrapped.model
    assert all(
        mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"distractor_{i}") >= 0 for i in range(3)
    )
    counts = []
    for seed in range(6):
        obs, _ = env.reset(seed=seed)
        placed = env.unwrapped.randomization["distractors"]
        counts.append(len(placed))
        cube = obs["environment_state"][:2]
        for d in placed:
            assert np.hypot(d["x"] - cube[0], d["y"] - cube[1]) >= 0.07
    assert max(counts) > 0 and obs["environment_state"].shape == (7,)  # only the task's objects


def test_the_follower_draws_the_same_scene_as_the_environment_for_a_seed():
    """The simulated follower (LeRobot: --robot.randomize=full) at a take's reset draws what
    the environment draws at reset(seed) although their models differ in cameras."""
    from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig
    from so101sim.robot.scene import robot_scene

    robot = SO101SimFollower(
        SO101SimFollowerConfig(scene="pick_cube", mode="lockstep", randomize="full")
    )
    robot.connect()
    try:
        scene = robot_scene(robot)
        scene.reset(5)
        env = gym.make(ID, randomize="full", cameras=["front"])
        obs, _ = env.reset(seed=5)
        assert scene.randomization == env.unwrapped.randomization
        np.testing.assert_allclose(scene.environment_state(), obs["environment_state"], atol=1e-6)
    finally:
        robot.disconnect()
    with pytest.raises(SettingError, match="needs a scene"):
        SO101SimFollowerConfig(randomize="light")


def test_actuator_sigmas_draw_each_servo_from_the_profiles_uncertainty(tmp_path):
    """The ``actuator_sigmas`` family writes the arm profile's uncertainty draws (recorded per
    joint under ``servos``) into the gain, delay and friction it names, and nothing else."""
    path = tmp_path / "wide.toml"
    path.write_text(
        'name = "wide"\nextends = "sts3215"\n\n[uncertainty]\n'
        "kp_per_p = 0.1\ndelay_s = 0.004\nfrictionloss = 0.02\n"
        f"{NOT_DRAWN}"
    )
    base = gym.make(ID, arm=str(path))
    base.reset(seed=3)
    m0 = base.unwrapped.model
    names = ("actuator_biasprm", "actuator_delay", "dof_frictionloss", "dof_damping",
             "dof_armature", "actuator_forcerange", "geom_rgba", "body_mass",
             "jnt_range")  # fmt: skip
    ref = {n: getattr(m0, n).copy() for n in names}
    env = gym.make(ID, arm=str(path), randomize={"actuator_sigmas": 2.0})
    env.reset(seed=3)
    inner = env.unwrapped
    drawn = inner.randomization["servos"]
    assert list(drawn) == list(so101sim.units.JOINT_NAMES)
    touched = {"actuator_biasprm", "actuator_delay", "dof_frictionloss"}
    for n in names:
        assert np.array_equal(ref[n], getattr(inner.model, n)) != (n in touched), n
    prof = inner.arm
    for j, (act, dof) in enumerate(zip(*_arm(inner.model), strict=True)):
        name = so101sim.units.JOINT_NAMES[j]
        nominal = prof.joint(name)
        kp = -inner.model.actuator_biasprm[act, 1]
        want = nominal.kp + drawn[name]["kp_per_p"] * nominal.firmware_p
        assert kp == pytest.approx(want)
        delay = inner.model.actuator_delay[act]  # what was applied is recorded
        assert delay == pytest.approx(nominal.delay_s + drawn[name]["delay_s"], abs=1e-12)
        reach = (inner.model.actuator_history[act, 0] - 2) * inner.model.opt.timestep
        assert 0 <= delay <= reach + 1e-12
        assert inner.model.dof_frictionloss[dof] == pytest.approx(
            max(0.0, ref["dof_frictionloss"][dof] + drawn[name]["frictionloss"])
        )
    again = gym.make(ID, arm=str(path), randomize={"actuator_sigmas": 2.0})
    again.reset(seed=3)
    assert again.unwrapped.randomization["servos"] == drawn
    # a profile without an uncertainty table draws nothing from this family
    plain = gym.make(ID, arm="official", randomize={"actuator_sigmas": 2.0})
    plain.reset(seed=3)
    assert plain.unwrapped.randomization["servos"] == {j: {} for j in so101sim.units.JOINT_NAMES}


_ZEROED = ("torque_limit", "damping", "viscous", "drive_frictionloss", "armature", "max_velocity")
NOT_DRAWN = "".join(f"{k} = 0.0\n" for k in _ZEROED)
"""The shipped sts3215's other standard deviations set to 0: those fields are not drawn."""


def _arm(model):
    from so101sim.model import arm_index

    idx = arm_index(model)
    return idx.actuator, idx.dof


def test_textures_are_built_in_and_change_only_the_images():
    """The ``textures`` family puts the table and the objects in one of the built-in textures
    (with the chance it gives), recorded per surface; the physics stays bit for bit."""
    env = gym.make(ID, randomize={"textures": 1.0}, cameras=["front"], image_size=(48, 64))
    plain = gym.make(ID, cameras=["front"], image_size=(48, 64))
    m = env.unwrapped.model
    mats = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_MATERIAL, f"so101sim_texture_{k}")
            for k in ("checker", "gradient", "speckle")]  # fmt: skip
    assert min(mats) >= 0
    seen = set()
    for seed in range(4):
        obs, _ = env.reset(seed=seed)
        ref, _ = plain.reset(seed=seed)
        chosen = env.unwrapped.randomization["textures"]
        assert set(chosen) == {"table", "cube"}  # chance 1: every surface
        seen |= set(chosen.values())
        table = np.flatnonzero(m.geom_bodyid == m.body("table").id)
        assert set(m.geom_matid[table]) == {
            mats[("checker", "gradient", "speckle").index(chosen["table"])]
        }
        assert not np.array_equal(obs["pixels"]["front"], ref["pixels"]["front"])
        np.testing.assert_array_equal(obs["agent_pos"], ref["agent_pos"])
        np.testing.assert_array_equal(obs["environment_state"], ref["environment_state"])
    assert len(seen) > 1
    a = rollout(env, 2)
    b = rollout(plain, 2)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x["agent_pos"], y["agent_pos"])
    none = gym.make(ID, randomize={"textures": 0.0})
    assert mujoco.mj_name2id(none.unwrapped.model, mujoco.mjtObj.mjOBJ_MATERIAL,
                             "so101sim_texture_checker") < 0  # fmt: skip
    with pytest.raises(SettingError, match="textures"):
        randomization({"textures": 1.5})


def test_a_preset_with_families_changed_is_one_string():
    """What --randomize takes on every command line: a preset, then family=number parts."""
    got = randomization("light,textures=0.5,distractors=2")
    assert got.textures == 0.5 and got.distractors == 2 and got.colors == 0.08  # light's
    assert randomization("friction=0.2") == Randomization(friction=0.2)
    assert randomization(" light , textures = 0.5 ") == randomization("light,textures=0.5")
    bad_specs = {
        "light,paint=1": "no family 'paint'",
        "light,textures=lots": "number",
        "textures=0.5,light": "family=number",
        "light,colors=5": "colors",
        "light,textures=0.2,textures=0.5": "textures twice",
    }
    for bad, match in bad_specs.items():
        with pytest.raises(SettingError, match=match):
            randomization(bad)
    from so101sim.robot import SO101SimFollowerConfig

    cfg = SO101SimFollowerConfig(scene="pick_cube", randomize="light,textures=0.5")
    assert cfg.randomize == "light,textures=0.5"
