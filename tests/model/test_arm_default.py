"""The default arm profile (sts3215) and where it reaches: load_model (full, physics-only, the
disk cache), the scenes, the preflight's sensor model, and ``--arm NAME|FILE`` on every entry
point (run, hold, check, check --variants, record, demo; the follower's config; the
environments). One resolution path (model.arm.load_profile): an unknown name names the known
profiles everywhere."""

from __future__ import annotations

import json

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import so101sim.envs  # noqa: F401  (registers the environments)
from so101sim.cli import main
from so101sim.errors import RobotConfigError, So101SimError
from so101sim.model import load_model, scene_path
from so101sim.model.arm import (
    PROFILE_DEFAULT,
    apply_profile,
    fill_delay_history,
    load_profile,
    profile_key,
    profile_toml,
)
from so101sim.model.trim import is_physics_only
from so101sim.preflight.rollout import sensor_model
from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig
from so101sim.scenes import SCENE_PRESETS, build_scene
from so101sim.sim import Simulation
from so101sim.units import GRIPPER_INDEX

KNOWN = "official, sts3215, sts3215-12v"
STS_KP = load_profile("sts3215").joint("shoulder_lift").kp  # 11.1 N·m/rad at 7.4 V


def stiffness(model: mujoco.MjModel) -> np.ndarray:
    """Every so101sim servo's stiffness is -biasprm[1] (the PID actuator keeps gainprm at 0)."""
    return -model.actuator_biasprm[:6, 1]


def test_the_default_is_the_fitted_servo_and_official_is_one_option_away():
    assert PROFILE_DEFAULT == "sts3215" and load_profile(None).name == "sts3215"
    m = load_model()
    assert m is load_model(arm="sts3215")  # the same compiled model, cached once
    np.testing.assert_allclose(stiffness(m), STS_KP)
    assert (m.actuator_delay[:6] > 0.02).all()
    official = load_model(arm="official")
    np.testing.assert_allclose(official.actuator_gainprm[:6, 0], 998.22)
    assert not official.actuator_delay.any()


def test_official_is_the_file_as_it_is_and_the_profile_reproduces_it():
    plain = mujoco.MjModel.from_xml_path(str(scene_path()))
    official = load_model(arm="official")
    spec = mujoco.MjSpec.from_file(str(scene_path()))
    apply_profile(spec, "official")
    applied = spec.compile()
    for f in ("dof_damping", "dof_frictionloss", "dof_armature", "actuator_gainprm",
              "actuator_biasprm", "actuator_forcerange", "actuator_ctrlrange"):  # fmt: skip
        np.testing.assert_allclose(getattr(official, f), getattr(plain, f), err_msg=f)
        np.testing.assert_allclose(getattr(applied, f), getattr(plain, f), err_msg=f)
    assert profile_key("official") == "" and profile_key("sts3215").startswith("arm-")


def test_a_profile_is_keyed_by_its_values_not_its_name(tmp_path):
    prof = load_profile("sts3215")
    path = tmp_path / "mine.toml"
    path.write_text(profile_toml(prof).replace('name = "sts3215"', 'name = "mine"'))
    assert profile_key(path) == profile_key("sts3215")
    assert load_model(arm=path) is load_model()
    assert profile_key("sts3215-12v") != profile_key("sts3215")


def test_physics_only_model_has_the_profile_and_the_same_physics():
    full, light = load_model(), load_model(physics_only=True)
    assert is_physics_only(light) and not is_physics_only(full)
    for f in ("actuator_biasprm", "actuator_forcerange", "actuator_delay", "dof_damping"):
        np.testing.assert_array_equal(getattr(light, f), getattr(full, f), err_msg=f)
    runs = []
    for m in (full, light):
        sim = Simulation(m)
        sim.command({"elbow_flex": 20.0, "shoulder_lift": -60.0})
        sim.step(300, trace=False)
        runs.append(sim.data.qpos.copy())
    np.testing.assert_array_equal(runs[0], runs[1])


