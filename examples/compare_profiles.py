"""Run the lab motion with each profile and compare how hard the actuators work.

python examples/compare_profiles.py
"""

import dataclasses

from so101sim import LAB_MOTION, Move
from so101sim.preflight import preflight

for profile in ("linear", "minimum_jerk", "limited"):
    steps = [
        dataclasses.replace(s, profile=profile) if isinstance(s, Move) else s for s in LAB_MOTION
    ]
    report = preflight(steps)
    joints = [(name, j) for s in report.steps for name, j in s.joints.items()]
    effort, e_joint = max((j.peak_effort, name) for name, j in joints)
    saturated = max(j.saturated for _, j in joints)
    error, t_joint = max((j.peak_tracking_error, name) for name, j in joints)
    print(
        f"{profile:>12}: peak effort {effort:.1%} ({e_joint}), saturated {saturated * 1000:.0f} ms,"
        f" peak tracking error {error:.3f}° ({t_joint}), {'PASS' if report.passed else 'FAIL'}"
    )
