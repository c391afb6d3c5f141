"""Tests of so101sim.recording.csvlog: one CSV row per control step."""

from __future__ import annotations

import numpy as np
import pytest
from recording_helpers import read_csv

from so101sim import LAB_MOTION, STARTING_POSE, Simulation, run_motion
from so101sim import recording as rec
from so101sim.units import JOINT_NAMES


def test_csv_has_one_row_per_control_step_and_ends_at_the_final_target(tmp_path):
    sim = Simulation()
    path = tmp_path / "lab.csv"
    with rec.Recorder(sim, log=path) as r:
        result = run_motion(sim.model, sim.data, LAB_MOTION, observers=r.observers)
    header, rows = read_csv(path)
    assert header == rec.csv_columns()
    assert header[:2] == ["time", "phase"]
    assert header[2:8] == [f"{n}_commanded" for n in JOINT_NAMES]
    assert header[8:] == [f"{n}_measured" for n in JOINT_NAMES]
    steps = sum(s.steps for s in result.segments)
    assert len(rows) == steps == round(6.0 / sim.timestep)
    times = np.array([float(row[0]) for row in rows])
    np.testing.assert_allclose(np.diff(times), sim.timestep, atol=1e-4)
    assert [row[1] for row in rows[:: steps // 3]] == ["to_zero", "hold", "return"]
    last = rows[-1]
    commanded = dict(zip(JOINT_NAMES, map(float, last[2:8]), strict=True))
    for name in JOINT_NAMES:
        assert commanded[name] == pytest.approx(STARTING_POSE[name], abs=1e-5)
    measured = np.array([float(v) for v in last[8:]])
    np.testing.assert_allclose(measured, result.segments[-1].measured[-1], atol=1e-5)


def test_csv_quotes_phase_names_with_commas(tmp_path):
    sim = Simulation()
    path = tmp_path / "q.csv"
    with rec.Recorder(sim, log=path):
        sim.hold(0.01, phase='wait, then "go"')
    _, rows = read_csv(path)
    assert len(rows) == 5 and rows[0][1] == 'wait, then "go"'
