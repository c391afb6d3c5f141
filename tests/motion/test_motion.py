import math

import numpy as np
import pytest

from so101sim import LAB_MOTION, Hold, Move, run_motion
from so101sim.errors import DurationError, JointNameError, So101SimError
from so101sim.motion import PROFILES, SegmentResult, plan_move, steps_for
from so101sim.sim.simulation import Simulation
from so101sim.units import JOINT_NAMES, STARTING_POSE, ZERO_POSE


def within(pose, expected, tol):
    return all(abs(pose[n] - expected[n]) <= tol for n in JOINT_NAMES)


# degrees from the target at the end of each lab step (to_zero, hold, return): the vendored
# ideal actuators reach it; the fitted STS3215 (P = 16) sags under the arm's weight (measured:
# 7.8° at the elbow after the move, 2.9° after the hold, 6.1° at the shoulder back at rest)
LAB_REACH = {"official": (1.0, 1.0, 1.0), "sts3215": (8.5, 3.5, 7.0)}


@pytest.mark.parametrize("arm", LAB_REACH)
def test_lab_motion_reaches_its_targets(arm):
    sim = Simulation(arm=arm)
    result = run_motion(sim.model, sim.data, LAB_MOTION)
    to_zero, hold, back = result.segments
    assert [s.phase for s in result.segments] == ["to_zero", "hold", "return"]
    assert [s.steps for s in result.segments] == [1000, 1000, 1000]
    tol = LAB_REACH[arm]
    assert within(to_zero.reached, ZERO_POSE, tol[0])
    assert within(hold.reached, ZERO_POSE, tol[1])
    assert within(back.reached, STARTING_POSE, tol[2])
    if arm == "sts3215":  # it does sag: the figures above are not loose bounds on nothing
        assert max(to_zero.final_error.values()) > 5.0
    assert back.target == pytest.approx(STARTING_POSE)
    assert result.completed and result.end_time == pytest.approx(6.0)
    # the tracking error is reported per joint: small for a 2 s move on ideal servos, the
    # sag and lag of the fitted servo (8.0° at the elbow) on the default arm
    assert set(to_zero.max_tracking_error) == set(JOINT_NAMES)
    assert 0 < to_zero.worst_tracking_error[1] < (2.0 if arm == "official" else 9.0)


def test_two_runs_are_bit_identical(sim):
    from so101sim import Simulation

    a = run_motion(sim.model, sim.data, LAB_MOTION)
    other = Simulation()
    b = run_motion(other.model, other.data, LAB_MOTION)
    for sa, sb in zip(a.segments, b.segments, strict=True):
        np.testing.assert_array_equal(sa.measured, sb.measured)
        np.testing.assert_array_equal(sa.times, sb.times)
    np.testing.assert_array_equal(sim.data.qpos, other.data.qpos)


def test_linear_move_commands_straight_lines_ending_on_target(sim):
    r = sim.move_to(ZERO_POSE, 0.5)
    start = np.array([STARTING_POSE[n] for n in JOINT_NAMES])
    n = r.steps
    expected = start + (0 - start) * (np.arange(1, n + 1) / n)[:, None]
    np.testing.assert_allclose(r.commanded, expected, atol=1e-9)
    np.testing.assert_array_equal(r.commanded[-1], np.zeros(6))


def test_minimum_jerk_profile_is_smooth_at_both_ends(sim):
    r = sim.move_to(ZERO_POSE, 1.0, shape="minimum_jerk")
    c = r.commanded
    first = np.abs(c[1] - c[0]).max()
    middle = np.abs(c[251] - c[250]).max()
    assert first < middle / 100
    assert np.abs(c[-1] - c[-2]).max() < middle / 100
    assert c[-1] == pytest.approx(np.zeros(6))


def test_moves_start_from_the_last_commanded_target(sim):
    sim.move_to(ZERO_POSE, 1.0)
    r = sim.move_to({**ZERO_POSE, "shoulder_pan": 20.0}, 1.0)
    assert r.start == pytest.approx(ZERO_POSE)  # not the (slightly sagging) measured pose


