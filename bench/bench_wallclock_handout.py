"""How many physics steps the lab handout's wall-clock timing takes for a "2 s" move.

The handout's ``move_to_pose`` loops ``while time.time() - start <= duration: mj_step(...)``,
stepping as fast as the machine can for 2 wall seconds. This prints how many steps (and so how
many simulated seconds) that is here, in a few tries, beside so101sim's fixed count. The bare
loop below leaves out the handout's per-step dict work, which lowers the count somewhat.

Run: python bench/bench_wallclock_handout.py [--tries 2]
"""

from __future__ import annotations

import argparse
import time

import mujoco

from so101sim import Simulation
from so101sim.motion import steps_for


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tries", type=int, default=2)
    ap.add_argument("--duration", type=float, default=2.0)
    args = ap.parse_args()
    sim = Simulation()
    m = sim.model
    print(f'so101sim: a "{args.duration:g} s" move is {steps_for(args.duration, m.opt.timestep)} '
          f"steps = {args.duration:g} simulated s, every time")  # fmt: skip
    for k in range(args.tries):
        d = mujoco.MjData(m)
        start, n = time.time(), 0
        while time.time() - start <= args.duration:
            mujoco.mj_step(m, d)
            n += 1
        print(f'handout, try {k + 1}: a "{args.duration:g} s" move ran {n:,} steps = '
              f"{d.time:.1f} simulated s")  # fmt: skip


if __name__ == "__main__":
    main()
