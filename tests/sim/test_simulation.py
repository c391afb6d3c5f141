import copy
import math

import mujoco
import numpy as np
import pytest
from fakes import FakeClock

from so101sim import Simulation
from so101sim.errors import (
    JointLimitError,
    JointValueError,
    SettingError,
    SimulationDivergedError,
)
from so101sim.model import load_model
from so101sim.sim.simulation import Observer, Pacer, ViewerObserver, advance
from so101sim.units import STARTING_POSE, ZERO_POSE


class FakeViewer:
    def __init__(self, close_after: int | None = None) -> None:
        self.syncs = 0
        self.close_after = close_after

    def is_running(self) -> bool:
        return self.close_after is None or self.syncs < self.close_after

    def sync(self) -> None:
        self.syncs += 1


def test_new_simulation_is_at_rest_pose(sim):
    assert sim.time == 0.0
    assert sim.timestep == 0.002
    for n, v in STARTING_POSE.items():
        assert sim.pose()[n] == pytest.approx(v, abs=1e-9)
    assert sim.commanded() == pytest.approx(STARTING_POSE)


def test_two_second_move_is_1000_steps(sim):
    r = sim.move_to(ZERO_POSE, 2.0)
    assert r.steps == 1000
    assert sim.time == pytest.approx(2.0, abs=1e-9)


def test_steps_round_to_the_nearest_step(sim):
    assert sim.hold(0.0031).steps == 2
    assert sim.hold(0.0001).steps == 1  # never zero steps for a positive duration


def test_rollout_and_python_loop_are_bit_identical():
    m = load_model()
    targets = np.linspace(-0.5, 0.5, 300)[:, None] * np.ones(6)
    targets[:, 5] = 0.0

    class EveryStep(Observer):  # forces one-step blocks, i.e. the Python loop
        def __init__(self):
            self.t = 0.0

        def next_time(self):
            return self.t

        def on_time(self, m, d):
            self.t = d.time + 1e-6
            return True

    d1, d2 = mujoco.MjData(m), mujoco.MjData(m)
    tr1 = advance(m, d1, targets)
    tr2 = advance(m, d2, targets, [EveryStep()])
    np.testing.assert_array_equal(tr1.qpos, tr2.qpos)
    np.testing.assert_array_equal(tr1.time, tr2.time)
    np.testing.assert_array_equal(d1.qvel, d2.qvel)
    np.testing.assert_array_equal(d1.qacc_warmstart, d2.qacc_warmstart)


def test_trace_records_each_step(sim):
    tr = sim.step(10)
    assert len(tr) == 10
    np.testing.assert_allclose(tr.time, 0.002 * np.arange(1, 11))
    assert tr.completed


def test_pacer_sleeps_to_absolute_deadlines_without_drift():
    clock = FakeClock()
    pacer = Pacer(clock=clock, sleep=clock.sleep)
    pacer.wait(0.0)  # anchors
    for k in range(1, 601):
        clock.t += 0.003  # work takes 3 ms of wall time per 1/60 s frame
        pacer.wait(k / 60)
        # after each wait, the wall clock is exactly on the frame's deadline
        assert clock.t == pytest.approx(100.0 + k / 60, abs=1e-9)
    assert len(clock.sleeps) == 600
    assert clock.sleeps[0] == pytest.approx(1 / 60 - 0.003)


def test_pacer_speed_and_catching_up():
    clock = FakeClock()
    pacer = Pacer(speed=2.0, clock=clock, sleep=clock.sleep, max_lag=0.25)
    pacer.wait(1.0)
    pacer.wait(2.0)  # 1 s of sim at 2x = 0.5 s of wall time
    assert clock.t == pytest.approx(100.5)
    clock.t += 0.1  # fell behind by less than max_lag: no sleep, no re-anchor
    pacer.wait(2.1)
    assert clock.t == pytest.approx(100.6) and pacer.lag_events == 0
    clock.t += 5.0  # a long stall: re-anchor instead of racing
    pacer.wait(2.2)
    assert pacer.lag_events == 1 and pacer.lag_s == pytest.approx(5.0)  # due at 100.6
    pacer.wait(3.2)
    assert clock.t == pytest.approx(105.6 + 0.5)


def test_pacer_rejects_bad_speed():
    with pytest.raises(ValueError):
        Pacer(0.0)


