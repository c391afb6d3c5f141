"""The real arm's stops: a range-mode recording's body joints reach the ends of the follower's
calibration sweep in ``compare`` and ``fit``, past the model's limits where a real arm sweeps
further (a folded rest pose against its stops)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pyarrow")

from fidelity_helpers import range_mode, true_arm, write_lerobot

from so101sim.fidelity.calibration import range_guess
from so101sim.fidelity.compare import compare, replay_episode
from so101sim.fidelity.fit import ArmReplayer
from so101sim.fidelity.logs import Episode, read_log
from so101sim.fidelity.stops import stop_limits, with_stops
from so101sim.model import default_units
from so101sim.model.index import arm_units
from so101sim.model.load import load_model
from so101sim.sim import Simulation
from so101sim.units import JOINT_NAMES

LIFT = JOINT_NAMES.index("shoulder_lift")


def _guess_ends() -> np.ndarray:
    scale, offset = range_guess()
    ends = np.full((2, len(JOINT_NAMES)), np.nan)
    ends[0, :5], ends[1, :5] = -100 * scale + offset, 100 * scale + offset
    return ends


def _folded(seconds: float = 3.0, fps: float = 30.0) -> tuple[np.ndarray, np.ndarray]:
    """Commands resting folded with shoulder_lift at -104 deg (past the model's -100), lifting
    to -60 and folding back."""
    t = np.arange(int(seconds * fps)) / fps
    cmd = np.tile(np.array([0.0, -104.0, 90.0, 60.0, 0.0, 10.0]), (len(t), 1))
    move = (t > 1.0) & (t < 2.0)
    cmd[move, LIFT] = -104.0 + 44.0 * np.sin(np.pi * (t[move] - 1.0))
    return t, cmd


@pytest.fixture(scope="module")
def folded():
    """An episode of a real arm whose stops are a typical follower's (its shoulder_lift reaches
    -105.9 deg), and the same arm read by a sim held at the model's limits."""
    arm = true_arm()
    base = load_model(arm=arm)
    wide = Simulation(with_stops(base, *stop_limits(arm_units(base), _guess_ends())))
    t, cmd = _folded()
    meas = replay_episode(wide, Episode(0, t, cmd, np.tile(cmd[0], (len(t), 1))))
    narrow = replay_episode(Simulation(base), Episode(0, t, cmd, meas))
    return arm, Episode(0, t, cmd, meas), narrow


def test_stop_limits_widen_never_narrow_and_read_through_a_calibration():
    units = default_units()
    lo, hi = units.limits
    same = stop_limits(units, None)
    np.testing.assert_array_equal(same[0], lo)
    np.testing.assert_array_equal(same[1], hi)
    ends = _guess_ends()
    wlo, whi = stop_limits(units, ends)
    assert wlo[LIFT] == pytest.approx(-100 * 1.033 - 2.6) and whi[LIFT] == pytest.approx(100.7)
    assert (wlo <= lo).all() and (whi >= hi).all()  # never narrower than the model
    assert wlo[-1] == lo[-1] and whi[-1] == hi[-1]  # the gripper keeps its range
    # a profile's [calibration] (reading = scale * angle + offset) moves the stops as angles
    scale, offset = np.ones(6), np.zeros(6)
    scale[LIFT], offset[LIFT] = 0.95, 3.0
    clo, _ = stop_limits(units, ends, scale, offset)
    assert clo[LIFT] == pytest.approx((ends[0, LIFT] - 3.0) / 0.95)
    scale[LIFT] = 1.2  # a stop inside the model's limit: the model's limit holds
    assert stop_limits(units, ends, scale, offset)[0][LIFT] == pytest.approx(lo[LIFT])
    # a model whose limits are already the stops is not copied
    base = load_model()
    assert with_stops(base, lo, hi) is base
    wide = with_stops(base, wlo, whi)
    assert wide is not base and arm_units(base).limits[0][LIFT] == pytest.approx(lo[LIFT])
    assert arm_units(wide).limits[0][LIFT] == pytest.approx(wlo[LIFT])


