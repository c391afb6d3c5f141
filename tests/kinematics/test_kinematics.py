"""Kinematics: forward kinematics against MuJoCo's own site poses, IK on targets the arm can
reach (sampled by forward kinematics) and on targets it cannot, straight-line moves of the
tip, and the workspace."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from so101sim.errors import (
    JointLimitError,
    JointNameError,
    OutputPathError,
    SettingError,
    UnreachableError,
)
from so101sim.kinematics import (
    is_reachable,
    line_deviation,
    plan_line,
    planar_arm,
    plot_workspace,
    sample_workspace,
    solve_ik,
    tip_pose,
    tip_positions,
)
from so101sim.model import arm_index, arm_units, load_model
from so101sim.units import JOINT_NAMES, STARTING_POSE, ZERO_POSE, to_lerobot

N_RANDOM = 1000


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return load_model()


def random_poses(model: mujoco.MjModel, n: int, seed: int) -> np.ndarray:
    lo, hi = arm_units(model).limits
    return np.random.default_rng(seed).uniform(lo, hi, size=(n, len(JOINT_NAMES)))


# ---------------------------------------------------------------------------- forward
def test_tip_matches_mujocos_site_pose_for_random_poses(model):
    units, idx = arm_units(model), arm_index(model)
    data = mujoco.MjData(model)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "gripperframe")
    worst_pos = worst_rot = 0.0
    for values in random_poses(model, N_RANDOM, seed=1):
        data.qpos[idx.qpos] = units.to_radians(values)
        mujoco.mj_forward(model, data)
        tip = tip_pose(units.array_to_pose(values))
        worst_pos = max(worst_pos, float(np.abs(tip.position - data.site_xpos[site]).max()))
        worst_rot = max(
            worst_rot, float(np.abs(tip.rotation - data.site_xmat[site].reshape(3, 3)).max())
        )
    assert worst_pos < 1e-9
    assert worst_rot < 1e-9


def test_tip_of_the_labs_poses_and_the_frames_axes():
    zero = tip_pose(ZERO_POSE)
    assert zero.position == pytest.approx(
        [0.3914, 0.0, 0.2265], abs=5e-4
    )  # forward, at shoulder height
    assert zero.pitch == pytest.approx(0.0, abs=1e-9)
    assert zero.approach == pytest.approx([1.0, 0.0, 0.0], abs=1e-9)
    start = tip_pose(STARTING_POSE)
    # the tool's pitch is minus the sum of the three parallel pitch joints
    s = STARTING_POSE
    assert start.pitch == pytest.approx(-(s["shoulder_lift"] + s["elbow_flex"] + s["wrist_flex"]))
    # a positive pan turns the arm to its right (-y); yaw is counter-clockwise from above
    turned = tip_pose({**ZERO_POSE, "shoulder_pan": 30.0})
    assert turned.position[1] < -0.1 and turned.yaw == pytest.approx(-30.0)
    # roll follows wrist_roll, 2.79° off: the gripper is not level at wrist_roll = 0
    rolled = tip_pose({**ZERO_POSE, "wrist_roll": 40.0})
    assert rolled.roll - zero.roll == pytest.approx(40.0)
    assert zero.roll == pytest.approx(-2.789, abs=1e-3)
    assert "x=0.391 y=0.000 z=0.226 m, pitch=0.0°" in zero.format()


def test_tip_accepts_lerobot_keys_arrays_and_rejects_bad_poses():
    p = tip_pose(to_lerobot(STARTING_POSE)).position
    assert p == pytest.approx(tip_pose(STARTING_POSE).position)
    assert tip_pose(np.array(list(STARTING_POSE.values()))).position == pytest.approx(p)
    with pytest.raises(JointLimitError):
        tip_pose({**ZERO_POSE, "elbow_flex": 120.0})
    with pytest.raises(JointNameError):
        tip_pose({"elbow_flex": 0.0})
    positions = tip_positions(np.array([list(ZERO_POSE.values()), list(STARTING_POSE.values())]))
    assert positions[1] == pytest.approx(p)


def test_planar_chain_read_from_the_model():
    arm = planar_arm()
    assert arm is not None
    assert arm.upper[0] == pytest.approx(0.1160, abs=1e-4)  # shoulder -> elbow
    assert arm.fore[0] == pytest.approx(0.1350, abs=1e-4)  # elbow -> wrist
    assert arm.pan_sign == -1.0  # the pan axis points down


# ---------------------------------------------------------------------------- inverse
@pytest.mark.parametrize("orientation", ["position", "pitch", "pitch+roll", "approach", "rotation"])
def test_ik_reaches_fk_sampled_targets(model, orientation):
    lo, hi = arm_units(model).limits
    ok = 0
    for values in random_poses(model, N_RANDOM, seed=2):
        tip = tip_pose(values)
        kw: dict = {}
        if "pitch" in orientation:
            kw["pitch"] = tip.pitch
        if "roll" in orientation:
            kw["roll"] = tip.roll
        if orientation == "approach":
            kw["approach"] = tip.approach
        if orientation == "rotation":
            kw["rotation"] = tip.rotation
        r = solve_ik(tip.position, closest=True, **kw)
        assert np.all(r.values >= lo) and np.all(r.values <= hi)  # never leaves the limits
        reached = tip_pose(r.values)
        err_mm = np.linalg.norm(reached.position - tip.position) * 1000.0
        angles = [0.0]
        if "pitch" in kw:
            angles.append(abs((reached.pitch - kw["pitch"] + 180) % 360 - 180))
        if "roll" in kw:
            angles.append(abs((reached.roll - kw["roll"] + 180) % 360 - 180))
        if "approach" in kw:
            angles.append(math.degrees(math.acos(min(1.0, reached.approach @ kw["approach"]))))
        if "rotation" in kw:  # the angle of the turn between the reached and the asked frame
            cos = (np.trace(reached.rotation.T @ kw["rotation"]) - 1.0) / 2.0
            angles.append(math.degrees(math.acos(min(1.0, cos))))
        ok += r.reachable and err_mm <= 1.0 and max(angles) <= 1.0
    assert ok >= 0.995 * N_RANDOM


def test_ik_says_unreachable_for_targets_outside_the_workspace():
    rng = np.random.default_rng(3)
    directions = rng.normal(size=(30, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    shoulder = np.array([0.039, 0.0, 0.117])
    for d in directions:  # 0.6 m from the shoulder: beyond the arm's 0.41 m of links
        target = shoulder + 0.6 * d
        with pytest.raises(UnreachableError, match=r"closest the tip gets is \d+\.\d mm away"):
            solve_ik(target)
        assert not is_reachable(target)
    with pytest.raises(UnreachableError, match=r"pitch 90°.*off the asked orientation"):
        solve_ik((0.2, 0.0, 0.05), pitch=90)  # pointing straight up that low: no
    closest = solve_ik((0.7, 0.0, 0.2), closest=True)
    assert not closest.reachable and closest.position_error_mm > 200
    lo, hi = arm_units(load_model()).limits
    assert np.all(closest.values >= lo) and np.all(closest.values <= hi)


def test_ik_warm_start_gripper_and_determinism():
    pose = {
        "shoulder_pan": 20.0,
        "shoulder_lift": 10.0,
        "elbow_flex": 30.0,
        "wrist_flex": 40.0,
        "wrist_roll": 5.0,
        "gripper": 40.0,
    }
    tip = tip_pose(pose)
    near = {k: v + 2.0 for k, v in pose.items()}
    r = solve_ik(tip.position, pitch=tip.pitch, roll=tip.roll, initial=near)
    assert [r.pose[n] for n in JOINT_NAMES[:4]] == pytest.approx(
        [pose[n] for n in JOINT_NAMES[:4]], abs=1e-3
    )
    assert r.pose["gripper"] == pytest.approx(42.0)  # the initial pose's gripper is kept
    assert solve_ik(tip.position, pitch=tip.pitch, gripper=70).pose["gripper"] == 70.0
    a = solve_ik((0.25, 0.05, 0.1), closest=True)
    b = solve_ik((0.25, 0.05, 0.1), closest=True)
    assert a.values == pytest.approx(b.values, abs=0)
    # position only: the tool keeps the warm start's pitch where it reaches
    kept = solve_ik((0.25, 0.05, 0.1), initial={**ZERO_POSE, "wrist_flex": 50.0})
    assert kept.tip.pitch == pytest.approx(tip_pose({**ZERO_POSE, "wrist_flex": 50.0}).pitch)


def test_ik_points_straight_down_with_pitch_or_approach():
    for kw in ({"pitch": -90}, {"approach": (0, 0, -1)}):
        r = solve_ik((0.2, -0.05, 0.03), **kw)
        assert r.tip.approach == pytest.approx([0.0, 0.0, -1.0], abs=1e-6)
        assert r.position_error_mm < 1e-3 and r.orientation_error_deg < 1e-3


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"target": (0.2, 0.0)}, "not three numbers"),
        ({"target": (0.2, 0.0, math.nan)}, "tip target z"),
        ({"target": "abc"}, "not three numbers"),
        ({"pitch": -90, "approach": (0, 0, -1)}, "both pitch and approach"),
        ({"pitch": 270}, "pitch"),
        ({"approach": (0, 0, 0)}, "not a direction"),
        ({"rotation": np.diag([1.0, 1.0, -1.0])}, "not a rotation matrix"),
        ({"rotation": np.eye(3), "pitch": 0}, "a rotation is given with pitch"),
        ({"restarts": -1}, "restarts"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"tolerance_mm": 0}, "tolerance_mm"),
    ],
)
def test_ik_rejects_bad_settings(kwargs, match):
    args = {"target": (0.2, 0.0, 0.05), **kwargs}
    with pytest.raises(SettingError, match=match):
        solve_ik(args.pop("target"), **args)


# ---------------------------------------------------------------------------- straight lines
def test_straight_line_keeps_the_commanded_tip_on_the_line():
    plan = plan_line(STARTING_POSE, (0.2, 0.0, 0.05), 1000, pitch=-90)
    assert plan.targets.shape == (1000, 6)
    assert plan.deviation_mm < 2.0 and plan.between_mm < 2.0
    assert plan.tips[-1] == pytest.approx([0.2, 0.0, 0.05], abs=1e-6)
    assert tip_pose(plan.targets[-1]).pitch == pytest.approx(-90.0, abs=1e-4)
    lo, hi = arm_units(load_model()).limits
    assert np.all(plan.targets >= lo) and np.all(plan.targets <= hi)
    assert plan.targets[:, -1] == pytest.approx(0.0)  # the gripper stays as it was
    dev = line_deviation(plan.targets, plan.start, plan.end)
    assert dev.max_mm == pytest.approx(plan.deviation_mm)
    assert len(plan.poses()) == 1000


def test_straight_line_with_a_profiles_fractions_and_a_turning_tool():
    s = np.arange(1, 501) / 500
    s = s**3 * (10 - 15 * s + 6 * s**2)  # minimum jerk
    plan = plan_line(ZERO_POSE, (0.25, -0.1, 0.05), s, approach=(0, 0, -1))
    assert plan.deviation_mm < 2.0 and plan.between_mm < 2.0
    assert tip_pose(plan.targets[-1]).approach == pytest.approx([0, 0, -1], abs=1e-6)


def test_a_line_through_unreachable_points_fails_before_anything_moves():
    with pytest.raises(UnreachableError, match=r"the end of the line.*nothing has moved"):
        plan_line(ZERO_POSE, (0.7, 0.0, 0.1))
    with pytest.raises(UnreachableError, match=r"cannot be followed: \d+% of the way"):
        plan_line(ZERO_POSE, (-0.1, 0.0, 0.1))  # through the shoulder
    with pytest.raises(SettingError, match=r"fractions in 0\.\.1"):
        plan_line(ZERO_POSE, (0.25, 0.0, 0.1), [0.5, 1.5])
    with pytest.raises(SettingError, match="steps"):
        plan_line(ZERO_POSE, (0.25, 0.0, 0.1), 0)


def test_a_simulated_line_tracks_within_a_few_mm(model):
    from so101sim.sim.simulation import Simulation  # tests may reach above the kinematics layer

    # the ideal actuators (the default sts3215 sags ~1.5 cm under the arm's weight)
    sim = Simulation(load_model(arm="official"), initial_pose=STARTING_POSE)
    n = round(2.0 / sim.timestep)
    s = np.arange(1, n + 1) / n
    plan = plan_line(
        sim.commanded_array(), (0.2, 0.0, 0.05), s**3 * (10 - 15 * s + 6 * s**2), pitch=-90
    )
    trace = sim.advance(plan.targets)
    reached = line_deviation(sim.units.from_radians(trace.qpos), plan.start, plan.end)
    assert reached.max_mm < 2.0


# ---------------------------------------------------------------------------- workspace
def test_workspace_samples_and_reachability():
    down = sample_workspace(2000, pitch=-90, seed=5)
    assert len(down.points) == 2000
    assert all(abs(tip_pose(v).pitch + 90) < 1e-6 for v in down.values[:50])
    section = sample_workspace(500, pan=0.0)
    assert np.abs(section.points[:, 1]).max() < 0.01  # the arm's plane, give or take the jaw
    assert 0.45 < sample_workspace(5000).reach_m < 0.5
    assert is_reachable(down.points[0], pitch=-90)
    assert not is_reachable((0.0, 0.0, 0.7))
    with pytest.raises(SettingError, match="samples"):
        sample_workspace(0)


def test_plot_workspace_writes_a_picture(tmp_path):
    path = plot_workspace(tmp_path / "ws.png", samples=500)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["ws.png"]  # no temporary file left
    with pytest.raises(OutputPathError, match="already exists"):
        plot_workspace(path, samples=500)
    assert plot_workspace(path, samples=500, force=True) == path
    with pytest.raises(OutputPathError, match="extension"):
        plot_workspace(tmp_path / "ws.txt")
    with pytest.raises(OutputPathError, match="existing folder"):
        plot_workspace(tmp_path / "nope" / "ws.png")


@pytest.mark.slow
def test_the_example_prints_the_tip_and_solves_ik():
    import subprocess
    import sys
    from pathlib import Path

    example = Path(__file__).resolve().parents[2] / "examples" / "kinematics_tip.py"
    out = subprocess.run(
        [sys.executable, str(example)], capture_output=True, text=True, timeout=120, check=True
    ).stdout
    assert "ZERO_POSE      x=0.391 y=0.000 z=0.226 m, pitch=0.0°" in out
    assert "STARTING_POSE  x=0.182 y=0.000 z=0.030 m, pitch=-50.0°" in out
    apart = float(out.split("1000 random poses: at most ")[1].split(" mm")[0])
    assert apart < 0.5  # the rounded textbook chain agrees with the simulator
    assert "reached  x=0.200 y=0.000 z=0.050 m, pitch=-90.0°" in out


def test_a_pose_outside_the_limits_gets_advice_kinematics_can_follow():
    with pytest.raises(JointLimitError, match="elbow_flex") as info:
        tip_pose({**STARTING_POSE, "elbow_flex": 200.0})
    assert "clip" not in str(info.value)  # tip_pose has no clip argument
    assert "inside the limits" in str(info.value) and info.value.joint == "elbow_flex"