def test_viewer_is_synced_at_its_rate_and_paced_by_sim_time(sim):
    clock = FakeClock()
    viewer = FakeViewer()
    obs = ViewerObserver(viewer, Pacer(clock=clock, sleep=clock.sleep), fps=50)
    sim.observers.append(obs)
    r = sim.move_to(ZERO_POSE, 1.0)
    assert r.steps == 500 and r.completed
    # a sync at t=0 and one every 1/50 s of simulated time after it
    assert viewer.syncs == 51
    # the fake wall clock advanced by exactly the simulated time: real time, no drift
    assert clock.t == pytest.approx(100.0 + 1.0, abs=1e-9)


class StallingViewer(FakeViewer):
    """A viewer whose tenth draw takes 2 s of the (fake) wall clock: the run falls behind."""

    def __init__(self, clock: FakeClock) -> None:
        super().__init__()
        self.clock = clock

    def sync(self) -> None:
        super().sync()
        if self.syncs == 10:
            self.clock.t += 2.0


def test_a_viewer_that_falls_behind_real_time_is_said_once(sim, caplog, monkeypatch):
    import so101sim.sim.observers as observers

    monkeypatch.setattr(observers, "_wall", lambda: 0.0)  # draws cost nothing: a fixed rate
    clock = FakeClock()
    viewer = StallingViewer(clock)
    sim.observers.append(ViewerObserver(viewer, Pacer(clock=clock, sleep=clock.sleep), fps=50))
    with caplog.at_level("WARNING", logger="so101sim"):
        r = sim.move_to(ZERO_POSE, 1.0)
        sim.hold(1.0)
    assert r.completed and sim.time == pytest.approx(2.0)  # simulated time is unaffected
    said = [rec.getMessage() for rec in caplog.records if "fell behind real time" in rec.message]
    assert len(said) == 1, said
    # the 2 s stall came in the 10th draw (t = 0.18 s): said at the next draw, due 0.02 s later
    assert "at 0.20 s of simulated time (1.98 s behind the wall clock)" in said[0]
    # the script's own time between two runs (input(), a plot) is not the viewer's lag
    caplog.clear()
    paused = Simulation()
    clock3 = FakeClock()
    paused.observers.append(ViewerObserver(FakeViewer(), Pacer(clock=clock3, sleep=clock3.sleep)))
    with caplog.at_level("WARNING", logger="so101sim"):
        paused.hold(0.2)
        clock3.t += 3.0
        paused.hold(0.2)
    assert paused.observers[0].pacer.lag_events == 0
    # the second hold in real time (to a frame, 1/60 s)
    assert clock3.t == pytest.approx(100.0 + 0.2 + 3.0 + 0.2, abs=0.03)
    assert not [rec for rec in caplog.records if "fell behind" in rec.message]
    # no warning from an observer told not to (so101sim run says it at the end instead)
    caplog.clear()
    quiet = Simulation()
    clock2 = FakeClock()
    quiet.observers.append(
        ViewerObserver(
            StallingViewer(clock2), Pacer(clock=clock2, sleep=clock2.sleep), 50, warn_lag=False
        )
    )
    with caplog.at_level("WARNING", logger="so101sim"):
        quiet.hold(0.5)
    assert quiet.observers[0].pacer.lag_events == 1
    assert not [rec for rec in caplog.records if "fell behind" in rec.message]


def test_closing_the_viewer_ends_the_run(sim):
    viewer = FakeViewer(close_after=10)
    clock = FakeClock()
    sim.observers.append(ViewerObserver(viewer, Pacer(clock=clock, sleep=clock.sleep), fps=50))
    r = sim.move_to(ZERO_POSE, 2.0)
    assert not r.completed
    assert r.steps < 1000
    assert sim.time == pytest.approx(r.end_time)


def test_set_pose_and_command(sim):
    sim.set_pose(ZERO_POSE)
    assert sim.pose() == pytest.approx(ZERO_POSE, abs=1e-12)
    full = sim.command({"elbow_flex.pos": 10.0})
    assert full["elbow_flex"] == 10.0 and full["shoulder_lift"] == 0.0
    sim.step(500)
    # the default arm (sts3215, P = 16) sags about 2° under the forearm's weight
    assert sim.pose()["elbow_flex"] == pytest.approx(10.0, abs=3.0)
    ideal = Simulation(arm="official", initial_pose=ZERO_POSE)
    ideal.command({"elbow_flex.pos": 10.0})
    ideal.step(500)
    assert ideal.pose()["elbow_flex"] == pytest.approx(10.0, abs=0.5)  # the vendored actuator


