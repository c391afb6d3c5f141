"""``so101sim compare``: LeRobot datasets (v2.1, v3.0; degrees and range mode) and CSV logs of a
hidden "true" arm, replayed in the sim, read without lerobot."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("pyarrow")

from fidelity_helpers import commands, range_mode, record, true_arm, write_csv, write_lerobot

from so101sim.cli import main
from so101sim.errors import CalibrationError
from so101sim.fidelity.compare import compare, replay_episode
from so101sim.fidelity.logs import Episode, LogError, parse_episodes, read_log
from so101sim.model import default_units
from so101sim.model.arm import profile_toml
from so101sim.sim import Simulation
from so101sim.units import JOINT_NAMES


@pytest.fixture(scope="module")
def episodes():
    return record(true_arm(), [1, 2], seconds=2.0)


@pytest.fixture(scope="module")
def true_toml(tmp_path_factory):
    path = tmp_path_factory.mktemp("arm") / "true.toml"
    path.write_text(profile_toml(true_arm()))
    return path


@pytest.mark.parametrize("version", ["v3.0", "v2.1"])
def test_a_dataset_is_read_in_both_layouts(tmp_path, episodes, version):
    root = write_lerobot(tmp_path / "ds", episodes, version=version)
    log = read_log(root, default_units(), units="degrees")
    assert log.kind == f"lerobot-{version}"
    assert log.fps == 30 and [e.index for e in log.episodes] == [0, 1]
    for got, want in zip(log.episodes, episodes, strict=True):
        np.testing.assert_allclose(got.command, want.command, atol=1e-4)
        np.testing.assert_allclose(got.measured, want.measured, atol=1e-4)
        np.testing.assert_allclose(got.times, want.times, atol=1e-6)
    only = read_log(root, default_units(), episodes=[1], units="degrees")
    assert [e.index for e in only.episodes] == [1]
    with pytest.raises(LogError, match="has no episode 7; expected one of its episodes 0-1"):
        read_log(root, default_units(), episodes=[7], units="degrees")
    with pytest.raises(LogError, match="units = 'kelvin' is invalid"):
        read_log(root, default_units(), units="kelvin")


def test_the_true_profile_predicts_its_own_recording(tmp_path, episodes, true_toml):
    root = write_lerobot(tmp_path / "ds", episodes)
    right = compare(root, arm=true_toml, units="degrees")
    wrong = compare(root, arm="official", units="degrees")
    assert right.frames == sum(len(e.times) for e in episodes) and right.episodes == [0, 1]
    for name in JOINT_NAMES:
        assert right.joints[name].mae < 0.1  # degrees: the same arm, replayed
        assert abs(right.joints[name].lag_s) <= 1 / 30 + 1e-9
    # the vendored arm is too stiff and has no delay: it leads the real arm and is further off
    for name in ("shoulder_lift", "elbow_flex"):
        assert wrong.joints[name].mae > 5 * right.joints[name].mae
        assert wrong.joints[name].lag_s > 0.02
        assert right.joints[name].mae < right.command_baseline[name]


def test_range_mode_with_and_without_calibration(tmp_path, episodes, capsys):
    lo_t = np.array([1000, 800, 900, 850, 100, 2000])
    hi_t = np.array([3000, 3200, 3100, 3050, 3900, 3400])
    deg_per_unit = (hi_t - lo_t)[:5] / 200 * 360 / 4095
    # the arm was placed at the model's zero when calibrated: that pose reads 2047 ticks
    placed = ((lo_t + hi_t)[:5] / 2 - 2047) * 360 / 4095

    def to_range(v):
        out = np.array(v, dtype=float)
        out[:5] = (out[:5] - placed) / deg_per_unit
        return out

    root = write_lerobot(tmp_path / "ds", episodes, transform=to_range)
    cal = {n: {"id": i + 1, "drive_mode": 0, "homing_offset": 0, "range_min": int(lo_t[i]),
               "range_max": int(hi_t[i])} for i, n in enumerate(JOINT_NAMES)}  # fmt: skip
    cal_path = tmp_path / "follower.json"
    cal_path.write_text(json.dumps(cal))
    log = read_log(root, default_units(), calibration=cal_path)
    assert not log.warnings
    np.testing.assert_allclose(log.episodes[0].measured, episodes[0].measured, atol=1e-3)
    # a degrees recording (beyond ±100) with a calibration is refused, not read as range mode
    wide = write_lerobot(tmp_path / "deg", episodes, transform=lambda v: np.asarray(v) * 3)
    with pytest.raises(LogError, match="beyond ±100"):
        read_log(wide, default_units(), calibration=cal_path)
    guessed = read_log(root, default_units())
    assert any("--calibration" in w for w in guessed.warnings)
    assert any("--units degrees" in w for w in guessed.warnings)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"shoulder_pan": {"range_min": 5}}))
    with pytest.raises(CalibrationError, match="range_min/range_max"):
        read_log(root, default_units(), calibration=bad)
    # the CLI prints the warning on stderr, the JSON alone on stdout
    assert main(["compare", str(root), "--json", "--episodes", "0"]) == 0
    out = capsys.readouterr()
    assert "calibration" in out.err
    json.loads(out.out)


def _lerobot_range(ticks, lo, hi):
    """LeRobot 0.6.1's range mode (``MotorsBus._normalize``, drive_mode 0) of a raw reading."""
    return (np.clip(ticks, lo, hi) - lo) / (hi - lo) * 200 - 100


