"""A student's lab script written the way the handout teaches: raw MuJoCo, the viewer from
mujoco.viewer.launch_passive, and moves timed with the wall clock (time.time()).

Run unchanged under `so101sim record` to check that its clock follows simulated time.
The model path comes from the first argument."""

import sys
import time

import mujoco
import mujoco.viewer

DEG = 3.14159 / 180.0  # as a student would write it
NAMES = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]


def to_radians(pose):
    return [*(pose[n] * DEG for n in NAMES[:5]), pose["gripper"] * 3.14159 / 100.0]


def to_pose(q):
    pose = {n: q[i] / DEG for i, n in enumerate(NAMES[:5])}
    pose["gripper"] = q[5] * 100.0 / 3.14159
    return pose


def go(m, d, viewer, goal, seconds):
    begin = to_pose(d.qpos.copy())
    t0 = time.time()
    while True:
        elapsed = time.time() - t0
        if elapsed > seconds:
            break
        a = min(elapsed / seconds, 1)
        d.ctrl = to_radians({n: (1 - a) * begin[n] + a * goal[n] for n in NAMES})
        mujoco.mj_step(m, d)
        viewer.sync()


def stay(m, d, viewer, seconds):
    here = to_pose(d.qpos.copy())
    t0 = time.time()
    while time.time() - t0 <= seconds:
        d.ctrl = to_radians(here)
        mujoco.mj_step(m, d)
        viewer.sync()


m = mujoco.MjModel.from_xml_path(sys.argv[1])
d = mujoco.MjData(m)
rest = {"shoulder_pan": 0.0, "shoulder_lift": -98.0, "elbow_flex": 88.0, "wrist_flex": 60.0,
        "wrist_roll": 0.0, "gripper": 0.0}  # fmt: skip
d.qpos = to_radians(rest)
with mujoco.viewer.launch_passive(m, d) as viewer:
    go(m, d, viewer, dict.fromkeys(NAMES, 0.0), 2.0)
    stay(m, d, viewer, 2.0)
    go(m, d, viewer, rest, 2.0)
print(f"done at t = {d.time:.3f} s")
