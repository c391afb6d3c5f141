"""The start lurch (issue 29): the lab handout's set_initial_pose writes d.qpos only, so the
servos' targets (d.ctrl) stay at 0. How far the arm leaves its starting pose in the first
0.5 s, per servo model: (a) the targets never written (pulled toward all zeros), (b) the
targets written before every step from the first (the delayed servo still acts on its empty
history, i.e. on 0, for its first ~27 ms). so101sim.lab.set_initial_pose and so101sim record
command the starting pose instead (docs/fidelity.md, "The start").

Run: PYTHONPATH=src python bench/bench_start_lurch.py
"""

import copy

import mujoco
import numpy as np

from so101sim.model import load_model

START = [*np.radians([0.0, -98.0, 88.0, 60.0, 0.0]).tolist(), 0.0]

for arm in ("sts3215", "official"):
    for written in (False, True):
        m = copy.copy(load_model(arm=arm))
        d = mujoco.MjData(m)
        d.qpos[:6] = START
        worst = 0.0
        for _ in range(250):  # 0.5 s
            if written:
                d.ctrl[:6] = START
            mujoco.mj_step(m, d)
            worst = max(worst, float(np.degrees(np.abs(d.qpos[:5] - START[:5]).max())))
        how = "targets written each step" if written else "targets never written"
        print(f"{arm:9s} {how:26s}: largest departure from the start {worst:5.1f}°")