def test_the_range_guess_is_a_typical_lerobot_calibration(tmp_path, episodes):
    from so101sim.fidelity.calibration import RANGE_GUESS, range_guess

    # wrist_roll: LeRobot >= 0.4 writes 0..4095 (not swept); the pose placed at calibration
    # reads 2047 ticks = the model's zero, so a reading is (ticks - 2047) * 360 / 4096 degrees
    ticks = np.linspace(0, 4095, 41)
    r = _lerobot_range(ticks, 0, 4095)
    scale, offset = RANGE_GUESS["wrist_roll"]
    np.testing.assert_allclose(scale * r + offset, (ticks - 2047) * 360 / 4096, atol=0.05)
    # a follower calibrated with the typical ranges (the placed pose at 2047 ticks) is read back
    # to its angles within a reading step
    scale, offset = range_guess()
    for j, name in enumerate(JOINT_NAMES[:5]):
        half = scale[j] * 100 * 4096 / 360  # half the swept range, ticks
        mid = 2047 + offset[j] * 4096 / 360  # the swept range's middle, ticks
        angle = np.linspace(-60, 60, 13)
        read = _lerobot_range(2047 + angle * 4096 / 360, mid - half, mid + half)
        np.testing.assert_allclose(scale[j] * read + offset[j], angle, atol=0.1, err_msg=name)
    # the elbow's swept middle lies below the placed pose on real arms (mean of 20 files)
    assert -8 < RANGE_GUESS["elbow_flex"][1] < -3

    # and compare reads a range-mode recording with it, saying so
    root = write_lerobot(tmp_path / "ds", episodes, transform=range_mode())
    log = read_log(root, default_units())
    assert log.range_guess and any("typical" in w for w in log.warnings)
    np.testing.assert_allclose(log.episodes[0].measured, episodes[0].measured, atol=1e-3)


