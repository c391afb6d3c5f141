"""The start-lurch note gives the pose in so101sim's units and says so: a handout script's
gripper 0 (qpos 0) reads 9.1 on so101sim's 0-100 scale, which a student would not expect."""

from __future__ import annotations

import math

import mujoco

from so101sim.lab.handin import hold_start
from so101sim.model.index import scene_path


def test_the_start_note_names_its_units_and_the_gripper_scale():
    m = mujoco.MjModel.from_xml_path(str(scene_path()))
    d = mujoco.MjData(m)
    d.qpos[:6] = [math.radians(a) for a in (0, -98, 88, 60, 0, 0)]
    note = hold_start(m, d)
    assert "shoulder_lift=-98.0, elbow_flex=88.0" in note and "gripper=9.1 (" in note
    assert "(degrees; the gripper on so101sim's 0-100 scale, where qpos 0 is 9.1)" in note
    assert list(d.ctrl[:6]) == list(d.qpos[:6])  # it commands the pose it found
