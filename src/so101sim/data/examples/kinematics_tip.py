"""Where is the gripper? Forward kinematics for the lab's poses, checked against a textbook
chain, then inverse kinematics for a point and a straight-line move to it.

Derived the SO-101's forward kinematics yourself (DH, or the planar chain of
docs/kinematics.md)? Put your numbers into ``textbook_tip`` below and see how far your tip is
from the simulator's.

(in the folder the examples were copied to: so101sim examples FOLDER; cd FOLDER)
python kinematics_tip.py
"""

import math

import numpy as np

from so101sim.kinematics import plan_line, solve_ik, tip_pose
from so101sim.model import arm_units, load_model
from so101sim.units import STARTING_POSE, ZERO_POSE, format_pose

# The chain at the zero pose, in metres, read off docs/kinematics.md (rounded to 0.1 mm).
PAN_X = 0.0388  # the pan axis: vertical, 3.9 cm in front of the base frame's origin
SHOULDER_X, SHOULDER_Z = 0.0692, 0.1166  # the shoulder_lift axis, in the arm's plane
UPPER, UPPER_ANGLE = 0.1160, math.radians(76.03)  # shoulder -> elbow, angle above horizontal
FORE, FORE_ANGLE = 0.1350, math.radians(2.21)  # elbow -> wrist flex axis
TOOL = 0.1592  # wrist flex axis -> tip, along the wrist-roll axis
OFFSET = 0.0079  # the tip lies this far off the roll axis (below it at wrist_roll = 0)


def textbook_tip(pose: dict[str, float]) -> np.ndarray:
    """The tip (metres, base frame) of ``pose`` (degrees), by the planar chain."""
    pan, lift, elbow, flex, roll = (math.radians(pose[n]) for n in list(pose)[:5])
    # in the arm's plane (x forward, z up); a positive pitch joint tilts the arm down
    a1, a2 = UPPER_ANGLE - lift, FORE_ANGLE - lift - elbow
    pitch = -(lift + elbow + flex)  # the tool's angle above the horizontal
    below, side = OFFSET * math.cos(roll), -OFFSET * math.sin(roll)  # the tip round the roll axis
    x = SHOULDER_X + UPPER * math.cos(a1) + FORE * math.cos(a2)
    z = SHOULDER_Z + UPPER * math.sin(a1) + FORE * math.sin(a2)
    x += TOOL * math.cos(pitch) + below * math.sin(pitch)
    z += TOOL * math.sin(pitch) - below * math.cos(pitch)
    # the pan turns the plane about the vertical axis, clockwise seen from above
    r = x - PAN_X
    return np.array(
        [
            PAN_X + r * math.cos(pan) + side * math.sin(pan),
            -r * math.sin(pan) + side * math.cos(pan),
            z,
        ]
    )


def main() -> None:
    print("The tip (base frame: x forward, y left, z up):")
    for name, pose in (("ZERO_POSE", ZERO_POSE), ("STARTING_POSE", STARTING_POSE)):
        print(f"  {name:<14} {tip_pose(pose).format()}")

    lo, hi = arm_units(load_model()).limits
    rng = np.random.default_rng(0)
    worst = 0.0
    for values in rng.uniform(lo, hi, size=(1000, 6)):
        pose = dict(zip(ZERO_POSE, values.tolist(), strict=True))
        worst = max(worst, float(np.linalg.norm(textbook_tip(pose) - tip_pose(pose).position)))
    print(
        f"Textbook chain vs the simulator, 1000 random poses: at most {worst * 1000:.2f} mm apart"
    )

    target = (0.20, 0.0, 0.05)
    result = solve_ik(target, pitch=-90, initial=STARTING_POSE)
    print(f"IK: tip at {target} m, pointing straight down (pitch -90°):")
    print(f"  pose     {format_pose(result.pose)}")
    print(f"  reached  {result.tip.format()}  ({result.position_error_mm:.4f} mm off)")

    line = plan_line(STARTING_POSE, target, 200, pitch=-90)
    print(
        f"A straight line there from STARTING_POSE: {len(line.targets)} targets, the tip "
        f"within {line.deviation_mm:.4f} mm of the line ({line.between_mm:.3f} mm between targets)"
    )


if __name__ == "__main__":
    main()
