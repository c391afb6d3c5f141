"""Load-dependent gearbox friction (issue 32, point 1; Rhoban's BAM M3-M6): a profile's
``load_friction`` adds friction that grows with the servo's torque, set by the stepping kernel
from the servo's torque at fixed simulated times, the same physics on every path through it."""

from __future__ import annotations

import copy
from dataclasses import replace

import mujoco
import numpy as np
import pytest

from so101sim.errors import ProfileError, SimulationDivergedError
from so101sim.model.arm import load_profile, profile_from_toml, profile_toml, write_servo
from so101sim.model.load import arm_index, load_model
from so101sim.model.loadfriction import UPDATE_PERIOD_S, active_load_friction, load_friction
from so101sim.sim.batch import BatchStepper
from so101sim.sim.batched import WorldStepper
from so101sim.sim.simulation import Simulation
from so101sim.sim.stepping import advance_unobserved, step_block

FOLDED = {"shoulder_pan": 0.0, "shoulder_lift": -10.0, "elbow_flex": 0.0, "wrist_flex": 0.0,
          "wrist_roll": 0.0, "gripper": 10.0}  # fmt: skip  # the forearm held out: loaded
STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


def _loaded(k: float = 0.057, **servo):
    p = load_profile("sts3215")
    return replace(p, name=f"load-{k}", servo=replace(p.servo, load_friction=k, **servo))


def _started(m):
    d = mujoco.MjData(m)
    d.qpos[:6] = [0.3, -0.5, 0.8, 0.4, 0.1, 0.2]
    d.ctrl[:6] = [0.5, -1.0, 1.2, 0.8, 0.3, 0.2]
    mujoco.mj_forward(m, d)
    return d


def test_a_profile_with_load_friction_carries_it_and_the_default_model_is_unchanged():
    plain = load_model()
    assert plain.ntendon == 0 and load_friction(plain) is None
    m = load_model(arm=_loaded(0.05))
    found = load_friction(m)
    assert found is not None and len(found.tendons) == 6
    assert np.allclose(m.numeric_data[found.numerics], 0.05)
    assert found.stride == round(UPDATE_PERIOD_S / m.opt.timestep)
    assert np.array_equal(found.dofs, arm_index(m).dof)
    # the joints keep their own Coulomb friction; the load's share starts at 0
    assert np.allclose(m.dof_frictionloss[:6], plain.dof_frictionloss[:6])
    assert np.all(m.tendon_frictionloss == 0.0)
    # a profile's TOML keeps it
    again = profile_from_toml(profile_toml(_loaded(0.05)))
    assert again.joint("elbow_flex").load_friction == 0.05


def test_load_friction_out_of_its_bounds_is_refused_by_name():
    text = profile_toml(_loaded(0.05)).replace("load_friction = 0.05", "load_friction = 2.0")
    with pytest.raises(ProfileError, match="load_friction"):
        profile_from_toml(text)


def test_writing_load_friction_into_a_model_without_it_is_refused():
    m = copy.copy(load_model())
    idx = arm_index(m)
    servo = _loaded(0.05).joint("elbow_flex")
    with pytest.raises(ProfileError, match=r"load_friction = 0\.05 .* joint 'elbow_flex'"):
        write_servo(m, int(idx.actuator[2]), int(idx.dof[2]), servo)
    write_servo(m, int(idx.actuator[2]), int(idx.dof[2]), replace(servo, load_friction=0.0))


def test_the_friction_follows_the_servo_torque_and_every_path_steps_the_same_physics():
    base = load_model(arm=_loaded(0.057))
    found = load_friction(base)
    models = [copy.copy(base) for _ in range(4)]
    datas = [_started(m) for m in models]
    # one block unrecorded, recorded blocks of uneven sizes, the batch of many models, worlds
    advance_unobserved(models[0], datas[0], None, 1003)
    for k in (1, 46, 501, 455):
        step_block(models[1], datas[1], np.repeat(datas[1].ctrl[None], k, axis=0))
    states = np.empty((2, mujoco.mj_stateSize(base, STATE)))
    for i in (2, 3):
        mujoco.mj_getState(models[i], datas[i], states[i - 2], STATE)
    control = np.repeat(datas[2].ctrl[None, None], 2, axis=0)
    scratch = [mujoco.MjData(base) for _ in range(2)]
    with BatchStepper(2) as pool:
        for k in (17, 16, 970):  # a fit steps frame by frame
            states = pool.step(models[2:], scratch, states, control, k)
    mujoco.mj_setState(models[2], datas[2], states[0], STATE)
    ref = datas[0].qpos.copy()
    assert datas[0].time == pytest.approx(1003 * base.opt.timestep)
    assert np.array_equal(datas[1].qpos, ref)
    assert np.array_equal(datas[2].qpos, ref)
    world_model, world_data = copy.copy(base), _started(copy.copy(base))
    with WorldStepper([world_model], [world_data], 1) as worlds:
        worlds.advance(500)
        worlds.advance(503)
    assert np.array_equal(world_data.qpos, ref)
    # the load's share is the coefficient times the servo's torque at the last update
    m, d = models[0], datas[0]
    advance_unobserved(m, d, None, (-1003) % found.stride)  # to an update time
    torque = np.abs(d.actuator_force[found.actuators])
    advance_unobserved(m, d, None, 1)
    assert np.allclose(m.tendon_frictionloss[found.tendons], 0.057 * torque)
    assert np.allclose(d.userdata[found.slots], 0.057 * torque)
    assert torque.max() > 0.1  # the servos carry the arm
    # and it moves the arm: the same start without it ends elsewhere
    plain = load_model()
    d0 = _started(plain)
    advance_unobserved(plain, d0, None, 1003)
    assert np.abs(np.degrees(d0.qpos[:5] - ref[:5])).max() > 0.05


