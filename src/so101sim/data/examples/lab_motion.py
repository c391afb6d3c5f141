"""The lab's motion on the lab's helpers: start -> all zeros in 2 s -> hold 2 s -> back in 2 s.

Opens the viewer on a desktop (real time); runs headless on a server and prints each phase.
(in the folder the examples were copied to: so101sim examples FOLDER; cd FOLDER)
Run: python lab_motion.py
Servo model: the script compiles scene.xml itself, so it runs the file's own ideal actuators
(official); so101sim record --arm sts3215 lab_motion.py -o lab.mp4 runs the fitted servos.
"""

import contextlib

import mujoco

from so101sim.lab import (
    convert_to_dictionary,
    hold_position,
    move_to_pose,
    send_position_command,
    set_initial_pose,
)
from so101sim.model import scene_path
from so101sim.viewer import has_display, open_viewer

m = mujoco.MjModel.from_xml_path(str(scene_path()))
d = mujoco.MjData(m)

starting_position = {
    "shoulder_pan": 0.0,
    "shoulder_lift": -98.0,
    "elbow_flex": 88.0,
    "wrist_flex": 60.0,
    "wrist_roll": 0.0,
    "gripper": 0.0,
}
desired_position = dict.fromkeys(starting_position, 0.0)

set_initial_pose(d, starting_position)
send_position_command(d, starting_position)

with open_viewer(m, d) if has_display() else contextlib.nullcontext() as viewer:
    move_to_pose(m, d, viewer, desired_position, 2.0)  # go to the desired position
    hold_position(m, d, viewer, 2.0)  # hold it
    move_to_pose(m, d, viewer, starting_position, 2.0)  # return to the start

final = convert_to_dictionary(d.qpos)
print(f"t = {d.time:.3f} s")
print({joint: round(value, 2) for joint, value in final.items()})
