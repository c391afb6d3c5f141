"""Simulating the bench's runs with a profile, scoring them, and fitting a profile to them.

The score of a run is its mean absolute position error (rad) over all its samples; a set of
runs scores the mean of its runs' scores ("mean per-run error").
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..model.arm import UNCERTAIN_FIELDS, ArmLike, ServoParams, load_profile
from .bench import BenchBatch, BenchRig, bench_servo
from .benchdata import BenchRun

__all__ = ["BenchFit", "fit_bench", "per_run_errors", "simulate_runs", "summarize"]


def _stack(runs: Sequence[BenchRun]) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    t = max(len(r.t) for r in runs)
    period = float(np.median(np.diff(runs[0].t)))
    goals = np.empty((len(runs), t))
    en = np.empty((len(runs), t), dtype=bool)
    for i, r in enumerate(runs):
        n = len(r.t)
        goals[i, :n], goals[i, n:] = r.goal, r.goal[-1]
        en[i, :n], en[i, n:] = r.enabled, r.enabled[-1]
    init = np.array([r.pos[0] for r in runs])
    return period, goals, init, en


def rigs_of(runs: Sequence[BenchRun]) -> list[BenchRig]:
    return [BenchRig(r.mass, r.length, r.kp) for r in runs]


def simulate_runs(runs: Sequence[BenchRun], arm: ArmLike = None) -> list[np.ndarray]:
    """The predicted positions (rad) of each run with profile ``arm``, all in one batch."""
    batch = BenchBatch(rigs_of(runs), arm)
    period, goals, init, en = _stack(runs)
    out = batch.simulate(period, goals, init, en)
    return [out[i, : len(r.t)] for i, r in enumerate(runs)]


def per_run_errors(runs: Sequence[BenchRun], predictions: Sequence[np.ndarray]) -> np.ndarray:
    """Each run's mean absolute position error, rad."""
    return np.array([np.mean(np.abs(p - r.pos)) for r, p in zip(runs, predictions, strict=True)])


def summarize(runs: Sequence[BenchRun], errors: np.ndarray) -> dict[str, float]:
    """Mean per-run error overall (``"all"``) and per trajectory."""
    by: dict[str, list[float]] = defaultdict(list)
    for r, e in zip(runs, errors, strict=True):
        by[r.trajectory].append(float(e))
    out = {k: float(np.mean(v)) for k, v in sorted(by.items())}
    out["all"] = float(np.mean(errors))
    return out


# ---------------------------------------------------------------------------- fitting
FIT_PARAMS: tuple[str, ...] = tuple(n for n in UNCERTAIN_FIELDS if n != "offset")
"""The servo fields the bench fit identifies: those a profile's ``[uncertainty]`` may name but
the calibration offset (a pendulum bench has none). Back-EMF (``damping``) and viscous friction are
told apart, as are the mechanical and the drive's Coulomb friction, by the runs where the servo
lets go (lift-and-drop's free fall from about 2 s)."""

_LOW = {"kp_per_p": 0.05, "torque_limit": 0.2, "damping": 0.0, "viscous": 0.0,
        "frictionloss": 0.0, "drive_frictionloss": 0.0, "armature": 0.001, "delay_s": 0.0,
        "smoothing_s": 0.0, "max_velocity": 1.0, "load_friction": 0.0}  # fmt: skip
_HIGH = {"kp_per_p": 20.0, "torque_limit": 10.0, "damping": 10.0, "viscous": 5.0,
         "frictionloss": 2.0, "drive_frictionloss": 2.0, "armature": 0.2, "delay_s": 0.1,
         "smoothing_s": 0.1, "max_velocity": 30.0, "load_friction": 0.5}  # fmt: skip


@dataclass(frozen=True)
class BenchFit:
    """The result of :func:`fit_bench`: the servo at 12 V, each parameter's standard error
    (from the Jacobian), and the fit runs' mean per-run error."""

    servo: ServoParams
    names: tuple[str, ...]
    stderr: dict[str, float]
    fit_error: float
    evaluations: int


