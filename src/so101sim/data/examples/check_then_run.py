"""Check a motion file in the simulation, and run it only if it passes.

(in the folder the examples were copied to: so101sim examples FOLDER; cd FOLDER)
python check_then_run.py [motion.toml]   # default: wave.toml next to this script
"""

import sys
from pathlib import Path

from so101sim import Simulation, load_motion, run_motion
from so101sim.preflight import check_motion_file, format_report

path = sys.argv[1] if len(sys.argv) > 1 else Path(__file__).resolve().parent / "wave.toml"

report = check_motion_file(path)
print(format_report(report))
if not report.passed:
    sys.exit(1)

motion = load_motion(path)
sim = Simulation(initial_pose=motion.start)
result = run_motion(sim.model, sim.data, motion.steps)
for seg in result.segments:
    joint, error = seg.worst_tracking_error
    print(f"{seg.phase:>12}: ended at {seg.end_time:.3f} s, largest error {error:.2f} ({joint})")
