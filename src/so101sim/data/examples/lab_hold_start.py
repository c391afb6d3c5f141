"""The lab's first script: put the arm in its starting pose and keep it there.

Opens the viewer on a desktop (close it to stop early); runs headless on a server.
(in the folder the examples were copied to: so101sim examples FOLDER; cd FOLDER)
Run: python lab_hold_start.py
Servo model: the file's own ideal actuators (official), as the handout's scripts get;
so101sim record --arm sts3215 lab_hold_start.py -o hold.mp4 runs the fitted servos.
"""

import contextlib

import mujoco

from so101sim.lab import hold_position, send_position_command, set_initial_pose
from so101sim.model import scene_path
from so101sim.viewer import has_display, open_viewer

m = mujoco.MjModel.from_xml_path(str(scene_path()))
d = mujoco.MjData(m)

starting_position = {
    "shoulder_pan": 0.0,  # degrees, 0 = middle of the joint's range
    "shoulder_lift": -98.0,
    "elbow_flex": 88.0,
    "wrist_flex": 60.0,
    "wrist_roll": 0.0,
    "gripper": 0.0,  # 0 = closed ... 100 = open
}

set_initial_pose(d, starting_position)
send_position_command(d, starting_position)

with open_viewer(m, d) if has_display() else contextlib.nullcontext() as viewer:
    result = hold_position(m, d, viewer, 30.0)  # 30 s of simulated time

print(f"held for {result.duration:.1f} s; largest tracking error {result.worst_tracking_error}")
