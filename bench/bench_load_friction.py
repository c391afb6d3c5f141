"""What load-dependent gearbox friction (a profile's ``load_friction``) costs the stepping kernel:
the same hold stepped with and without it, side by side in one run, on each path through the
kernel (unrecorded ``advance_unobserved``, recorded ``step_block``, and a fit's batch of models in
``BatchStepper``).

    PYTHONPATH=src python bench/bench_load_friction.py [--seconds S]

Prints simulated seconds per wall second for each and the ratio (with / without).
"""

from __future__ import annotations

import argparse
import copy
import time
from dataclasses import replace

import mujoco
import numpy as np

from so101sim.model.arm import load_profile
from so101sim.model.load import load_model
from so101sim.sim.batch import BatchStepper
from so101sim.sim.stepping import advance_unobserved, step_block

STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


def _model(k: float) -> mujoco.MjModel:
    p = load_profile("sts3215")
    return copy.copy(load_model(arm=replace(p, servo=replace(p.servo, load_friction=k))))


def _start(m: mujoco.MjModel) -> mujoco.MjData:
    d = mujoco.MjData(m)
    d.qpos[:6] = [0.3, -0.5, 0.8, 0.4, 0.1, 0.2]
    d.ctrl[:6] = [0.5, -1.0, 1.2, 0.8, 0.3, 0.2]
    mujoco.mj_forward(m, d)
    return d


def _rate(run, m: mujoco.MjModel, seconds: float) -> float:
    n = round(seconds / m.opt.timestep)
    t0 = time.perf_counter()
    run(m, n)
    return seconds / (time.perf_counter() - t0)


def unobserved(m, n):
    advance_unobserved(m, _start(m), None, n)


def recorded(m, n):
    d = _start(m)
    for _ in range(n // 1000):
        step_block(m, d, np.repeat(d.ctrl[None], 1000, axis=0))


def batch(m, n, size=8, frame=17):
    models = [copy.copy(m) for _ in range(size)]
    datas = [mujoco.MjData(m) for _ in range(2)]
    states = np.empty((size, mujoco.mj_stateSize(m, STATE)))
    for b, mb in enumerate(models):
        mujoco.mj_getState(mb, _start(mb), states[b], STATE)
    control = np.repeat(_start(m).ctrl[None, None], size, axis=0)
    with BatchStepper(2) as pool:
        for _ in range(n // frame // size):  # the batch's steps in all: about n
            states = pool.step(models, datas, states, control, frame)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per path")
    args = ap.parse_args()
    plain, loaded = _model(0.0), _model(0.057)
    print(f"{'path':<22}{'without':>12}{'with':>12}{'ratio':>9}   (simulated s per wall s)")
    for name, run in (("advance_unobserved", unobserved), ("step_block", recorded),
                      ("BatchStepper (fit)", batch)):  # fmt: skip
        a = _rate(run, plain, args.seconds)
        b = _rate(run, loaded, args.seconds)
        print(f"{name:<22}{a:>12.1f}{b:>12.1f}{b / a:>9.2f}")


if __name__ == "__main__":
    main()
