"""The servo bench: the pendulum rig built from the arm's actuator code, its runs, its fit, and
BAM M1 (all on synthetic runs: CI has no real data)."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from so101sim.errors import SettingError
from so101sim.fidelity.bam import BamM1, simulate_m1
from so101sim.fidelity.bench import BenchBatch, BenchRig, ServoBench, bench_servo
from so101sim.fidelity.benchdata import BenchRun, load_bench_runs, split_runs
from so101sim.fidelity.benchfit import per_run_errors, simulate_runs, summarize
from so101sim.model.arm import load_profile

G = 9.81


def test_a_loaded_servo_sags_by_its_load_over_its_stiffness():
    bench = ServoBench(mass=0.5, length=0.15, firmware_kp=16, arm="sts3215")
    s = bench.servo
    assert s.kp == pytest.approx(16 * load_profile("sts3215-12v").servo.kp_per_p)
    t = np.arange(600) * 0.005
    q = bench.simulate(t, np.full(600, math.pi / 2), initial=math.pi / 2)
    load = (0.5 + bench.rig.arm_mass / 2) * G * 0.15  # N·m at the horizontal
    sag = math.pi / 2 - q[-1]
    band = s.joint_frictionloss / s.kp  # Coulomb friction lets it stop anywhere in this band
    assert load / s.kp - band - 1e-3 <= sag <= load / s.kp + band + 1e-3
    stiff = ServoBench(mass=0.5, length=0.15, firmware_kp=16, arm="official")
    q2 = stiff.simulate(t, np.full(600, math.pi / 2), initial=math.pi / 2)
    assert math.pi / 2 - q2[-1] < 0.05 * sag  # the vendored actuator barely sags


def test_the_command_arrives_after_the_delay_and_torque_off_lets_go():
    bench = ServoBench(mass=0.3, length=0.1, firmware_kp=32, arm="sts3215")
    delay = bench.servo.delay_s
    t = np.arange(400) * 0.005
    q = bench.simulate(t, np.where(t >= 0.1, 0.5, 0.0), initial=0.0)  # a step at 0.1 s
    before = t <= 0.1 + delay - 0.005
    assert np.abs(q[before]).max() < 1e-6
    assert np.abs(q[t >= 0.1 + delay + 0.01]).min() > 1e-4
    assert q[-1] > 0.4
    en = np.ones(400, dtype=bool)
    en[200:] = False  # the servo lets go at 1 s: the pendulum falls back to hanging
    q_off = bench.simulate(t, np.full(400, 1.2), initial=1.2, torque_enabled=en)
    assert q_off[199] > 1.0 and q_off[-1] < 0.6
    # the mechanical friction stays: it still swings less than a frictionless pendulum
    assert q_off[200:].min() > -1.2


def test_many_benches_in_one_model_match_one_at_a_time():
    rigs = [BenchRig(0.5, 0.1, 8), BenchRig(1.0, 0.15, 24), BenchRig(0.7, 0.15, 4)]
    batch = BenchBatch(rigs, "sts3215")
    t = np.arange(300) * 0.005
    goals = np.stack([np.where(t > 0.2, 1.0, 0.0) * (i + 1) * 0.4 for i in range(3)])
    together = batch.simulate(0.005, goals, np.zeros(3))
    for i, r in enumerate(rigs):
        alone = ServoBench(r.mass, r.length, r.firmware_kp, "sts3215").simulate(t, goals[i])
        np.testing.assert_allclose(together[i], alone, atol=1e-9)


def test_bench_inputs_are_checked():
    with pytest.raises(SettingError, match="mass"):
        ServoBench(mass=-1, length=0.1)
    with pytest.raises(SettingError, match="length"):
        ServoBench(mass=1, length=0)
    bench = ServoBench(mass=0.5, length=0.1)
    with pytest.raises(SettingError, match="differ in length"):
        bench.simulate([0, 0.005], [0.0])
    with pytest.raises(SettingError, match="evenly spaced"):
        bench.simulate([0, 0.005, 0.5], [0.0, 0.0, 0.0])
    with pytest.raises(SettingError, match="torque_enabled"):
        bench.simulate([0, 0.005], [0.0, 0.0], torque_enabled=[True])


def _synthetic_runs(servo_arm, n_per=2):
    """Runs of a known servo: steps and sines for two conditions, ``n_per`` runs each."""
    t = np.arange(500) * 0.005
    runs = []
    for k, (mass, length, kp, traj) in enumerate(
        [(0.5, 0.1, 16.0, "brutal"), (1.0, 0.15, 8.0, "sin_sin"), (0.7, 0.15, 32.0, "sin_sin")]
    ):
        goal = np.where(t > 0.3, 1.2, 0.0) if traj == "brutal" else 0.8 * np.sin(2 * t * (k + 1))
        for rep in range(n_per):
            runs.append(
                BenchRun(
                    f"sysid_{traj}_{k}_{rep}.json",
                    mass,
                    length,
                    kp,
                    traj,
                    t,
                    goal,
                    np.zeros_like(t),
                    np.ones_like(t, dtype=bool),
                )
            )
    pred = simulate_runs(runs, servo_arm)
    return [replace(r, pos=p) for r, p in zip(runs, pred, strict=True)]


def test_runs_are_read_from_json_and_npz_and_split_by_name(tmp_path):
    runs = _synthetic_runs("sts3215")
    folder = tmp_path / "processed"
    folder.mkdir()
    for r in runs:
        entries = [{"timestamp": float(a), "goal_position": float(b), "position": float(c),
                    "torque_enable": bool(d)} for a, b, c, d in
                   zip(r.t, r.goal, r.pos, r.enabled, strict=True)]  # fmt: skip
        doc = {"mass": r.mass, "length": r.length, "kp": r.kp, "trajectory": r.trajectory,
               "entries": entries}  # fmt: skip
        (folder / r.name).write_text(json.dumps(doc))
    read = load_bench_runs(folder)
    assert len(read) == len(runs)
    fit, val = split_runs(read)
    assert len(fit) == len(val) == 3
    assert all(f.name.endswith("_0.json") for f in fit)
    assert all(v.name.endswith("_1.json") for v in val)
    meta = [{"name": r.name, "mass": r.mass, "length": r.length, "kp": r.kp,
             "trajectory": r.trajectory} for r in runs]  # fmt: skip
    arrays = {"meta": json.dumps(meta)}
    for i, r in enumerate(runs):
        arrays |= {f"t{i}": r.t, f"g{i}": r.goal, f"p{i}": r.pos, f"e{i}": r.enabled}
    np.savez(tmp_path / "runs.npz", **arrays)
    again = load_bench_runs(tmp_path / "runs.npz")
    np.testing.assert_allclose(again[3].pos, runs[3].pos)
    # the profile that made the runs predicts them exactly; another does not
    errs = per_run_errors(again, simulate_runs(again, "sts3215"))
    assert errs.max() < 1e-9
    other = summarize(again, per_run_errors(again, simulate_runs(again, "official")))
    assert other["all"] > 0.01 and set(other) == {"brutal", "sin_sin", "all"}
    with pytest.raises(SettingError, match="does not exist"):
        load_bench_runs(tmp_path / "nothing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(SettingError, match=r"no \.json runs"):
        load_bench_runs(tmp_path / "empty")


def test_bam_m1_holds_against_gravity_and_lets_go():
    t = np.arange(400) * 0.005
    en = np.ones(400, dtype=bool)
    en[200:] = False
    run = BenchRun("r", 0.5, 0.1, 32.0, "lift_and_drop", t, np.full(400, -1.2),
                   np.full(400, -1.2), en)  # fmt: skip
    m1 = BamM1(kt=3.6, R=9.8, armature=0.028, q_offset=0.0, friction_base=0.05,
               friction_viscous=0.06)  # fmt: skip
    q = simulate_m1([run], m1)[0]
    assert abs(q[199] + 1.2) < 0.1  # held near the goal under its load
    assert q[-1] > -0.6  # torque off: it falls


def test_bench_fit_recovers_a_known_servo():
    pytest.importorskip("scipy")
    from so101sim.fidelity.benchfit import fit_bench

    true = load_profile("sts3215-12v")
    true = replace(true, servo=replace(true.servo, kp_per_p=1.3, delay_s=0.045))
    runs = _synthetic_runs(true, n_per=1)
    res = fit_bench(runs, "sts3215", names=("kp_per_p", "delay_s"), every=2, max_evaluations=30)
    assert res.servo.kp_per_p == pytest.approx(1.3, rel=0.03)
    assert res.servo.delay_s == pytest.approx(0.045, abs=0.003)
    assert res.fit_error < 0.003
    assert bench_servo(true, 16).kp == pytest.approx(1.3 * 16)
