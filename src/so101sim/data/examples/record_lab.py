"""Record the lab's motion for the hand-in: a video, a plot and a CSV log, no screen recorder.

(in the folder the examples were copied to: so101sim examples FOLDER; cd FOLDER)
python record_lab.py            # writes record_lab.mp4, .png and .csv here
Servo model: Simulation()'s default, the fitted sts3215 (named in the plot, caption and log).
"""

from so101sim import STARTING_POSE, ZERO_POSE, Recorder, Simulation

sim = Simulation()  # the arm in its folded rest pose
outputs = {"video": "record_lab.mp4", "plot": "record_lab.png", "log": "record_lab.csv"}
with Recorder(sim, **outputs, force=True) as rec:
    sim.move_to(ZERO_POSE, 2.0, phase="to_zero")
    sim.hold(2.0, phase="hold")
    result = sim.move_to(STARTING_POSE, 2.0, phase="return")

print("largest tracking error on the way back:", result.worst_tracking_error)
for kind, path in rec.outputs.items():
    print(f"{kind}: {path}")
