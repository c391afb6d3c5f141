"""Robust preflight (``so101sim check --variants N``) next to a raw rollout of the same
variants, side by side in one run, and its scaling from 1 to 2 threads.

    PYTHONPATH=src python bench/bench_variants.py [COUNT] [MOTION.toml]

*Raw rollout*: the same worker threads, each writing the same variants into its model copy
(``apply_variant``, ``mj_setConst``) and rolling out the same controls in the same blocks with
``mujoco.rollout`` itself (not through so101sim's stepping kernel), with nothing measured.
*Robust preflight*: ``check_variants`` (the model
and motion prepared, every variant measured and judged, the report). The goal (issue 14) is a
ratio of at most 1.15.
"""

from __future__ import annotations

import sys
import threading
import time

import mujoco
import numpy as np
from mujoco import rollout as _rollout

from so101sim.model import scene_path
from so101sim.motion.file import lab_motion_path, load_motion
from so101sim.preflight.judge import Thresholds
from so101sim.preflight.robust import check_variants
from so101sim.preflight.rollout import BLOCK, Worker, plan_motion, sensor_model
from so101sim.preflight.variants import sample_variants

_CTRL = mujoco.mjtState.mjSTATE_CTRL.value


def raw_rollout(base, plan, variants, threads: int) -> None:
    todo = iter(variants)
    lock = threading.Lock()

    def work() -> None:
        w = Worker(base, plan, Thresholds())
        runner = _rollout.Rollout(nthread=0)
        while True:
            with lock:
                v = next(todo, None)
            if v is None:
                return
            offset, s0 = w._start(v)
            _raw_blocks(w, runner, offset, s0)

    pool = [threading.Thread(target=work) for _ in range(threads)]
    for t in pool:
        t.start()
    for t in pool:
        t.join()


def _raw_blocks(w: Worker, runner, offset, s0) -> None:
    """The worker's rollout, raw: ``mujoco.rollout`` on the same blocks and controls, with no
    kernel around it (no divergence check, no exit gate, nothing measured)."""
    m, d, idx = w.m, w.d, w.idx
    targets, n = w.plan.targets, len(w.plan.targets)
    warm = d.qacc_warmstart.copy()
    for a in range(0, n, BLOCK):
        k = min(BLOCK, n - a)
        ctrl = np.zeros((1, k, m.nu))
        ctrl[0][:, idx.actuator] = targets[a : a + k] - offset
        state = np.empty((1, k, len(s0)))
        sens = np.empty((1, k, m.nsensordata))
        runner.rollout(
            [m], [d], s0[None], ctrl, control_spec=_CTRL, skip_checks=True, nstep=k,
            initial_warmstart=warm[None], state=state, sensordata=sens,
        )  # fmt: skip
        s0, warm = state[0, -1].copy(), d.qacc_warmstart.copy()


def timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def compare(count: int, path, indent: str = "") -> None:
    """Print raw rollout and robust preflight of ``count`` variants of ``path``, with 2 threads
    and 1, and the scaling."""
    motion = load_motion(path)
    base = sensor_model(scene_path())  # compiled (or cached) before timing
    plan = plan_motion(base, motion.steps, motion.start, lines=motion.lines)
    variants = sample_variants(count, 0)
    steps = count * len(plan.targets)
    print(f"{indent}{count} variants of {path}: {len(plan.targets)} steps each, {steps:,} in all")
    rows = {}
    for threads in (2, 1):
        raw = timed(lambda: raw_rollout(base, plan, variants, threads))  # noqa: B023
        robust = timed(lambda: check_variants(path, count=count, threads=threads))  # noqa: B023
        rows[threads] = (raw, robust)
        print(
            f"{indent}{threads} thread(s): raw rollout {raw:7.2f} s "
            f"({steps / raw / 1e3:5.0f}k steps/s)   robust preflight {robust:7.2f} s"
            f"   ratio {robust / raw:.2f} (goal <= 1.15)"
        )
    print(
        f"{indent}scaling 1 -> 2 threads: raw rollout {rows[1][0] / rows[2][0]:.2f}x, "
        f"robust preflight {rows[1][1] / rows[2][1]:.2f}x"
    )


def main() -> None:
    count = int(sys.argv[1]) if len(sys.argv) > 1 else 1000
    path = sys.argv[2] if len(sys.argv) > 2 else lab_motion_path()
    compare(count, path)


if __name__ == "__main__":
    main()
