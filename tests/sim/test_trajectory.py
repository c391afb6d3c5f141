"""Profiles: linear, minimum_jerk and the ruckig-planned ``limited`` profile."""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest

from so101sim.errors import SettingError, So101SimError, TrajectoryLimitError
from so101sim.model import default_units, load_model
from so101sim.motion import PROFILES, Hold, Move, get_profile, run_motion
from so101sim.motion.plan import plan_segments
from so101sim.sim.limited import STS3215_LIMITS, JointLimits, LimitedProfile
from so101sim.sim.simulation import Simulation
from so101sim.units import JOINT_NAMES, STARTING_POSE, ZERO_POSE

DT = 0.002
START = default_units().pose_to_array(STARTING_POSE)
TARGET = np.array([20.0, -10.0, 30.0, -15.0, 40.0, 60.0])


def check_limited_moves(start, steps, dt, *, strict=False):
    """The ``limited`` moves too short for the limits, as the motion planner finds them."""
    model = load_model()
    assert model.opt.timestep == dt
    return list(plan_segments(model, steps, start, strict=strict).stretched)


def _derivatives(start: np.ndarray, out: np.ndarray, dt: float):
    """Velocity, acceleration, jerk by finite differences, the move starting at rest."""
    x = np.vstack([start, start, start, out])
    v = np.diff(x, axis=0) / dt
    a = np.diff(v, axis=0) / dt
    j = np.diff(a, axis=0) / dt
    return v, a, j


@pytest.mark.parametrize("name", ["linear", "minimum_jerk", "limited"])
def test_each_profile_starts_and_ends_at_the_right_poses(name):
    out = PROFILES[name](START, TARGET, 1000, DT)
    assert out.shape == (1000, len(JOINT_NAMES))
    np.testing.assert_array_equal(out[-1], TARGET)
    # The first step moves away from the start by at most one step at the profile's speed.
    first_step = np.abs(out[0] - START)
    biggest_step = np.abs(np.diff(out, axis=0)).max(axis=0)
    assert np.all(first_step <= biggest_step + 1e-12)
    # No profile overshoots: every sample lies between start and target.
    lo, hi = np.minimum(START, TARGET), np.maximum(START, TARGET)
    assert np.all(out >= lo - 1e-9) and np.all(out <= hi + 1e-9)


def test_minimum_jerk_has_zero_velocity_at_both_ends():
    out = PROFILES["minimum_jerk"](START, TARGET, 1000, DT)
    v = np.diff(np.vstack([START, out]), axis=0) / DT
    peak = np.abs(v).max(axis=0)
    moving = peak > 0
    assert np.all(np.abs(v[0][moving]) < 1e-4 * peak[moving])
    assert np.all(np.abs(v[-1][moving]) < 1e-4 * peak[moving])
    # the linear profile, by contrast, starts at full speed
    lin = PROFILES["linear"](START, TARGET, 1000, DT)
    v_lin = (lin[0] - START) / DT
    np.testing.assert_allclose(np.abs(v_lin), np.abs(TARGET - START) / 2.0)


@pytest.mark.parametrize("n", [250, 1000, 2500])
def test_limited_respects_its_limits_on_every_step(n):
    prof = LimitedProfile()
    out = prof(START, TARGET, n, DT)
    vmax, amax, jmax = STS3215_LIMITS.in_arm_units(default_units())
    v, a, j = _derivatives(START, out, DT)
    rel = 1 + 1e-6
    assert np.all(np.abs(v) <= vmax * rel)
    assert np.all(np.abs(a) <= amax * rel)
    assert np.all(np.abs(j) <= jmax * rel)


def test_limited_finishes_all_joints_together():
    out = LimitedProfile()(START, TARGET, 1000, DT)
    moving = START != TARGET
    # Every moving joint is still short of its target one step before the end...
    assert np.all(np.abs(out[-2] - TARGET)[moving] > 0)
    # ...and still moving through the last tenth of the move, however short its own travel.
    tail = np.abs(np.diff(out[-100:], axis=0))[:, moving]
    assert np.all(tail.sum(axis=0) > 0)
    # On its own, shoulder_pan's 20° would take well under half the time: it was slowed down
    # to arrive with the others.
    pan_only = START.copy()
    pan_only[0] = TARGET[0]
    assert LimitedProfile().minimum_duration(START, pan_only) < 0.5 * len(out) * DT