def test_a_zero_coefficient_steps_as_a_model_without_load_friction():
    """Also after the model stepped with a coefficient above 0 (its share must not linger)."""
    m = copy.copy(load_model(arm=_loaded(0.05)))
    advance_unobserved(m, _started(m), None, 300)
    assert m.tendon_frictionloss.max() > 0.005
    idx = arm_index(m)
    servo = replace(_loaded(0.05).joint("elbow_flex"), load_friction=0.0)
    for j in range(6):  # as a fit or the bench writes a servo
        write_servo(m, int(idx.actuator[j]), int(idx.dof[j]), servo)
    assert active_load_friction(m) is None and not m.tendon_frictionloss.any()
    ref = copy.copy(load_model())
    for j in range(6):
        write_servo(ref, int(idx.actuator[j]), int(idx.dof[j]), servo)
    d, d0 = _started(m), _started(ref)
    advance_unobserved(m, d, None, 600)
    advance_unobserved(ref, d0, None, 600)
    assert np.allclose(d.qpos, d0.qpos, atol=1e-12)


@pytest.mark.parametrize(("k", "holds"), [(0.0, False), (0.3, True)])
def test_a_loaded_servo_holds_a_goal_change_that_moves_a_servo_without_it(k, holds):
    """The forearm held out (its servo carrying ~0.5 N·m), friction that holds, little friction
    of its own: the goal moved 0.5° toward the sagging joint (the servo's torque eases by ~0.1
    N·m). Without load friction the joint follows; with 0.3 N·m per N·m it stays (for 10 s of
    simulated time), as a geared servo stuck under a load does."""
    prof = replace(_loaded(k, frictionloss=0.02, drive_frictionloss=0.0), static_friction=True)
    sim = Simulation(arm=prof)
    sim.move_to(FOLDED, 1.0)
    sim.hold(2.0)
    before = sim.pose()["elbow_flex"]
    assert before > FOLDED["elbow_flex"] + 1.0  # sagging under the forearm's weight
    goal = dict(FOLDED, elbow_flex=FOLDED["elbow_flex"] + 0.5)
    sim.move_to(goal, 0.1)
    sim.hold(10.0)
    moved = abs(sim.pose()["elbow_flex"] - before)
    assert sim.time == pytest.approx(13.1)
    if holds:
        assert moved < 0.02
    else:
        assert moved > 0.3


def test_a_diverged_loaded_model_is_left_with_a_finite_friction():
    """The divergence check puts the last good state back: the load's share (kept beside the
    state, in userdata) is that state's, so the model steps on from it as from any other."""
    m = copy.copy(load_model(arm=_loaded(0.057)))
    found = load_friction(m)
    m.actuator_gainprm[:, 0] = 1e9  # absurd gains: the explicit integrator blows up
    m.actuator_biasprm[:, 1] = -1e9
    m.actuator_forcerange[:] = [-1e12, 1e12]
    for fast in (True, False):
        d = _started(m)
        d.ctrl[:6] = 0.0
        with pytest.raises(SimulationDivergedError, match="diverged"):
            if fast:
                advance_unobserved(m, d, None, 500)
            else:
                step_block(m, d, np.repeat(d.ctrl[None], 500, axis=0))
        assert np.isfinite(d.qpos).all() and d.time < 500 * m.opt.timestep
        # the share of the state it is left in (not of the block's diverged end)
        share = 0.057 * np.abs(d.actuator_force[found.actuators])
        assert np.isfinite(share).all()
        assert np.allclose(d.userdata[found.slots], share)
        assert np.allclose(m.tendon_frictionloss[found.tendons], share)