def test_a_range_mode_log_carries_its_stops_and_a_degrees_log_none(tmp_path, folded):
    _, ep, _ = folded
    ranged = write_lerobot(tmp_path / "r", [ep], transform=range_mode())
    log = read_log(ranged, default_units())
    np.testing.assert_allclose(log.stops[:, :5], _guess_ends()[:, :5])
    assert np.isnan(log.stops[:, -1]).all()
    degrees = write_lerobot(tmp_path / "d", [ep])
    assert read_log(degrees, default_units(), units="degrees").stops is None


def test_compare_replays_a_folded_arm_against_its_stops(tmp_path, folded):
    arm, ep, narrow = folded
    rest = ep.measured[:, LIFT] < -100.5
    assert rest.mean() > 0.5  # the real arm rests past the model's limit
    # a sim held at the model's limits is degrees off while the arm rests there
    assert np.mean(np.abs(narrow[rest, LIFT] - ep.measured[rest, LIFT])) > 2.5
    root = write_lerobot(tmp_path / "ds", [ep], transform=range_mode())
    res = compare(root, arm=arm, keep_traces=True)
    sim = res.traces[0]["sim_pose"]
    assert sim[rest, LIFT].min() < -103.0
    assert res.joints["shoulder_lift"].mae < 0.3
    # the replay's limits go with the result (compare --web poses its arms with them), and the
    # shared model keeps its own
    assert res.limits is not None and res.limits[0][LIFT] == pytest.approx(_guess_ends()[0, LIFT])
    assert arm_units(load_model(arm=arm)).limits[0][LIFT] == pytest.approx(-100.0)
    # in degrees the recording says nothing of the stops: the model's limits hold
    deg = compare(write_lerobot(tmp_path / "deg", [ep]), arm=arm, units="degrees")
    assert deg.joints["shoulder_lift"].mae > 1.5


def test_the_fit_replays_against_the_same_stops(folded):
    arm, ep, _ = folded
    servos = [{n: arm.joint(n) for n in JOINT_NAMES}]
    with_stops_ = ArmReplayer([ep], arm, stops=_guess_ends(), threads=1).replay(servos)[0]
    without = ArmReplayer([ep], arm, threads=1).replay(servos)[0]
    rest = ep.measured[:, LIFT] < -100.5
    assert np.mean(np.abs(with_stops_[:, LIFT] - ep.measured[:, LIFT])) < 0.3
    assert without[rest, LIFT].min() > -101.0  # held at the model's limit


def test_a_reversed_motor_drive_mode_1_gives_its_stops_lowest_first(tmp_path):
    """LeRobot's ``drive_mode`` 1 (a motor mounted the other way round) reads -100 at the
    angle's upper end: the stops are still (lower, upper) angles, and widen the model's range."""
    import json

    from so101sim.fidelity.calibration import calibration_of, to_arm_units

    cal = {n: {"id": i + 1, "drive_mode": 0, "homing_offset": 0, "range_min": 700,
               "range_max": 3400} for i, n in enumerate(JOINT_NAMES)}  # fmt: skip
    cal["shoulder_lift"]["drive_mode"] = 1
    path = tmp_path / "follower.json"
    path.write_text(json.dumps(cal))
    scale, offset = calibration_of(path)
    assert scale[LIFT] < 0 < scale[0]
    values = np.zeros((3, len(JOINT_NAMES)))
    _, _, guessed, ends = to_arm_units(values, values, "range", path, [])
    assert not guessed and ends is not None
    assert (ends[0, :5] < ends[1, :5]).all()
    sweep = (3400 - 700) / 4095 * 360  # the swept angle, either way round
    np.testing.assert_allclose(ends[1, :5] - ends[0, :5], sweep, rtol=1e-3)
    assert ends[0, LIFT] == pytest.approx(100.0 * scale[LIFT] + offset[LIFT])
    lo, hi = stop_limits(default_units(), ends)
    units_lo, units_hi = default_units().limits
    assert lo[LIFT] == pytest.approx(min(ends[0, LIFT], units_lo[LIFT]))
    assert hi[LIFT] == pytest.approx(max(ends[1, LIFT], units_hi[LIFT]))