def test_bad_target_moves_nothing(sim):
    before = sim.data.qpos.copy(), sim.data.ctrl.copy(), sim.time
    with pytest.raises(JointLimitError):
        sim.move_to({**ZERO_POSE, "wrist_flex": 200}, 1.0)
    with pytest.raises(JointLimitError):
        sim.command({"wrist_flex": -200})
    np.testing.assert_array_equal(sim.data.qpos, before[0])
    np.testing.assert_array_equal(sim.data.ctrl, before[1])
    assert sim.time == before[2]


def test_reset(sim):
    sim.move_to(ZERO_POSE, 0.5)
    sim.reset()
    assert sim.time == 0.0
    assert sim.pose() == pytest.approx(STARTING_POSE, abs=1e-9)


def test_divergence_is_reported():
    m = copy.copy(load_model())
    m.actuator_gainprm[:, 0] = 1e9  # absurd gains: the explicit integrator blows up
    m.actuator_biasprm[:, 1] = -1e9
    m.actuator_forcerange[:] = [-1e12, 1e12]
    sim = Simulation(m)
    with pytest.raises(SimulationDivergedError, match="diverged"):
        sim.move_to(ZERO_POSE, 1.0)


def test_model_path_is_accepted(tmp_path):
    from so101sim.model import scene_path

    sim = Simulation(scene_path())
    assert sim.model is load_model()
    assert math.isclose(sim.pose()["shoulder_lift"], -98.0)


def test_viewer_keeps_pacing_after_a_reset(sim):
    clock = FakeClock()
    viewer = FakeViewer()
    sim.observers.append(ViewerObserver(viewer, Pacer(clock=clock, sleep=clock.sleep), fps=50))
    sim.move_to(ZERO_POSE, 1.0)
    syncs, wall = viewer.syncs, clock.t
    sim.reset()  # simulated time goes back to 0
    sim.move_to(ZERO_POSE, 1.0)
    assert viewer.syncs - syncs == 51  # synced again at its rate
    assert clock.t - wall == pytest.approx(1.0, abs=1e-9)  # and paced in real time again


def test_a_target_written_to_ctrl_directly_is_honoured(sim):
    import mujoco

    from so101sim.model import default_units

    sim.data.ctrl[:6] = default_units().to_radians(np.array([0.0, 0, 0, 0, 0, 0]))
    assert sim.commanded() == pytest.approx(ZERO_POSE)
    sim.hold(2.0)  # holds what is in ctrl, not the earlier target (-98°)
    # ... sagging under the arm's weight by a few degrees (sts3215, P = 16), not at -98°
    assert sim.pose()["shoulder_lift"] == pytest.approx(0.0, abs=5.0)
    fresh = mujoco.MjData(sim.model)  # never commanded: targets untouched
    from so101sim.sim.simulation import Simulation

    assert not Simulation.attach(sim.model, fresh).was_commanded


def test_nan_state_is_reported_even_without_a_mujoco_warning(sim):
    import mujoco

    from so101sim.sim.stepping import _STATE_SPEC, _check_divergence

    s0 = np.empty(mujoco.mj_stateSize(sim.model, _STATE_SPEC))
    mujoco.mj_getState(sim.model, sim.data, s0, _STATE_SPEC)
    states = np.repeat(s0[None], 2, axis=0)
    states[:, 0] += [0.002, 0.004]
    states[1, 1 + sim.index.qpos[1]] = np.nan
    with pytest.raises(SimulationDivergedError, match="NaN or inf") as info:
        _check_divergence(sim.model, sim.data, states, s0, 1 + sim.index.qpos)
    assert "t = 0.004 s" in str(info.value)  # the step it happened in
    assert sim.time == pytest.approx(0.002)  # left at the last good state
    assert np.isfinite(sim.data.qpos).all()


