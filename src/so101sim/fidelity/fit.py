"""Fitting an arm profile to a real arm's recordings: ``so101sim fit``.

The parameters of each joint's servo (by default ``kp_per_p``, ``torque_limit``, ``damping``,
``frictionloss``, ``armature`` and a small calibration ``offset``) and the command delay shared
by all joints are found by robust least squares (scipy, soft-L1 loss) on the position error of
the sim against the real arm, each episode replayed from its first measured pose as
:func:`~so101sim.fidelity.compare.compare` does. Every evaluation replays all episodes for many
parameter vectors at once: one :func:`mujoco.rollout.rollout` call per frame steps the whole
batch (the current guess and one finite-difference neighbour per parameter) on all cores.

A weak prior pulls each parameter toward the starting profile (a joint that barely moved in the
recordings keeps its starting values instead of drifting); each parameter's standard error
comes from the Jacobian at the solution. Episodes held out of the fit (the last one by default,
when there are two or more) measure how well the fitted profile predicts motion it did not see.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from ..errors import SettingError
from ..model.arm import (
    UNCERTAIN_FIELDS,
    UNCERTAIN_LIMIT,
    ArmLike,
    ArmProfile,
    ServoParams,
    load_profile,
    write_servo,
)
from ..model.build import build, recipe
from ..model.load import arm_index, arm_units
from ..units import JOINT_NAMES, ArmUnits
from ..validation import check_count
from .deps import need
from .logs import ArmLog, Episode, read_log

log = logging.getLogger(__name__)

MAX_THREADS = 256  # threads for the parallel rollouts (one MjData each)

__all__ = ["FIT_NAMES", "ArmReplayer", "FitResult", "fit"]

FIT_NAMES: tuple[str, ...] = (
    "kp_per_p",
    "torque_limit",
    "damping",
    "frictionloss",
    "armature",
    "offset",
)
"""The per-joint servo fields :func:`fit` identifies by default (and the shared ``delay_s``)."""

MAX_DELAY_S = 0.15
"""The longest command delay a fit considers, s."""

_BOUNDS = {
    "kp_per_p": (0.02, 50.0),
    "torque_limit": (0.05, 20.0),
    "damping": (0.0, 20.0),
    "viscous": (0.0, 10.0),
    "frictionloss": (0.0, 3.0),
    "drive_frictionloss": (0.0, 3.0),
    "armature": (1e-4, 0.5),
    "offset": (-0.2, 0.2),
    "delay_s": (0.0, MAX_DELAY_S),
    "max_velocity": (0.5, 30.0),  # only from a profile with a slew-limited goal
}
_TYPICAL = {"kp_per_p": 0.5, "torque_limit": 1.0, "damping": 0.5, "viscous": 0.1,
            "frictionloss": 0.05, "drive_frictionloss": 0.05, "armature": 0.01,
            "offset": 0.01, "delay_s": 0.01, "max_velocity": 1.0}  # fmt: skip
_PRIOR_SD = {"offset": 0.05, "delay_s": 0.05}  # absolute; others: relative (50 %)


class ArmReplayer:
    """Replays recorded episodes on a batch of arms (one parameter set each), all in one
    :func:`mujoco.rollout.rollout` call per frame.

    ``base``: the starting profile (its values where a batch entry does not say otherwise)."""

    def __init__(
        self,
        episodes: Sequence[Episode],
        base: ArmProfile,
        *,
        model_path: str | Path | None = None,
        threads: int | None = None,
    ) -> None:
        self.episodes = list(episodes)
        self.base = base
        wide = replace(base, servo=replace(base.servo, delay_s=MAX_DELAY_S),
                       joints={j: {k: v for k, v in d.items() if k != "delay_s"}
                               for j, d in base.joints.items()})  # fmt: skip
        # the model builder's, a one-off (not cached); the batch's copies are what the fit
        # writes into
        self.model = build(recipe(model_path, arm=wide, keep=False))
        self.index = arm_index(self.model)
        self.units: ArmUnits = arm_units(self.model)
        self.threads = check_count(
            threads or min(8, os.cpu_count() or 1), "threads", minimum=1, maximum=MAX_THREADS
        )
        self._models: list[mujoco.MjModel] = []

    def _batch_models(self, n: int) -> list[mujoco.MjModel]:
        while len(self._models) < n:
            import copy

            self._models.append(copy.copy(self.model))
        return self._models[:n]

    def replay(self, servos: Sequence[dict[str, ServoParams]]) -> list[np.ndarray]:
        """For each batch entry (joint -> servo), the predicted measured poses (arm units) of
        every episode, concatenated: ``(nbatch, frames, 6)``."""
        rollout = need("mujoco.rollout", "mujoco>=3.2")
        models = self._batch_models(len(servos))
        idx = self.index
        for m, joints in zip(models, servos, strict=True):
            for j, name in enumerate(JOINT_NAMES):
                write_servo(m, int(idx.actuator[j]), int(idx.dof[j]), joints[name])
        offsets = np.array([[s[n].offset for n in JOINT_NAMES] for s in servos])
        datas = [mujoco.MjData(self.model) for _ in range(self.threads)]
        out = []
        with rollout.Rollout(nthread=self.threads) as pool:
            for ep in self.episodes:
                out.append(self._episode(pool, models, datas, ep, offsets))
        return np.concatenate(out, axis=1)

    def _episode(self, pool, models, datas, ep: Episode, offsets: np.ndarray) -> np.ndarray:
        m = self.model
        idx, units = self.index, self.units
        lo, hi = units.limits
        n = len(models)
        start = units.to_radians(np.clip(ep.measured[0], lo, hi))
        cmd = units.to_radians(np.clip(ep.command, lo, hi))
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        states = np.empty((n, mujoco.mj_stateSize(m, spec)))
        d = datas[0]
        for b, model in enumerate(models):
            mujoco.mj_resetData(model, d)
            d.qpos[idx.qpos] = start - offsets[b]
            d.ctrl[idx.actuator] = start
            mujoco.mj_forward(model, d)
            from ..model.arm import fill_delay_history

            fill_delay_history(model, d)
            mujoco.mj_getState(model, d, states[b], spec)
        dt = m.opt.timestep
        marks = np.round(ep.times / dt).astype(int)
        frames = len(ep.times)
        qadr = 1 + idx.qpos  # state = [time, qpos, ...]
        pred = np.empty((n, frames, len(JOINT_NAMES)))
        control = np.zeros((n, 1, m.nu))
        for k in range(frames):
            q = states[:, qadr] + offsets
            pred[:, k] = units.from_radians(q)
            if k + 1 == frames:
                break
            steps = int(marks[k + 1] - marks[k])
            if steps <= 0:
                continue
            control[:, 0, :] = 0.0
            control[:, 0, idx.actuator] = cmd[k]
            st, _ = pool.rollout(models, datas, states, control, nstep=steps)
            states = st[:, -1, :].copy()
        return pred


@dataclass(frozen=True)
class FitResult:
    """What :func:`fit` found: the fitted profile, each fitted value and its standard error,
    and the error (mean absolute, arm units) per joint on the fitted and held-out episodes."""

    profile: ArmProfile
    values: dict[str, dict[str, float]]
    stderr: dict[str, dict[str, float]]
    fit_episodes: list[int]
    heldout_episodes: list[int]
    fit_error: dict[str, float]
    heldout_error: dict[str, float] | None
    start_fit_error: dict[str, float]
    start_heldout_error: dict[str, float] | None
    evaluations: int


def _mae(pred: np.ndarray, real: np.ndarray) -> dict[str, float]:
    e = np.mean(np.abs(pred - real), axis=0)
    return {n: float(e[j]) for j, n in enumerate(JOINT_NAMES)}


def fit(
    logs: Sequence[str | Path | ArmLog],
    *,
    arm: ArmLike = "sts3215",
    episodes: list[int] | None = None,
    calibration: str | Path | None = None,
    units: str = "auto",
    holdout: int | None = None,
    names: Sequence[str] = FIT_NAMES,
    joints: Sequence[str] = JOINT_NAMES,
    fit_delay: bool = True,
    max_evaluations: int = 30,
    threads: int | None = None,
    model: str | Path | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> FitResult:
    """Fit ``arm`` (the starting profile) to the recordings ``logs``.

    ``holdout``: how many episodes (the last ones) to keep out of the fit and predict (default:
    1 when there are two episodes or more, else 0). ``names``/``joints``: what is fitted;
    ``fit_delay``: also the shared command delay. ``max_evaluations`` bounds the solver's
    iterations (each one replays the episodes for every parameter at once).

    Raises:
        SettingError: no usable episodes, unknown names or joints.
    """
    optimize = need("scipy.optimize", "scipy")
    start = load_profile(arm)
    bad = [n for n in names if n not in _BOUNDS or n == "delay_s"]
    if bad:
        raise SettingError(
            f"cannot fit {bad[0]!r}; expected servo fields among {', '.join(FIT_NAMES)}, "
            "viscous, drive_frictionloss, max_velocity"
        )
    unknown = [j for j in joints if j not in JOINT_NAMES]
    if unknown:
        raise SettingError(f"unknown joint {unknown[0]!r}; expected {', '.join(JOINT_NAMES)}")
    max_evaluations = check_count(max_evaluations, "max_evaluations", minimum=1, maximum=10_000)
    if threads is not None:  # one MjData per thread: bounded before anything is allocated
        threads = check_count(threads, "threads", minimum=1, maximum=MAX_THREADS)
    replayer_units = arm_units(_plain_model(model))
    eps: list[Episode] = []
    for item in logs:
        data = item if isinstance(item, ArmLog) else read_log(
            item, replayer_units, episodes=episodes, calibration=calibration, units=units
        )  # fmt: skip
        eps.extend(data.episodes)
    if not eps:
        raise SettingError("no episodes to fit; expected at least one recorded episode")
    n_hold = (1 if len(eps) >= 2 else 0) if holdout is None else holdout
    n_hold = check_count(n_hold, "holdout", minimum=0, maximum=len(eps) - 1)
    fit_eps, held_eps = eps[: len(eps) - n_hold], eps[len(eps) - n_hold :]
    rep = ArmReplayer(fit_eps, start, model_path=model, threads=threads)
    real = np.concatenate([e.measured for e in fit_eps])

    keys: list[tuple[str, str]] = [(j, n) for j in joints for n in names]
    if fit_delay:
        keys.append(("*", "delay_s"))
    x0 = np.array([_get(start, j, n) for j, n in keys])
    scale = np.array([max(abs(v), _TYPICAL[n]) for v, (_, n) in zip(x0, keys, strict=True)])
    lo = np.array([_BOUNDS[n][0] for _, n in keys]) / scale
    hi = np.array([_BOUNDS[n][1] for _, n in keys]) / scale
    z0 = np.clip(x0 / scale, lo + 1e-9, hi - 1e-9)
    z_start = z0.copy()
    prior_sd = np.array([_PRIOR_SD.get(n, 0.5 * abs(v) + 1e-3) for v, (_, n) in
                         zip(x0, keys, strict=True)]) / scale  # fmt: skip
    n_res = real.size
    data_w = 1.0 / np.sqrt(n_res)
    prior_w = 0.05  # arm units per prior standard deviation, spread over the data's size
    calls = [0]

    def profile_of(z: np.ndarray) -> ArmProfile:
        return _with_values(start, keys, z * scale)

    def servos_of(z: np.ndarray) -> dict[str, ServoParams]:
        prof = profile_of(z)
        return {n: prof.joint(n) for n in JOINT_NAMES}

    def residuals_batch(zs: list[np.ndarray]) -> list[np.ndarray]:
        preds = rep.replay([servos_of(z) for z in zs])
        calls[0] += len(zs)
        out = []
        for z, p in zip(zs, preds, strict=True):
            r = ((p - real) * data_w).ravel()
            out.append(np.concatenate([r, (z - z_start) / prior_sd * prior_w]))
        if progress is not None:
            progress(calls[0], float(np.mean(np.abs(preds[0] - real))))
        return out

    cache: dict[bytes, np.ndarray] = {}

    def fun(z: np.ndarray) -> np.ndarray:
        key = z.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = residuals_batch([z])[0]
        return cache[key]

    def jac(z: np.ndarray) -> np.ndarray:
        h = 1e-3 * np.maximum(1.0, np.abs(z))
        steps = []
        for i in range(len(z)):
            zi = z.copy()
            zi[i] = zi[i] + h[i] if zi[i] + h[i] <= hi[i] else zi[i] - h[i]
            steps.append(zi)
        res = residuals_batch([z, *steps])
        f0 = res[0]
        cols = [(r - f0) / (zi[i] - z[i]) for i, (r, zi) in enumerate(zip(res[1:], steps,
                                                                         strict=True))]  # fmt: skip
        return np.stack(cols, axis=1)

    start_pred = rep.replay([servos_of(z_start)])[0]
    if fit_delay:  # the delay first, on a grid, all in one batch: a good start for the solver
        grid = np.arange(0.0, MAX_DELAY_S + 1e-9, 0.005)
        zs = []
        for dl in grid:
            z = z0.copy()
            z[-1] = np.clip(dl / scale[-1], lo[-1], hi[-1])
            zs.append(z)
        preds = rep.replay([servos_of(z) for z in zs])
        calls[0] += len(zs)
        errs = [float(np.mean(np.abs(p - real))) for p in preds]
        z0 = zs[int(np.argmin(errs))]
    sol = optimize.least_squares(
        fun, z0, jac=jac, bounds=(lo, hi), x_scale="jac", loss="soft_l1",
        f_scale=0.5 * data_w, max_nfev=max_evaluations,
    )  # fmt: skip
    best = profile_of(sol.x)
    jm = sol.jac
    dof = max(1, n_res - len(keys))
    s2 = float(np.sum(sol.fun[:n_res] ** 2)) / dof / data_w**2
    cov = np.linalg.pinv(jm.T @ jm) * s2 * data_w**2
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * scale
    values: dict[str, dict[str, float]] = {}
    stderr: dict[str, dict[str, float]] = {}
    for (j, n), v, e in zip(keys, sol.x * scale, se, strict=True):
        values.setdefault(j, {})[n] = float(v)
        stderr.setdefault(j, {})[n] = float(e)
    fit_pred = rep.replay([servos_of(sol.x)])[0]
    held_err = start_held = None
    if held_eps:
        hold = ArmReplayer(held_eps, start, model_path=model, threads=threads)
        hreal = np.concatenate([e.measured for e in held_eps])
        hp = hold.replay([servos_of(sol.x), servos_of(z_start)])
        held_err, start_held = _mae(hp[0], hreal), _mae(hp[1], hreal)
    return FitResult(
        profile=replace(
            best,
            name=f"{start.name}-fit",
            description=f"{start.name} fitted to recorded motion by so101sim fit "
            f"({len(fit_eps)} episode(s))",
            source="",
            uncertainty=_spread(stderr),
        ),
        values=values,
        stderr=stderr,
        fit_episodes=[e.index for e in fit_eps],
        heldout_episodes=[e.index for e in held_eps],
        fit_error=_mae(fit_pred, real),
        heldout_error=held_err,
        start_fit_error=_mae(start_pred, real),
        start_heldout_error=start_held,
        evaluations=calls[0],
    )


def _spread(stderr: dict[str, dict[str, float]]) -> dict[str, float]:
    """The fitted profile's ``[uncertainty]``: per parameter, the largest of the joints'
    standard errors (finite ones, within the table's bounds)."""
    out: dict[str, float] = {}
    for values in stderr.values():
        for name, se in values.items():
            if name in UNCERTAIN_FIELDS and math.isfinite(se):
                out[name] = max(out.get(name, 0.0), float(se))
    return {k: min(v, UNCERTAIN_LIMIT[k]) for k, v in out.items()}


def _plain_model(path: str | Path | None) -> mujoco.MjModel:
    from ..model.load import load_model

    return load_model(path)


def _get(profile: ArmProfile, joint: str, name: str) -> float:
    if joint == "*":
        return float(getattr(profile.servo, name))
    return float(getattr(profile.joint(joint, scaled=False), name))


def _with_values(
    profile: ArmProfile, keys: Sequence[tuple[str, str]], values: np.ndarray
) -> ArmProfile:
    """``profile`` with the fitted values, as its TOML holds them (at its ``measured_at_v``:
    the model gets them scaled to ``supply_v`` as for any profile)."""
    servo = profile.servo
    joints = {j: dict(d) for j, d in profile.joints.items()}
    for (j, n), v in zip(keys, values, strict=True):
        if j == "*":
            servo = replace(servo, **{n: float(v)})
            for d in joints.values():
                d.pop(n, None)
        else:
            joints.setdefault(j, {})[n] = float(v)
    return replace(profile, servo=servo, joints=joints)
