"""Tests of so101sim.recording.plot: commanded vs measured angles of a run."""

from __future__ import annotations

import imageio.v2 as imageio
import pytest

from so101sim import LAB_MOTION, Simulation, run_motion
from so101sim import recording as rec


def test_plot_is_a_png_of_the_requested_size(tmp_path):
    sim = Simulation()
    result = run_motion(sim.model, sim.data, LAB_MOTION)
    path = rec.plot_run(result, tmp_path / "lab.png", width=800, height=600)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = imageio.imread(path)
    assert image.shape[:2] == (600, 800)
    assert image[..., :3].std() > 10


def test_recorder_plot_matches_the_run(tmp_path):
    sim = Simulation()
    with rec.Recorder(sim, plot=tmp_path / "p.png", plot_size=(640, 480)) as r:
        run_motion(sim.model, sim.data, LAB_MOTION, observers=r.observers)
    run = r.collector.run_log()
    assert [p[0] for p in run.phases] == ["to_zero", "hold", "return"]
    assert run.phases[0][1] == pytest.approx(0.0) and run.phases[-1][2] == pytest.approx(6.0)
    assert imageio.imread(r.outputs["plot"]).shape[:2] == (480, 640)