def test_commanded_reads_the_value_commanded(sim):
    sim.command({"wrist_flex": 60.0, "gripper": 33.3})
    assert sim.commanded()["wrist_flex"] == 60.0
    assert sim.commanded()["gripper"] == 33.3


def test_step_count_must_be_a_whole_number(sim):
    from so101sim.errors import SettingError

    for bad in (-1, 2.5, True):
        with pytest.raises(SettingError, match="whole number of steps"):
            sim.step(bad)


def _unstable_sim() -> Simulation:
    m = copy.copy(load_model())
    m.actuator_gainprm[:, 0] = 1e9  # absurd gains: the explicit integrator blows up
    m.actuator_biasprm[:, 1] = -1e9
    m.actuator_forcerange[:] = [-1e12, 1e12]
    return Simulation(m)


def test_divergence_is_detected_every_time_and_leaves_the_state_where_it_happened():
    sim = _unstable_sim()
    for _ in range(3):  # MuJoCo's reset zeroes its warning counter: each one is still seen
        t_before = sim.time
        with pytest.raises(SimulationDivergedError, match="diverged at t = ") as info:
            sim.move_to(ZERO_POSE, 1.0)
        assert sim.time >= t_before  # never back at 0 after a reset
        assert np.isfinite(sim.data.qpos).all() and np.isfinite(sim.data.qvel).all()
        assert f"{sim.time + sim.timestep:.3f} s" in str(info.value)


def test_a_long_hold_keeps_its_summary_but_no_per_step_arrays(sim):
    from so101sim.sim.simulation import TRACE_AUTO_STEPS

    r = sim.hold(TRACE_AUTO_STEPS * sim.timestep + 1.0)  # over the automatic limit
    assert r.steps == TRACE_AUTO_STEPS + 500
    assert r.times.size == 0 and r.commanded.shape == (0, 6) and r.measured.shape == (0, 6)
    assert r.max_tracking_error["shoulder_lift"] > 0
    assert r.target == pytest.approx(STARTING_POSE, abs=1e-9)
    short = sim.hold(2.0)  # short segments keep it, as before
    assert short.times.size == 1000
    kept = sim.hold(1.0, trace=False)
    assert kept.times.size == 0 and kept.steps == 500


def test_summary_without_trace_equals_summary_with_it():
    a, b = Simulation(), Simulation()
    ra = a.move_to(ZERO_POSE, 2.0, trace=True)
    rb = b.move_to(ZERO_POSE, 2.0, trace=False)
    assert ra.max_tracking_error == rb.max_tracking_error  # bit for bit
    assert ra.target == rb.target and ra.reached == rb.reached


def test_huge_durations_and_counts_are_refused_before_anything_is_allocated(sim):
    from so101sim.errors import DurationError, SettingError

    for bad in (1e9, 1e308, 10**400):
        with pytest.raises(DurationError, match="at most"):
            sim.hold(bad)
        with pytest.raises(DurationError, match="at most 3600 s"):
            sim.move_to(ZERO_POSE, bad)
    with pytest.raises(SettingError, match="whole number of steps"):
        sim.step(10**12)
    assert sim.time == 0.0


def test_data_of_another_model_is_refused():
    import mujoco

    from so101sim.errors import ModelError

    other = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    with pytest.raises(ModelError, match="another model"):
        Simulation(load_model(), data=mujoco.MjData(other))


def test_likely_unit_mistakes_are_warned_before_the_run(sim, caplog):
    import logging

    radians = {
        "shoulder_pan": 0,
        "shoulder_lift": 1.57,
        "elbow_flex": -1.2,
        "wrist_flex": 0.3,
        "wrist_roll": 0,
        "gripper": 0,
    }
    with caplog.at_level(logging.WARNING, logger="so101sim"):
        sim.move_to(radians, 0.1)
    assert "looks like radians" in caplog.text and "90.0°" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="so101sim"):
        sim.move_to({**STARTING_POSE, "gripper": 0.5}, 0.1)
        sim.hold(601.0, trace=False)
    assert "gripper = 0.5 looks like a fraction" in caplog.text
    assert "did you mean milliseconds" in caplog.text