def fit_bench(
    runs: Sequence[BenchRun],
    start: ArmLike = "sts3215",
    *,
    names: Sequence[str] = FIT_PARAMS,
    max_evaluations: int = 400,
    every: int = 2,
    progress: Callable[[int, float, dict[str, float]], None] | None = None,
) -> BenchFit:
    """Robust least squares (scipy, soft-L1 loss: close to the mean absolute error the runs are
    scored by) of the servo's ``names`` on ``runs``: residuals are the position errors at every
    ``every``-th sample of every run, each run weighted by 1/sqrt(its length) so that every run
    counts alike."""
    # scipy (the optional fidelity extra), checked with a message naming it
    from .deps import need

    optimize = need("scipy.optimize", "scipy")
    prof = load_profile(start)
    base = bench_servo(prof, 16.0)
    slew = "max_velocity" in names or base.max_velocity > 0
    batch = BenchBatch(rigs_of(runs), prof, max_delay_s=_HIGH["delay_s"], slew=slew)
    period, goals, init, en = _stack(runs)
    lengths = np.array([len(r.t) for r in runs])
    mask = np.zeros(goals.shape, dtype=bool)
    for i, n in enumerate(lengths):
        mask[i, :n:every] = True
    real = np.zeros(goals.shape)
    for i, r in enumerate(runs):
        real[i, : len(r.t)] = r.pos
    weights = np.broadcast_to(1.0 / np.sqrt(lengths / every)[:, None], goals.shape)[mask]
    scale = np.array([max(abs(getattr(base, k)), _HIGH[k] * 0.05) for k in names])
    calls = [0]

    def servos(x: np.ndarray) -> list[ServoParams]:
        s = replace(base, **{k: float(v) for k, v in zip(names, x * scale, strict=True)})
        return [replace(s, firmware_p=r.kp) for r in runs]

    def residuals(x: np.ndarray) -> np.ndarray:
        batch.set_servo(servos(x))
        sim = batch.simulate(period, goals, init, en)
        calls[0] += 1
        res = (sim - real)[mask] * weights
        if progress is not None:
            err = float(np.mean(np.abs((sim - real)[mask])))
            progress(calls[0], err, {k: float(v) for k, v in zip(names, x * scale, strict=True)})
        return res

    x0 = np.array([getattr(base, k) for k in names]) / scale
    lo = np.array([_LOW[k] for k in names]) / scale
    hi = np.array([_HIGH[k] for k in names]) / scale
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    sol = optimize.least_squares(
        residuals,
        x0,
        bounds=(lo, hi),
        x_scale="jac",
        diff_step=1e-3,
        max_nfev=max_evaluations,
        loss="soft_l1",
        f_scale=0.01 / np.sqrt(lengths.mean() / every),
    )
    best = servos(sol.x)[0]
    stderr = _stderr(sol, scale, names)
    batch.set_servo(servos(sol.x))
    sim = batch.simulate(period, goals, init, en)
    errs = [np.mean(np.abs(sim[i, :n] - runs[i].pos)) for i, n in enumerate(lengths)]
    return BenchFit(replace(best, firmware_p=16.0), tuple(names), stderr, float(np.mean(errs)),
                    calls[0])  # fmt: skip


def _stderr(sol, scale: np.ndarray, names: Sequence[str]) -> dict[str, float]:
    """Standard errors from the Jacobian at the solution: sqrt(diag((JᵀJ)⁻¹) · s²)."""
    j = sol.jac
    dof = max(1, len(sol.fun) - len(names))
    s2 = float(sol.fun @ sol.fun) / dof
    try:
        cov = np.linalg.pinv(j.T @ j) * s2
    except np.linalg.LinAlgError:
        return {k: float("nan") for k in names}
    se = np.sqrt(np.clip(np.diag(cov), 0, None)) * scale
    return {k: float(v) for k, v in zip(names, se, strict=True)}