def test_cli_json_is_one_object_on_stdout(tmp_path, episodes, true_toml, capsys):
    root = write_lerobot(tmp_path / "ds", episodes)
    plot = tmp_path / "overlay.png"
    code = main(["compare", str(root), "--arm", str(true_toml), "--episodes", "0-1", "--json",
                 "--plot", str(plot), "--units", "degrees"])  # fmt: skip
    assert code == 0
    out = capsys.readouterr()
    obj = json.loads(out.out)
    assert set(obj) == {"frames", "episodes", "joints", "command_baseline", "holds", "moves",
                        "worst_windows", "gripper_blocked_frames"}  # fmt: skip
    assert obj["frames"] == 120 and obj["episodes"] == [0, 1]
    assert set(obj["joints"]) == set(JOINT_NAMES)
    assert set(obj["joints"]["elbow_flex"]) == {"mae", "rms", "max", "lag_s"}
    assert set(obj["command_baseline"]["gripper"]) == {"mae"}
    assert plot.stat().st_size > 10_000 and plot.read_bytes()[:4] == b"\x89PNG"
    assert main(["compare", str(root), "--units", "degrees"]) == 0
    text = capsys.readouterr().out
    assert "command mae" in text and "elbow_flex" in text


def test_a_csv_log_is_compared(tmp_path, episodes, true_toml):
    path = write_csv(tmp_path / "run.csv", episodes[0])
    res = compare(path, arm=true_toml)
    assert res.episodes == [0] and res.frames == len(episodes[0].times) - 1  # the log: one less
    assert max(e.mae for e in res.joints.values()) < 0.1


def test_bad_inputs_say_what_is_wrong(tmp_path, capsys):
    with pytest.raises(LogError, match=r"does not exist|neither a LeRobot dataset"):
        read_log(tmp_path / "nothing", default_units())
    (tmp_path / "ds" / "meta").mkdir(parents=True)
    (tmp_path / "ds" / "meta" / "info.json").write_text(json.dumps({"fps": 30, "features": {}}))
    with pytest.raises(LogError, match="no 'action' feature"):
        read_log(tmp_path / "ds", default_units())
    assert parse_episodes("0-1,3") == [0, 1, 3]
    for bad in ("a", "3-1", "-2", "0-99999999"):
        with pytest.raises(Exception, match="--episodes"):
            parse_episodes(bad)
    assert main(["compare", str(tmp_path / "nothing")]) == 2
    assert "does not exist; expected a LeRobot dataset" in capsys.readouterr().err


def test_a_missing_optional_package_says_what_to_install(tmp_path, episodes, monkeypatch):
    import sys

    from so101sim.fidelity.deps import MissingDependencyError

    root = write_lerobot(tmp_path / "ds", episodes)
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)  # import fails as if absent
    with pytest.raises(MissingDependencyError, match=r"so101sim\[fidelity\]"):
        read_log(root, default_units(), units="degrees")
    # a CSV log needs no optional package
    assert compare(write_csv(tmp_path / "e.csv", episodes[0])).frames == len(episodes[0].times) - 1


def test_a_joint_that_never_moves_has_no_lag(tmp_path, true_toml, capsys):
    """A still joint matches the sim at every shift: no lag is printed for it (``-``, JSON
    null), where the moving joints keep theirs."""
    sim = Simulation(arm=true_arm())
    t, cmd = commands(5, 2.0)
    cmd[:, 4] = 10.0  # wrist_roll held at 10 degrees throughout
    meas = replay_episode(sim, Episode(0, t, cmd, np.tile(cmd[0], (len(t), 1))))
    root = write_lerobot(tmp_path / "ds", [Episode(0, t, cmd, meas)])
    res = compare(root, arm=true_toml, units="degrees")
    assert res.joints["wrist_roll"].lag_s != res.joints["wrist_roll"].lag_s  # NaN
    assert abs(res.joints["elbow_flex"].lag_s) <= 1 / 30 + 1e-9
    assert (
        main(["compare", str(root), "--arm", str(true_toml), "--units", "degrees", "--json"]) == 0
    )
    obj = json.loads(capsys.readouterr().out)
    assert obj["joints"]["wrist_roll"]["lag_s"] is None
    assert isinstance(obj["joints"]["elbow_flex"]["lag_s"], float)
    assert main(["compare", str(root), "--arm", str(true_toml), "--units", "degrees"]) == 0
    row = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("wrist_roll"))
    assert row.split()[4] == "-"  # joint, sim mae, rms, max, lag s
