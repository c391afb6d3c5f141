"""Tests of so101sim.recording.plot: commanded vs measured angles of a run."""

from __future__ import annotations

import imageio.v2 as imageio
import numpy as np
import pytest

from so101sim import LAB_MOTION, Hold, Simulation, run_motion
from so101sim import recording as rec
from so101sim.errors import RecordingError
from so101sim.sim.simulation import Trace


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


def test_a_long_run_is_plotted_from_a_bounded_envelope_that_keeps_spikes(tmp_path):
    n = 1_000_000
    times = 0.002 * np.arange(1, n + 1)
    commanded = np.zeros((n, 6))
    measured = np.zeros((n, 6))
    measured[654_321, 2] = 45.0  # a single step's spike
    run = rec.RunLog(times, commanded, measured, [("hold", 0.0, times[-1])]).bounded()
    assert len(run.times) <= rec.MAX_PLOT_POINTS + 2
    assert run.measured[:, 2].max() == 45.0 and run.tracking_errors[:, 2].max() == 45.0
    path = rec.plot_run(run, tmp_path / "long.png", width=640, height=480)
    assert imageio.imread(path).shape[:2] == (480, 640)


def test_the_collector_keeps_flat_memory_however_long_the_run():
    """tracemalloc counts NumPy's arrays: the collector's memory must not grow with steps."""
    import tracemalloc

    model = Simulation().model
    k = 4096
    base = np.arange(1, k + 1) * 0.002
    ctrl, qpos = np.zeros((k, 6)), np.zeros((k, 6))

    def peak(blocks: int) -> int:
        collector = rec.TraceCollector(model)
        tracemalloc.start()
        try:
            for b in range(blocks):
                collector.on_steps(Trace(base + b * k * 0.002, ctrl, qpos), "hold")
            collector.run_log()
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    small, large = peak(20), peak(200)  # 82k and 819k steps
    assert large - small < 2_000_000, (small, large)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"width": 10**9}, "width"), ({"height": 10}, "height"), ({"dpi": 0}, "dpi")],
)
def test_plot_sizes_are_bounded(tmp_path, kwargs, match):
    sim = Simulation()
    result = run_motion(sim.model, sim.data, [Hold(0.1)])
    with pytest.raises(RecordingError, match=match):
        rec.plot_run(result, tmp_path / "p.png", **kwargs)
    assert list(tmp_path.iterdir()) == []