def test_scenes_and_the_preflight_sensor_model_get_the_profile():
    scene = SCENE_PRESETS["pick_cube"]
    np.testing.assert_allclose(stiffness(build_scene(scene)), STS_KP)
    np.testing.assert_allclose(stiffness(build_scene(scene, arm="official")), 998.22)
    np.testing.assert_allclose(stiffness(sensor_model(scene_path())), STS_KP)
    np.testing.assert_allclose(stiffness(sensor_model(scene_path(), "official")), 998.22)


def test_there_is_no_global_override_of_the_default_profile():
    """The default is one constant (issue 30: no ``default_profile`` block): what None means
    never changes while a program runs."""
    import so101sim.model.arm as arm_module

    assert not hasattr(arm_module, "default_profile")
    assert load_profile(None).name == "sts3215"


def test_unknown_profiles_name_the_known_ones_everywhere():
    with pytest.raises(So101SimError, match=KNOWN):
        load_model(arm="sts9999")
    with pytest.raises(So101SimError, match=KNOWN):
        Simulation(arm="sts9999")
    with pytest.raises(RobotConfigError, match=f"arm: .*{KNOWN}"):
        SO101SimFollowerConfig(arm="sts9999")
    with pytest.raises(So101SimError, match=KNOWN):
        gym.make("so101sim/PickCube-v0", arm="sts9999")
    with pytest.raises(So101SimError, match=KNOWN):
        build_scene(SCENE_PRESETS["pick_cube"], arm="sts9999")


# ---------------------------------------------------------------------------- entry points
def _worst(text: str) -> float:
    """The largest 'largest tracking error' a run printed, degrees."""
    return max(
        float(line.split(":")[1].split("°")[0])
        for line in text.splitlines()
        if "largest tracking error" in line
    )


def test_run_and_hold_take_arm(capsys):
    assert main(["run", "--headless"]) == 0
    soft = _worst(capsys.readouterr().out)
    assert main(["run", "--headless", "--arm", "official"]) == 0
    stiff = _worst(capsys.readouterr().out)
    assert stiff < 0.5 < 5.0 < soft  # the fitted servo sags and lags; the vendored one does not
    assert main(["hold", "--headless", "--duration", "0.5", "--arm", "official"]) == 0
    assert _worst(capsys.readouterr().out) < 0.1
    assert main(["run", "--headless", "--arm", "sts9999"]) == 2
    assert KNOWN in capsys.readouterr().err


def test_check_takes_arm_and_the_effort_is_of_the_profiles_torque_limit(capsys):
    efforts = {}
    for arm in ("official", "sts3215"):
        assert main(["check", "--json", "--arm", arm]) == 0
        report = json.loads(capsys.readouterr().out)
        efforts[arm] = max(j["peak_effort"] for s in report["steps"] for j in s["joints"].values())
    # the vendored actuator (kp 998) hits its 3.35 N·m limit at every start; the fitted
    # servo (kp 11, slew-limited goal) stays inside its 3.92 N·m
    assert efforts["official"] > 0.9 > efforts["sts3215"]
    assert main(["check", "--arm", "nope.toml"]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_check_variants_takes_arm(capsys):
    argv = ["check", "--variants", "3", "--threads", "1", "--json"]
    assert main([*argv, "--arm", "official"]) in (0, 1)
    official = json.loads(capsys.readouterr().out)
    assert main(argv) in (0, 1)
    default = json.loads(capsys.readouterr().out)
    worst = {}
    for name, rep in (("official", official), ("sts3215", default)):
        worst[name] = max(o["tracking_error"] for o in rep["per_variant"])
    assert worst["official"] < 1.0 < 5.0 < worst["sts3215"]


def plain_model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(scene_path()))


