"""The lab helpers' warnings from the kernel's recorded states (preflight.states): the same
samples as the per-step recorder, bit for bit, with the physics stepped in whole blocks."""

from __future__ import annotations

import numpy as np
import pytest

from so101sim import Simulation
from so101sim.preflight.measure import StepRecorder
from so101sim.preflight.states import StateRecorder, vectorisable
from so101sim.units import STARTING_POSE, ZERO_POSE

INTO_FLOOR = {**ZERO_POSE, "shoulder_lift": 60.0, "elbow_flex": 60.0}
CURLED = {**ZERO_POSE, "shoulder_lift": -90.0, "elbow_flex": 90.0, "wrist_flex": 95.0}
EVERY_JOINT = {
    "shoulder_pan": 60.0, "shoulder_lift": 30.0, "elbow_flex": -20.0, "wrist_flex": 40.0,
    "wrist_roll": 90.0, "gripper": 80.0,
}  # fmt: skip


def _record(cls, poses, arm="official"):
    sim = Simulation(arm=arm)  # official: forces from the states (plain position actuators)
    recs = []
    for pose in poses:
        move, hold = cls(sim.model), cls(sim.model)
        sim.move_to(pose, 0.8, observers=[move], trace=True)
        sim.hold(0.3, observers=[hold], trace=True)
        recs += [move, hold]
    return sim, recs


@pytest.mark.parametrize(
    ("path", "arm"), [("twin", "official"), ("screen", "official"), ("twin", None)]
)
@pytest.mark.parametrize(
    "poses",
    [
        [ZERO_POSE, STARTING_POSE],
        [INTO_FLOOR, STARTING_POSE],
        [CURLED, INTO_FLOOR],
        [EVERY_JOINT, INTO_FLOOR, EVERY_JOINT, STARTING_POSE],
    ],
)
def test_the_state_recorder_gives_the_step_recorders_samples_bit_for_bit(
    poses, path, arm, monkeypatch
):
    """Both contact paths: the kernel's contact twin (the shipped model: each step's contact
    count from a contact sensor), and the screen (a model with no twin); on the default arm
    (arm None: the fitted servo's delay and slewed goal) the twin's force sensors give the
    forces."""
    from so101sim.sim import stepping

    used = []
    real = stepping.contact_twin
    if path == "screen":
        monkeypatch.setattr(stepping, "contact_twin", lambda m: used.append(m) and None)
    else:
        monkeypatch.setattr(stepping, "contact_twin", lambda m: used.append(m) or real(m))
    a, steps = _record(StepRecorder, poses, arm)
    b, states = _record(StateRecorder, poses, arm)
    assert used and (path == "screen" or real(b.model) is not None)
    assert np.array_equal(a.data.qpos, b.data.qpos)  # the same physics
    touched = 0
    for s, v in zip(steps, states, strict=True):
        assert np.array_equal(np.array(s.times), v.times)
        assert np.array_equal(np.array(s.forces), v.forces)  # MuJoCo's own forces, exactly
        assert s.contacts == v.contacts  # every contact of every step, same order and depth
        touched += len(v.contacts)
    if INTO_FLOOR in poses:
        assert touched > 0  # the cases that touch did touch


def test_the_lab_helpers_step_whole_blocks_in_c(monkeypatch):
    from so101sim.lab import hold_position, move_to_pose
    from so101sim.sim import stepping

    sim = Simulation(arm="official")  # the handout's model: the file's own actuators
    assert vectorisable(sim.model)
    # the default arm's servo (slew-limited goal, delay) acts on more than the states hold
    assert not vectorisable(Simulation().model)
    blocks = []
    real = stepping.step_block
    monkeypatch.setattr(
        stepping, "step_block", lambda m, d, c, **k: blocks.append(len(c)) or real(m, d, c, **k)
    )
    move_to_pose(sim.model, sim.data, None, ZERO_POSE, 2.0)
    hold_position(sim.model, sim.data, None, 2.0)
    assert blocks == [1000, 1000]  # one call into C per segment, not one per step
    blocks.clear()
    default = Simulation()  # the default arm: its twin's sensors give the forces
    move_to_pose(default.model, default.data, None, ZERO_POSE, 2.0)
    hold_position(default.model, default.data, None, 2.0)
    assert blocks == [1000, 1000]


def test_a_model_whose_forces_do_not_follow_from_the_states_is_watched_per_step():
    import copy

    from so101sim.model import load_model

    m = copy.copy(load_model())
    m.actuator_gaintype[0] = 2  # user-defined gain: nothing to vectorise
    assert not vectorisable(m)


