"""How long a straight tip line takes to plan, by duration (issue 23: planning cost follows the
line's length and turn, not its duration).

    PYTHONPATH=src python bench/bench_tipline.py [--durations 2 10 300 3600]

Plans a 6 cm line of the tip (pitch -90°) lasting each duration with
``Simulation.plan_tip_move`` (one target per 2 ms physics step: 3600 s is 1.8 million
targets), and loads a motion file of 30 such lines of 60 s. Prints wall seconds and the IK
solves made (nothing is asserted; the tests assert the solve counts, tests/test_stalls.py).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from so101sim.motionfile import load_motion

from so101sim import Simulation
from so101sim.kinematics import ik

START, TARGET = (0.20, -0.03, 0.05), (0.26, -0.03, 0.05)
SOLVES = [0]
_run = ik.Descent.run


def _counted(self, *args, **kwargs):
    SOLVES[0] += 1
    return _run(self, *args, **kwargs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--durations", type=float, nargs="+", default=[2, 10, 300, 3600])
    args = parser.parse_args()
    ik.Descent.run = _counted
    sim = Simulation()
    corner = sim.plan_tip_move(START, 2.0, pitch=-90, path="joint")[1][-1]
    for duration in args.durations:
        sim.command_array(corner, check=False)
        SOLVES[0] = 0
        t0 = time.perf_counter()
        _, targets = sim.plan_tip_move(TARGET, duration, pitch=-90)
        took = time.perf_counter() - t0
        print(f"{duration:>7g} s line: {len(targets):>9} targets, {SOLVES[0]:>5} IK solves, "
              f"planned in {took:.2f} s")  # fmt: skip
    lines = ['start = "rest"', "[[steps]]", f"move = {{ tip = {list(START)}, pitch = -90, "
             'path = "joint" }', "duration = 2.0"]  # fmt: skip
    for i in range(30):
        tip = TARGET if i % 2 == 0 else START
        lines += ["[[steps]]", f"move = {{ tip = {list(tip)}, pitch = -90 }}", "duration = 60.0"]
    with tempfile.TemporaryDirectory() as folder:
        f = Path(folder) / "lines.toml"
        f.write_text("\n".join(lines) + "\n")
        SOLVES[0] = 0
        t0 = time.perf_counter()
        load_motion(f)
        took = time.perf_counter() - t0
    print(f"30 lines of 60 s: loaded in {took:.2f} s, {SOLVES[0]} IK solves")


if __name__ == "__main__":
    main()
