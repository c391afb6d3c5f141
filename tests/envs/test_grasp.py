"""Grasping that holds: the gripper closing on a 2.5 cm cube of 10-50 g lifts it and holds it
without slip, jumps or parts passing into each other; a cube on the table stays put. A sample
of placements here; bench/bench_envs.py measures 50 (the same thresholds)."""

import mujoco
import numpy as np

from so101sim.envs.grasp import (
    GRASP_LIMITS,
    REST_LIMITS,
    cube_scene,
    default_contact,
    grasp_trial,
    grasp_trials,
    limit_gripper,
    rest_trial,
    sample_cube_placements,
)
from so101sim.model import load_model
from so101sim.model.arm import gripper_full_range
from so101sim.robot.config import GRIPPER_TORQUE_FRACTION
from so101sim.scenes import build_scene
from so101sim.sim.simulation import Simulation


def test_the_gripper_lifts_and_holds_cubes_of_10_to_50_g_at_random_placements():
    trials = grasp_trials(5, seed=1)
    masses = [t.mass for t in trials]
    assert min(masses) >= 0.01 and max(masses) <= 0.05
    for t in trials:
        assert t.ok, t
        assert t.lifted_mm >= GRASP_LIMITS["lifted_mm"]
        assert t.slip_mm <= GRASP_LIMITS["slip_mm"]
        assert t.penetration_mm <= GRASP_LIMITS["penetration_mm"]
        assert t.disturbed_mm <= GRASP_LIMITS["disturbed_mm"]


def test_the_lightest_and_heaviest_cubes_at_the_edges_of_the_patch():
    for x, y, yaw, mass in [(0.15, -0.1, -45.0, 0.01), (0.23, 0.1, 45.0, 0.05)]:
        assert grasp_trial(x, y, yaw, mass).ok


def test_a_cube_left_on_the_table_stays_put_for_60_s():
    r = rest_trial(0.2, 0.05, 30.0, 0.01, duration=60.0)
    assert r.ok and r.drift_mm <= REST_LIMITS["drift_mm"] and r.sink_mm <= REST_LIMITS["sink_mm"]
    assert r.turn_deg < 0.1


def test_mujocos_default_contacts_let_the_cube_sink_into_the_jaws():
    # Why the objects' contacts are tuned: with MuJoCo's defaults the squeeze pushes the jaws
    # over a centimetre into a light cube.
    t = grasp_trial(0.2, 0.0, 0.0, 0.01, hold=0.5, contact=default_contact())
    assert t.penetration_mm > 5 * GRASP_LIMITS["penetration_mm"]


def test_the_gripper_force_is_limited_as_on_the_real_arm():
    m = build_scene(cube_scene(0.2, 0.0, 0.0, 0.03))
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "gripper")
    full = gripper_full_range(None)  # the default profile's gripper torque limit
    limit_gripper(m)
    np.testing.assert_allclose(m.actuator_forcerange[g], full * GRIPPER_TORQUE_FRACTION)
    # the profile's own 50 % (torque_scale) is replaced, not applied a second time
    assert GRIPPER_TORQUE_FRACTION == 0.5 and full[1] == 2 * load_model().actuator_forcerange[g][1]
    official = build_scene(cube_scene(0.2, 0.0, 0.0, 0.03), arm="official")
    limit_gripper(official, arm="official")
    assert official.actuator_forcerange[g][1] == 0.5 * 3.35


def test_closing_on_nothing_the_jaws_close_as_in_the_lab_and_on_a_cube_they_stop_at_it():
    empty = Simulation(build_scene(cube_scene(0.3, 0.3, 0.0, 0.03)))
    lab = Simulation()
    for s in (empty, lab):
        s.command({"gripper": 40.0})
        s.hold(0.5)
        s.command({"gripper": 0.0})
        s.hold(0.5)
    assert abs(empty.pose()["gripper"] - lab.pose()["gripper"]) < 0.01  # pads do not block
    t = grasp_trial(0.2, 0.0, 0.0, 0.03, hold=0.2)
    assert t.ok


def test_placements_are_drawn_from_the_seed():
    assert sample_cube_placements(5, 3) == sample_cube_placements(5, 3)
    assert sample_cube_placements(5, 3) != sample_cube_placements(5, 4)