@pytest.mark.parametrize("seed", [0, 1])
def test_the_screen_never_clears_a_pair_that_touches(seed):
    """The screen's promise, checked against MuJoCo's own collision detection: at random arm
    positions, a pair of bodies whose gap exceeds its bound (joint travel times the pair's
    levers) does not touch at a nearby position; and every pair MuJoCo reports is one of the
    screen's pairs."""
    import mujoco

    from so101sim.preflight import screen

    sim = Simulation()
    m = sim.model
    scr = screen._screen(m)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    lo, hi = m.jnt_range[:, 0], m.jnt_range[:, 1]
    cleared = touching = 0
    for _ in range(150):
        qa = rng.uniform(lo, hi)
        gap = screen.gaps(m, scr, qa, 0.0)
        step = rng.normal(size=m.nv) * rng.choice([0.01, 0.05, 0.2])
        qb = np.clip(qa + step, lo, hi)
        delta = np.abs(qb - qa)
        bound = delta @ scr.lever.T
        d.qpos[:] = qb
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        bodies = m.geom_bodyid[d.contact.geom[: d.ncon]]
        pair = scr.pair_of[bodies[:, 0], bodies[:, 1]]
        assert (pair >= 0).all()  # MuJoCo's pairs are among the screen's
        touching += d.ncon > 0
        clear = bound < gap - screen._TOLERANCE_M
        cleared += int(clear.sum())
        assert not clear[pair].any()  # a cleared pair never touches
    assert touching > 0 and cleared > 0  # both cases were met


def test_the_contact_twin_has_the_models_physics_bit_for_bit():
    """Stepped for thousands of steps with the same targets, the twin (the model with a
    contact sensor and force sensors) and the model end in the same state; its sensors count
    each step's contacts as the model's own step finds them (self-contact and the floor
    included) and give the model's actuator forces."""
    import mujoco

    from so101sim.model.twin import contact_twin

    sim = Simulation()
    m = sim.model
    twin = contact_twin(m)
    assert twin is not None and twin.model.nsensordata == m.nsensordata + 1 + m.nu
    d, td = mujoco.MjData(m), mujoco.MjData(twin.model)
    rng = np.random.default_rng(3)
    lo, hi = m.actuator_ctrlrange.T
    touched = 0
    for i in range(3000):
        if i % 200 == 0:
            ctrl = rng.uniform(lo, hi)
        d.ctrl[:] = td.ctrl[:] = ctrl
        mujoco.mj_step(m, d)
        mujoco.mj_step(twin.model, td)
        assert td.sensordata[twin.found] == d.ncon
        assert np.array_equal(td.sensordata[twin.forces], d.actuator_force)
        touched += d.ncon > 0
    assert np.array_equal(d.qpos, td.qpos) and np.array_equal(d.qvel, td.qvel)
    assert touched > 0


def test_a_model_with_no_source_has_no_twin_and_a_copy_of_one_has():
    import copy

    import mujoco

    from so101sim.model import load_model
    from so101sim.model.twin import contact_twin

    m = load_model()
    assert contact_twin(copy.copy(m)) is not None  # the same model: found by its signature
    other = copy.copy(m)
    other.body_pos[2, 0] += 0.01  # a field the twin copies from the model before each use
    assert contact_twin(other) is not None
    assert np.array_equal(contact_twin(other).model.body_pos, other.body_pos)
    other.jnt_stiffness[0] += 1.0  # synced too, after the twin was made
    assert contact_twin(other).model.jnt_stiffness[0] == other.jnt_stiffness[0]
    other = copy.copy(m)
    other.dof_invweight0[0] += 1.0  # not synced: a different model, no twin
    assert contact_twin(other) is None
    xml = "<mujoco><worldbody><geom type='plane' size='1 1 1'/></worldbody></mujoco>"
    assert contact_twin(mujoco.MjModel.from_xml_string(xml)) is None


def test_a_changed_model_gives_the_step_recorders_samples_on_its_twin():
    """A copy of the loaded model with other gains and heavier links (fields the twin copies
    before each use), changed again after the first segment: the same samples and physics."""
    import copy

    from so101sim.model import load_model
    from so101sim.model.twin import contact_twin

    def run(cls):
        m = copy.copy(load_model())
        m.actuator_gainprm[1, 0] *= 0.5
        m.actuator_biasprm[1, 1] *= 0.5
        sim = Simulation(m)
        recs = [cls(m), cls(m)]
        sim.move_to(INTO_FLOOR, 0.8, observers=[recs[0]], trace=True)
        m.body_mass[3] *= 1.5
        sim.move_to(STARTING_POSE, 0.8, observers=[recs[1]], trace=True)
        return sim, recs

    a, steps = run(StepRecorder)
    b, states = run(StateRecorder)
    assert contact_twin(b.model) is not None
    assert np.array_equal(a.data.qpos, b.data.qpos)
    for s, v in zip(steps, states, strict=True):
        assert np.array_equal(np.array(s.forces), v.forces)
        assert s.contacts == v.contacts
    assert sum(len(v.contacts) for v in states) > 0
