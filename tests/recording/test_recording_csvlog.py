"""Tests of so101sim.recording.csvlog: one CSV row per control step."""

from __future__ import annotations

import os

import numpy as np
import pytest
from recording_helpers import read_csv

from so101sim import LAB_MOTION, STARTING_POSE, Simulation, run_motion
from so101sim import recording as rec
from so101sim.errors import OutputPathError
from so101sim.sim.simulation import Trace
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
    assert header[8:14] == [f"{n}_measured" for n in JOINT_NAMES]
    assert header[14:] == ["servo_model"] and rows[0][14] == "sts3215"
    steps = sum(s.steps for s in result.segments)
    assert len(rows) == steps == round(6.0 / sim.timestep)
    times = np.array([float(row[0]) for row in rows])
    np.testing.assert_allclose(np.diff(times), sim.timestep, atol=1e-4)
    assert [row[1] for row in rows[:: steps // 3]] == ["to_zero", "hold", "return"]
    last = rows[-1]
    commanded = dict(zip(JOINT_NAMES, map(float, last[2:8]), strict=True))
    for name in JOINT_NAMES:
        assert commanded[name] == pytest.approx(STARTING_POSE[name], abs=1e-5)
    measured = np.array([float(v) for v in last[8:14]])
    np.testing.assert_allclose(measured, result.segments[-1].measured[-1], atol=1e-5)


def test_csv_quotes_phase_names_with_commas(tmp_path):
    sim = Simulation()
    path = tmp_path / "q.csv"
    with rec.Recorder(sim, log=path):
        sim.hold(0.01, phase='wait, then "go"')
    _, rows = read_csv(path)
    assert len(rows) == 5 and rows[0][1] == 'wait, then "go"'


needs_dev_full = pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")


@needs_dev_full
def test_a_full_disk_stops_the_run_with_a_clear_error_and_leaves_no_file(tmp_path):
    sim = Simulation()
    path = tmp_path / "full.csv"
    with (
        pytest.raises(OutputPathError, match="No space left on device") as info,
        rec.Recorder(sim, log=path) as r,
    ):
        r.log._file.tmp.symlink_to("/dev/full")  # every write fails as on a full disk
        sim.hold(30.0)
    assert "could not write the log" in str(info.value)
    assert sim.time < 10.0  # the run stopped at the first failed write (a block of steps)
    assert list(tmp_path.iterdir()) == [] and r.outputs == {}


def test_the_log_streams_to_disk_in_flat_memory(tmp_path):
    """Memory does not grow with the number of steps logged (blocks as the stepping sends)."""
    import tracemalloc

    model = Simulation().model
    k = 512  # rows per block (stepping sends up to 4096)
    trace = Trace(np.arange(1, k + 1) * 0.002, np.zeros((k, 6)), np.zeros((k, 6)))

    def peak(blocks: int) -> int:
        log = rec.CsvLog(tmp_path / f"{blocks}.csv", model)
        tracemalloc.start()
        try:
            for _ in range(blocks):
                log.on_steps(trace, "hold")
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
            log.close()

    small, large = peak(5), peak(60)  # 28k more rows: 3.6 MB if they were kept
    assert large - small < 1_000_000, (small, large)
    assert len(read_csv(tmp_path / "60.csv")[1]) == 60 * k