def test_hold_keeps_the_last_target(sim):
    sim.move_to(ZERO_POSE, 1.0)
    r = sim.hold(3.0)
    assert r.kind == "hold"
    np.testing.assert_array_equal(r.commanded, np.zeros((1500, 6)))
    assert within(r.reached, ZERO_POSE, 3.0)  # sts3215 holds the arm out 2.7° low at most
    ideal = Simulation(arm="official")
    ideal.move_to(ZERO_POSE, 1.0)
    assert within(ideal.hold(3.0).reached, ZERO_POSE, 0.2)


@pytest.mark.parametrize("bad", [0, -1.0, math.nan, math.inf, "2", None, True])
def test_bad_durations(sim, bad):
    with pytest.raises(DurationError):
        sim.move_to(ZERO_POSE, bad)
    with pytest.raises(DurationError):
        sim.hold(bad)
    assert sim.time == 0.0


def test_steps_for():
    assert steps_for(2.0, 0.002) == 1000
    assert steps_for(0.5, 0.01) == 50


def test_unknown_profile_lists_valid_ones(sim):
    with pytest.raises(So101SimError, match="linear") as e:
        sim.move_to(ZERO_POSE, 1.0, shape="cubic")
    assert "minimum_jerk" in str(e.value)


def test_a_bad_step_anywhere_means_nothing_runs(sim):
    steps = [Move(ZERO_POSE, 1.0), Hold(1.0), Move({"elbow": 0.0}, 1.0)]
    with pytest.raises(JointNameError):
        run_motion(sim.model, sim.data, steps)
    assert sim.time == 0.0


def test_plan_move_returns_the_whole_move_at_once(sim):
    start, targets = plan_move(sim.model, sim.data, ZERO_POSE, 2.0)
    assert targets.shape == (1000, 6)
    assert start == pytest.approx([STARTING_POSE[n] for n in JOINT_NAMES])
    assert sim.time == 0.0  # planning does not step


def test_segment_result_helpers():
    sim = Simulation(arm="official")  # the ideal actuators end a move on its target
    r = sim.move_to(ZERO_POSE, 2.0)
    assert isinstance(r, SegmentResult)
    assert r.duration == pytest.approx(2.0)
    assert max(r.final_error.values()) < 1.0
    assert set(PROFILES) >= {"linear", "minimum_jerk"}


def test_tip_moves_in_a_sequence_are_planned_before_the_first_one_runs(sim):
    from so101sim.errors import UnreachableError
    from so101sim.motion import run_segments

    ok = [Move.to_tip((0.22, 0.0, 0.08), 1.0, pitch=-60), Move.to_tip((0.22, 0.08, 0.08), 1.0)]
    sim = Simulation(arm="official")  # the plan, on ideal servos (sts3215 sags 2.3 cm here)
    r = run_segments(sim, ok)
    assert r.completed and len(r.segments) == 2
    assert np.linalg.norm(sim.tip().position - (0.22, 0.08, 0.08)) < 0.01
    fresh = Simulation()
    bad = [Move.to_tip((0.22, 0.0, 0.08), 1.0), Move.to_tip((0.9, 0.0, 0.1), 1.0)]
    with pytest.raises(UnreachableError):
        run_segments(fresh, bad)
    assert fresh.time == 0.0  # the reachable first move did not run either


def test_commanded_path_is_what_a_run_commands_without_simulating():
    from so101sim.motion import commanded_path, run_segments

    sim = Simulation()
    times, path = commanded_path(sim.model, LAB_MOTION, STARTING_POSE)
    r = run_segments(sim, LAB_MOTION, trace=True)
    commanded = np.vstack([s.commanded for s in r.segments])  # via radians and back
    np.testing.assert_allclose(path, commanded, rtol=0, atol=1e-9)
    np.testing.assert_allclose(times, np.concatenate([s.times for s in r.segments]))
    assert sim.time == pytest.approx(6.0)


def test_a_motion_longer_than_a_day_in_all_is_refused_before_it_runs(sim):
    steps = [Hold(50_000.0), Hold(50_000.0)]
    with pytest.raises(DurationError, match="in all"):
        run_motion(sim.model, sim.data, steps)
    assert sim.time == 0.0
