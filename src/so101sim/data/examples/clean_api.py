"""The same lab motion on so101sim's own API, with results to inspect.

(in the folder the examples were copied to: so101sim examples FOLDER; cd FOLDER)
Run: python clean_api.py
"""

from so101sim import STARTING_POSE, ZERO_POSE, Simulation

sim = Simulation()  # the shipped SO-101, resting in its starting pose

for result in (
    sim.move_to(ZERO_POSE, 2.0, phase="to_zero"),
    sim.hold(2.0),
    sim.move_to(STARTING_POSE, 2.0, shape="minimum_jerk", phase="return"),
):
    joint, error = result.worst_tracking_error
    print(f"{result.phase:8s} {result.steps} steps, ends t={result.end_time:.3f} s, "
          f"largest tracking error {error:.3f} ({joint})")  # fmt: skip

print("measured:", {k: round(v, 2) for k, v in sim.pose().items()})
