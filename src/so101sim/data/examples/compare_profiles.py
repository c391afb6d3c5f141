"""Run the lab motion with each move shape and compare how hard the actuators work.

The last row, "limited, fastest", gives each lab move the shortest duration the ``limited``
shape's joint limits allow (rounded up to whole physics steps).

(in the folder the examples were copied to: so101sim examples FOLDER; cd FOLDER)
python compare_profiles.py
"""

import dataclasses

from so101sim import LAB_MOTION, STARTING_POSE, Move, load_model
from so101sim.model import default_units
from so101sim.preflight import preflight
from so101sim.sim.limited import LimitedProfile, minimum_steps

TIMESTEP = load_model().opt.timestep  # the physics timestep, s (0.002)


def with_shape(shape, fastest=False):
    """The lab motion with every move using ``shape``; with ``fastest``, each move as short
    as the joint limits allow."""
    units, limited = default_units(), LimitedProfile()
    current = units.pose_to_array(STARTING_POSE)
    steps = []
    for s in LAB_MOTION:
        if isinstance(s, Move):
            target = units.pose_to_array(s.target, base=current)
            duration = s.duration
            if fastest:
                t_min = limited.minimum_duration(current, target)
                duration = minimum_steps(t_min, TIMESTEP) * TIMESTEP
            s = dataclasses.replace(s, shape=shape, duration=duration)
            current = target
        steps.append(s)
    return steps


runs = [(p, with_shape(p)) for p in ("linear", "minimum_jerk", "limited")]
runs.append(("limited, fastest", with_shape("limited", fastest=True)))
for label, steps in runs:
    report = preflight(steps)
    joints = [(name, j) for s in report.steps for name, j in s.joints.items()]
    effort, e_joint = max((j.peak_effort, name) for name, j in joints)
    saturated = max(j.saturated for _, j in joints)
    error, t_joint = max((j.peak_tracking_error, name) for name, j in joints)
    moves = ", ".join(f"{s.duration:.3f} s" for s in steps if isinstance(s, Move))
    print(
        f"{label:>16}: moves {moves}: peak effort {effort:.1%} ({e_joint}), "
        f"saturated {saturated * 1000:.0f} ms, peak tracking error {error:.3f}° ({t_joint}), "
        f"{'PASS' if report.passed else 'FAIL'}"
    )
