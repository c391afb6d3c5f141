"""``so101sim record SCRIPT`` frames the student's script as tightly as ``run --record``: the
video is drawn once the script ends, with the camera fitted to the whole motion it made, so
the arm's sweep fills at least half the frame's height in every named view (measured on the
recorded frames: the pixels of the arm's colour)."""

from __future__ import annotations

import numpy as np
import pytest
from recording_helpers import read_video

from so101sim.lab.handin import run_script

SCRIPT = """
import time
import mujoco, mujoco.viewer
from so101sim import load_model, STARTING_POSE, ZERO_POSE
from so101sim.model import arm_index, arm_units

m = load_model()
d = mujoco.MjData(m)
units, idx = arm_units(m), arm_index(m)
start = units.to_radians(units.pose_to_array(STARTING_POSE))
zero = units.to_radians(units.pose_to_array(ZERO_POSE))
d.qpos[idx.qpos] = start
d.ctrl[idx.actuator] = start
mujoco.mj_forward(m, d)
with mujoco.viewer.launch_passive(m, d) as viewer:
    for a, b in ((start, zero), (zero, start)):   # the handout's wall-clock loop
        t0 = time.time()
        while time.time() - t0 < 1.5:
            s = min(1.0, (time.time() - t0) / 1.5)
            d.ctrl[idx.actuator] = a + (b - a) * s
            mujoco.mj_step(m, d)
            viewer.sync()
"""


def arm_rows(frames: list[np.ndarray]) -> tuple[int, int]:
    """First and last image row holding the arm's (yellow) pixels in any frame."""
    rows = np.zeros(frames[0].shape[0], dtype=bool)
    for f in frames:
        img = f[..., :3].astype(float) / 255.0
        r, g, b = img[..., 0], img[..., 1], img[..., 2]
        yellow = (r > 0.35) & (g > 0.3) & (b < 0.6 * np.minimum(r, g)) & (np.abs(r - g) < 0.35)
        rows |= yellow.any(axis=1)
    hits = np.flatnonzero(rows)
    assert hits.size, "no arm pixels in the video"
    return int(hits[0]), int(hits[-1])


@pytest.mark.parametrize("view", ["default", "front", "side", "top"])
def test_record_frames_the_scripts_sweep_in_every_named_view(tmp_path, view):
    script = tmp_path / "lab.py"
    script.write_text(SCRIPT, encoding="utf-8")
    video = tmp_path / f"{view}.mp4"
    height = 120
    run = run_script(
        script, [], video, width=160, height=height, fps=6.0, quality="draft", view=view
    )
    assert run.exit_status == 0 and run.simulated_seconds == pytest.approx(3.0, abs=0.05)
    frames, _ = read_video(run.outputs["video"])
    assert len(frames) >= 15
    top, bottom = arm_rows(frames)
    assert bottom - top + 1 >= 0.5 * height, (view, top, bottom)