def test_record_arm_runs_the_scripts_own_model_with_the_profile(tmp_path, capsys):
    """record --arm leaves MuJoCo's loader alone (the script's model has the file's
    actuators) and runs the script's (m, d) with the profile's servos; without --arm the
    script's model runs as it is, and the run names its servo model."""
    script = tmp_path / "probe.py"
    script.write_text(
        "import mujoco, mujoco.viewer\n"
        "from so101sim.model import scene_path\n"
        "m = mujoco.MjModel.from_xml_path(str(scene_path()))\n"
        "print('KP', m.actuator_gainprm[1, 0])\n"
        "d = mujoco.MjData(m)\n"
        "d.qpos[2] = d.ctrl[2] = 1.2  # the elbow bent, commanded to stay\n"
        "with mujoco.viewer.launch_passive(m, d) as v:\n"
        "    d.ctrl[2] = 0.0  # then a step to 0\n"
        "    for _ in range(300):\n"
        "        mujoco.mj_step(m, d); v.sync()\n"
        "print('ELBOW', d.qpos[2])\n"
    )
    out = tmp_path / "p.mp4"
    base = ["record", str(script), "-o", str(out), "--width", "64", "--height", "48", "--force"]
    elbow = {}
    for arm in ("sts3215", None):
        assert main([*base, "--arm", arm] if arm else base) == 0
        captured = capsys.readouterr()
        assert float(captured.out.split("KP")[1].split()[0]) == pytest.approx(998.22)
        elbow[arm] = float(captured.out.split("ELBOW")[1].split()[0])
        said = [line for line in captured.err.splitlines() if "--arm" in line]
        assert len(said) == (1 if arm else 0), captured.err
        assert f"servo model: {arm or 'official'}" in captured.out
    # each run is, step for step, that model's own physics (the profile's: its servos' goal
    # history filled with the targets the script had when it opened the viewer)
    for arm, model in (("sts3215", load_model(arm="sts3215")), (None, plain_model())):
        d = mujoco.MjData(model)
        d.qpos[2] = d.ctrl[2] = 1.2
        fill_delay_history(model, d)
        d.ctrl[2] = 0.0
        mujoco.mj_step(model, d, nstep=300)
        assert elbow[arm] == pytest.approx(d.qpos[2], abs=1e-9), arm
    assert abs(elbow["sts3215"] - elbow[None]) > 0.05
    assert mujoco.MjModel.from_xml_path(str(scene_path())).actuator_gainprm[0, 0] > 900


def test_demo_takes_arm(capsys):
    assert main(["demo", "pick_cube", "--headless", "--arm", "official"]) == 0
    assert "success" in capsys.readouterr().out
    assert main(["demo", "pick_cube", "--headless", "--arm", "sts9999"]) == 2
    assert KNOWN in capsys.readouterr().err


def test_follower_and_environments_take_arm():
    follower = SO101SimFollower(SO101SimFollowerConfig(arm="official", mode="lockstep"))
    np.testing.assert_allclose(stiffness(follower._sim.model), 998.22)
    follower.connect()
    try:  # the gripper: LeRobot's 50 % of the profile's torque limit, once
        g = follower._sim.model.actuator_forcerange[follower._sim.index.actuator[GRIPPER_INDEX]]
        assert g[1] == pytest.approx(0.5 * 3.35)
    finally:
        follower.disconnect()
    default = SO101SimFollower(SO101SimFollowerConfig(mode="lockstep"))
    np.testing.assert_allclose(stiffness(default._sim.model), STS_KP)
    default.connect()
    try:  # not 25 %: the profile's own gripper torque_scale is replaced, not multiplied
        g = default._sim.model.actuator_forcerange[default._sim.index.actuator[GRIPPER_INDEX]]
        assert g[1] == pytest.approx(0.5 * load_profile("sts3215").joint("gripper").torque_limit)
    finally:
        default.disconnect()
    for arm, kp in (("official", 998.22), (None, STS_KP)):
        env = gym.make("so101sim/PickCube-v0", arm=arm)
        try:
            np.testing.assert_allclose(stiffness(env.unwrapped.model), kp)
            gripper = env.unwrapped.model.actuator_forcerange[5, 1]
            assert gripper == pytest.approx(0.5 * load_profile(arm).joint("gripper").torque_limit)
        finally:
            env.close()


def test_view_and_teleop_take_arm(capsys):
    """The commands that simulate the arm take --arm (a bad one is one error line, before any
    window or port is opened)."""
    teleop = ["teleop", "--headless", "--port", "/nonexistent", "--arm", "sts9999"]
    for argv in (["view", "--arm", "sts9999"], teleop):
        assert main(argv) == 2, argv
        captured = capsys.readouterr()
        assert "sts9999" in captured.err and "sts3215" in captured.err, argv
        assert len(captured.err.strip().splitlines()) == 1 and not captured.out, argv