def test_limited_takes_exactly_a_longer_requested_duration():
    prof = LimitedProfile()
    t_min = prof.minimum_duration(START, TARGET)
    n = math.ceil(t_min / DT) + 500
    out = prof(START, TARGET, n, DT)
    assert len(out) == n
    np.testing.assert_array_equal(out[-1], TARGET)


def test_limited_stretches_a_short_move_with_a_warning(caplog):
    prof = LimitedProfile()
    t_min = prof.minimum_duration(START, TARGET)
    with caplog.at_level(logging.WARNING, logger="so101sim.sim.limited"):
        out = prof(START, TARGET, 10, DT)
    assert len(out) == math.ceil(t_min / DT - 1e-9) > 10
    assert "stretching" in caplog.text
    np.testing.assert_array_equal(out[-1], TARGET)


def test_limited_strict_refuses_a_short_move():
    with pytest.raises(TrajectoryLimitError, match="at least") as exc:
        LimitedProfile(strict=True)(START, TARGET, 10, DT)
    assert isinstance(exc.value, So101SimError)


def test_limited_with_no_motion_holds_the_target():
    out = LimitedProfile()(TARGET, TARGET, 7, DT)
    np.testing.assert_array_equal(out, np.repeat(TARGET[None], 7, axis=0))


def test_joint_limits_are_validated():
    with pytest.raises(SettingError, match="velocity"):
        JointLimits.uniform(0.0, 1.0, 1.0)
    with pytest.raises(SettingError, match="6 finite"):
        JointLimits((1.0,), (1.0,) * 6, (1.0,) * 6)


def test_tighter_limits_give_longer_moves():
    slow = LimitedProfile(JointLimits.uniform(30.0, 100.0, 1000.0))
    assert slow.minimum_duration(START, TARGET) > LimitedProfile().minimum_duration(START, TARGET)


def test_check_limited_moves_before_a_run():
    steps = [
        Move(ZERO_POSE, 0.2, shape="limited", phase="fast"),
        Hold(1.0),
        Move(STARTING_POSE, 3.0, shape="limited", phase="slow"),
        Move(ZERO_POSE, 0.2, shape="linear", phase="linear"),
    ]
    short = check_limited_moves(START, steps, DT)
    assert [(s.index, s.phase) for s in short] == [(0, "fast")]
    assert short[0].minimum > short[0].requested
    with pytest.raises(TrajectoryLimitError, match="step 1 \\(fast\\)"):
        check_limited_moves(START, steps, DT, strict=True)


def test_a_profile_object_can_be_given_to_a_move():
    prof = LimitedProfile(strict=True)
    assert get_profile(prof) is prof
    sim = Simulation()
    r = run_motion(sim.model, sim.data, [Move(ZERO_POSE, 1.5, shape=prof)])
    assert r.segments[0].steps == 750
    assert r.segments[0].target == pytest.approx(ZERO_POSE)


def test_limited_runs_smoother_than_linear_in_the_simulation():
    errors = {}
    for name in ("linear", "limited"):
        sim = Simulation(arm="official")  # the ideal actuator: the error is the profile's own
        seg = sim.move_to(ZERO_POSE, 2.0, shape=name)
        errors[name] = seg.worst_tracking_error[1]
    assert errors["limited"] < errors["linear"]


def test_strict_refusal_quotes_a_duration_that_passes():
    # The lab's rest -> zero move: the limits need a fraction of a step more than 412 steps.
    prof = LimitedProfile()
    zero = default_units().pose_to_array(ZERO_POSE)
    t_min = prof.minimum_duration(START, zero)
    needed = math.ceil(t_min / DT) * DT
    assert needed > t_min  # t_min is not a whole number of steps, so rounding matters
    too_short = Move(ZERO_POSE, needed - DT, shape="limited")
    with pytest.raises(TrajectoryLimitError, match=f"need at least {needed:.3f} s"):
        check_limited_moves(START, [too_short], DT, strict=True)
    [short] = check_limited_moves(START, [too_short], DT)
    assert short.needed == pytest.approx(needed)
    # A request of exactly the quoted figure passes both the check and the strict profile.
    quoted = float(f"{needed:.3f}")
    assert check_limited_moves(START, [Move(ZERO_POSE, quoted, shape="limited")], DT) == []
    n = round(quoted / DT)
    out = LimitedProfile(strict=True)(START, zero, n, DT)
    assert len(out) == n
    with pytest.raises(TrajectoryLimitError, match=f"at least {needed:.3f} s"):
        LimitedProfile(strict=True)(START, zero, n - 1, DT)