def test_no_unit_warning_for_the_lab_motion(caplog):
    import logging

    from so101sim.motion import LAB_MOTION, run_segments

    with caplog.at_level(logging.WARNING, logger="so101sim"):
        run_segments(Simulation(), LAB_MOTION)
        Simulation().move_to(
            {
                "shoulder_pan": 0,
                "shoulder_lift": 2,
                "elbow_flex": 3,
                "wrist_flex": 0,
                "wrist_roll": 0,
                "gripper": 0,
            },
            0.5,
        )
    assert caplog.text == ""


def test_a_viewer_without_sync_is_refused_before_anything_moves(sim):
    from so101sim.errors import SettingError

    for bad in ("viewer", object(), 3):
        with pytest.raises(SettingError, match="sync"):
            sim.move_to(ZERO_POSE, 0.5, viewer=bad)
    assert sim.time == 0.0


def test_tip_moves_in_a_straight_line_and_report_the_tracking():
    from so101sim.kinematics import line_deviation

    sim = Simulation(initial_pose=ZERO_POSE, arm="official")  # the planner, on ideal servos
    start = sim.tip().position
    goal = (0.25, 0.05, 0.10)
    r = sim.move_to(tip=goal, pitch=-60, duration=2.0, shape="minimum_jerk", trace=True)
    commanded = line_deviation(r.commanded, start, goal, model=sim.model)
    measured = line_deviation(r.measured, start, goal, model=sim.model)
    assert commanded.max_mm <= 2.0  # the commanded tip stays on the line
    assert measured.max_mm < 10.0  # and the arm follows it closely (reported by check)
    assert np.linalg.norm(sim.tip().position - goal) < 0.005
    assert r.steps == 1000 and sim.commanded()["gripper"] == pytest.approx(0.0, abs=1e-6)


def test_a_tip_out_of_reach_raises_before_anything_moves():
    from so101sim.errors import UnreachableError

    sim = Simulation()
    with pytest.raises(UnreachableError, match="mm"):
        sim.move_to(tip=(0.9, 0.0, 0.1), duration=2.0)
    with pytest.raises(UnreachableError):
        sim.move_to(tip=(0.9, 0.0, 0.1), duration=2.0, path="joint")
    assert sim.time == 0.0


def test_a_joint_space_tip_move_ends_at_the_tip_and_paths_are_checked():
    from so101sim.errors import DurationError, SettingError

    sim = Simulation(arm="official")  # the planner, on ideal servos (sts3215 sags ~1 cm here)
    sim.move_to(tip=(0.2, -0.1, 0.05), pitch=-90, duration=2.0, path="joint", shape="limited")
    sim.hold(0.5)
    assert np.linalg.norm(sim.tip().position - (0.2, -0.1, 0.05)) < 0.005
    assert sim.tip().pitch == pytest.approx(-90, abs=2.0)
    with pytest.raises(SettingError, match="valid paths are line, joint"):
        sim.move_to(tip=(0.2, 0, 0.1), duration=1.0, path="arc")
    with pytest.raises(SettingError, match="straight-line"):
        sim.move_to(tip=(0.2, 0, 0.1), duration=1.0, shape="limited")
    with pytest.raises(DurationError, match="missing"):
        sim.move_to(tip=(0.2, 0, 0.1))
    with pytest.raises(SettingError, match="target pose or tip"):
        sim.move_to(duration=1.0)


def test_stepping_with_nothing_watching_is_the_same_physics_bit_for_bit():
    watched, plain = Simulation(), Simulation()
    for s in (watched, plain):
        s.command(ZERO_POSE)
    for n in (1, 10, 47, 48, 5000):  # below, at and above the rollout and chunk sizes
        watched.step(n, trace=True)  # the observed path (a per-step trace)
        plain.step(n, trace=False)  # MuJoCo's own loop
        assert plain.time == watched.time
        assert np.array_equal(plain.data.qpos, watched.data.qpos)
        assert np.array_equal(plain.data.qvel, watched.data.qvel)
        assert np.array_equal(plain.data.ctrl, watched.data.ctrl)


def test_divergence_with_nothing_watching_is_caught_where_it_happened():
    for start in (0, 200):  # at time 0 a reset looks like the start: the warnings tell
        sim, watched = _unstable_sim(), _unstable_sim()
        for s in (sim, watched):
            s.data.time = start * s.timestep
            s.command(ZERO_POSE)
        with pytest.raises(SimulationDivergedError) as seen:
            watched.step(500, trace=True)
        with pytest.raises(SimulationDivergedError) as fast:
            sim.step(500, trace=False)
        assert str(fast.value) == str(seen.value)  # same step, same cause
        assert sim.time == watched.time and np.isfinite(sim.data.qpos).all()
        assert np.array_equal(sim.data.qpos, watched.data.qpos)


