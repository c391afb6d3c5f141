from pathlib import Path

import numpy as np
import pytest

from so101sim.errors import SettingError
from so101sim.motion import LAB_MOTION, run_segments
from so101sim.motion.file import load_motion
from so101sim.recording.framing import NAMED_VIEWS, body_positions, project, view_for_run
from so101sim.sim.simulation import Simulation

EXAMPLES_DIR = Path(__file__).resolve().parents[2] / "examples"


def _qpos_frames(segments, start, fps=30.0):
    from so101sim.sim.simulation import Observer

    class Snap(Observer):
        def __init__(self):
            self.t, self.frames = 0.0, []

        def next_time(self):
            return self.t

        def on_time(self, m, d):
            self.frames.append(d.qpos.copy())
            self.t = d.time + 1 / fps - 1e-9
            return True

    sim = Simulation(initial_pose=start)
    snap = Snap()
    run_segments(sim, segments, observers=[snap])
    return sim.model, snap.frames


@pytest.mark.parametrize("size", [(640, 480), (1280, 720)])
@pytest.mark.parametrize("which", ["lab", "wave"])
def test_the_fitted_view_keeps_every_body_in_frame_at_every_frame(which, size):
    if which == "lab":
        from so101sim.units import STARTING_POSE

        model, frames = _qpos_frames(LAB_MOTION, STARTING_POSE)
    else:
        motion = load_motion(EXAMPLES_DIR / "wave.toml")
        model, frames = _qpos_frames(motion.steps, motion.start)
    w, h = size
    view = view_for_run(model, frames, w, h)
    worst = max(np.abs(project(view, body_positions(model, q), w / h)).max() for q in frames)
    assert worst <= 0.95  # inside the frame, with a margin
    assert worst >= 0.3  # and not a speck in the middle


def test_named_views_and_overrides(sim):
    frames = [sim.data.qpos.copy()]
    for name in NAMED_VIEWS:
        v = view_for_run(sim.model, frames, 640, 480, view=name)
        assert (v.azimuth, v.elevation) == NAMED_VIEWS[name]
    v = view_for_run(sim.model, frames, 640, 480, azimuth=30, distance=2.0, lookat=(0, 0, 0.1))
    assert v.azimuth == 30 and v.distance == 2.0 and v.lookat == (0, 0, 0.1)
    with pytest.raises(SettingError, match="valid views are default, front, side, top"):
        view_for_run(sim.model, frames, 640, 480, view="back")
    with pytest.raises(SettingError, match="lookat"):
        view_for_run(sim.model, frames, 640, 480, lookat=(0, 0))