def test_a_never_commanded_arm_holds_its_pose_with_nothing_watching():
    sim = Simulation()
    before = sim.pose()
    sim.step(1000, trace=False)
    # it holds: the default servo (P = 16) settles 1.4° under the folded arm's weight
    assert sim.pose() == pytest.approx(before, abs=2.0)
    assert sim.commanded() == pytest.approx(before, abs=1e-6)


def test_pose_values_are_the_pose_array_as_plain_floats():
    from so101sim.sim import fastpath

    sim = Simulation()
    sim.move_to({**ZERO_POSE, "shoulder_pan": 20, "elbow_flex": 10, "gripper": 40}, 0.5)
    values = fastpath.pose_values(sim)
    assert all(type(v) is float for v in values)
    assert values == sim.pose_array().tolist()
    with pytest.warns(DeprecationWarning, match="fastpath.pose_values"):
        assert sim.pose_values() == values  # the old spelling, for one release


def test_the_old_spellings_warn_and_do_what_they_did():
    from so101sim.sim import fastpath

    sim, other = Simulation(), Simulation()
    with pytest.warns(DeprecationWarning, match="fastpath.command_joints"):
        sim.command_joints([1, 5], [-10.0, 30.0])
    fastpath.command_joints(other, [1, 5], [-10.0, 30.0])
    assert sim.commanded() == other.commanded()
    with pytest.warns(DeprecationWarning, match="use shape="):
        old = sim.move_to(ZERO_POSE, 0.2, profile="minimum_jerk")
    new = other.move_to(ZERO_POSE, 0.2, shape="minimum_jerk")
    assert old.reached == new.reached
    with pytest.raises(SettingError, match="shape= only"):
        sim.plan_move(ZERO_POSE, 0.2, shape="linear", profile="linear")


@pytest.mark.parametrize(
    ("values", "match"),
    [
        (np.zeros(5), r"shape \(5,\); expected six numbers"),
        (np.full(6, np.nan), "shoulder_pan = nan is not a finite number"),
        ([0, 0, 0, np.inf, 0, 50], "wrist_flex = inf is not a finite number"),
        ("x", "are not numbers; expected six numbers"),
        (None, "are not numbers|shape"),
    ],
)
def test_command_array_refuses_what_is_not_six_finite_numbers(values, match):
    """Issue 30: NaN passed command_array; np.zeros(5) gave a bare broadcasting error."""
    sim = Simulation()
    before = sim.commanded()
    for check in (True, False):
        with pytest.raises(JointValueError, match=match):
            sim.command_array(values, check=check)
    assert sim.commanded() == before  # nothing was set


def test_set_initial_pose_without_data_says_what_it_expected():
    from so101sim.lab.helpers import send_position_command, set_initial_pose

    for call in (set_initial_pose, send_position_command):
        with pytest.raises(SettingError, match=r"not a mujoco\.MjData; expected the d of"):
            call(None, STARTING_POSE)


def test_a_viewer_that_draws_slowly_is_synced_less_often_so_the_run_keeps_real_time(sim):
    """MuJoCo's passive viewer waits while it draws (about 25 ms on a CPU renderer): synced 60
    times a simulated second it would slow the run below real time. The observer measures a
    sync's cost and syncs less often: drawing takes at most half the wall time. The sync here
    takes at least 20 ms (a sleep; a busy machine only makes it longer), so at most one sync
    every 40 ms of simulated time: at most 26 for a 1 s move."""
    import time as _time

    class SlowViewer(FakeViewer):
        def sync(self):
            _time.sleep(0.02)
            super().sync()

    viewer = SlowViewer()
    clock = FakeClock()
    obs = ViewerObserver(viewer, Pacer(clock=clock, sleep=clock.sleep), fps=60)
    r = sim.move_to(ZERO_POSE, 1.0, observers=[obs])
    assert r.completed and r.steps == 500
    assert 5 <= viewer.syncs <= 26
    assert obs.sync_cost >= 0.02
