"""Fitting an arm profile to a real arm's recordings: ``so101sim fit``.

The parameters of each joint's servo (by default ``kp_per_p``, ``torque_limit``, ``damping``,
``frictionloss``, ``armature`` and a small calibration ``offset``) and the command delay shared
by all joints are found by robust least squares (scipy, soft-L1 loss) on the position error of
the sim against the real arm, each episode replayed from its first measured pose as
:func:`~so101sim.fidelity.compare.compare` does. Every evaluation replays all episodes for many
parameter vectors at once: one call of the stepping kernel per frame
(:class:`~so101sim.sim.stepping.BatchStepper`, ``mujoco.rollout``) steps the whole batch (the
current guess and one finite-difference neighbour per parameter) on all cores.

A range-mode recording without LeRobot's calibration JSON (its degrees a guess) also gets each
body joint's calibration fitted: the reading is ``scale`` × angle + ``offset``
(:data:`~so101sim.fidelity.fitparams.CALIBRATION_NAMES`), written to the profile's
``[calibration]`` with standard errors, and used by ``compare`` on such recordings.

A weak prior pulls each parameter toward the starting profile (a joint that barely moved in the
recordings keeps its starting values instead of drifting); standard errors come from the
Jacobian at the solution (:func:`~.fitparams.standard_errors`). Whole episodes are held out of
the fit (``holdout``; the last one by default, when there are two or more): the fitted profile,
the default profile and the bare commands are all scored on them. Frames where the real
gripper is blocked on an object (:func:`~.windows.blocked_gripper`) are left out of its error.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np

from ..errors import SettingError
from ..model.arm import PROFILE_DEFAULT, ArmLike, ArmProfile, load_profile
from ..model.load import arm_units
from ..units import JOINT_NAMES
from ..validation import check_count
from .calibration import applied_calibration, calibration_maps
from .deps import need
from .fitparams import (
    BOUNDS,
    CALIBRATION_NAMES,
    FIT_NAMES,
    MAX_DELAY_S,
    PRIOR_SD,
    TYPICAL,
    FitResult,
    get_value,
    mae,
    spread,
    standard_errors,
    with_values,
)
from .logs import ArmLog, Episode, read_log
from .replayer import MAX_THREADS, ArmReplayer
from .windows import stall_episodes

log = logging.getLogger(__name__)

FD_STEPS = (0.3, 0.03)
"""Finite-difference steps, relative to each parameter's scale: a wide one first (the replayed
arm's friction makes its error rough at small scales, and a narrow slope leads the solver into a
false valley: a calibration offset traded for stiffness), then a narrow one to settle."""

LOAD_FRICTION_GRID = (0.0, 0.02, 0.04, 0.06, 0.09, 0.13, 0.2, 0.3, 0.4)
"""The ``load_friction`` values (one for every fitted joint) tried before the solver starts, as
the delay is: from a start without it, the solver alone stays near 0 (a fit of a synthetic arm
with 0.057 found 0.005-0.02 and missed its calibration offsets by up to 3°)."""

__all__ = ["FIT_NAMES", "LOAD_FRICTION_GRID", "ArmReplayer", "FitResult", "fit"]


def _split(eps: list[Episode], holdout: Sequence[int] | None) -> tuple[list, list]:
    if holdout is None:
        n_hold = 1 if len(eps) >= 2 else 0
        return eps[: len(eps) - n_hold], eps[len(eps) - n_hold :]
    have = [e.index for e in eps]
    missing = [h for h in holdout if h not in have]
    if missing:
        raise SettingError(
            f"--holdout names episode {missing[0]}, which is not among the episodes read "
            f"({', '.join(map(str, have))}); expected some of them"
        )
    held = [e for e in eps if e.index in set(holdout)]
    fitted = [e for e in eps if e.index not in set(holdout)]
    if not fitted:
        raise SettingError("--holdout holds out every episode; expected some left to fit on")
    return fitted, held


def fit(
    logs: Sequence[str | Path | ArmLog],
    *,
    arm: ArmLike = "sts3215",
    episodes: list[int] | None = None,
    calibration: str | Path | None = None,
    units: str = "auto",
    holdout: Sequence[int] | None = None,
    names: Sequence[str] = FIT_NAMES,
    joints: Sequence[str] = JOINT_NAMES,
    fit_delay: bool = True,
    fit_calibration: bool | None = None,
    max_evaluations: int = 30,
    threads: int | None = None,
    model: str | Path | None = None,
    robot_id: str | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> FitResult:
    """Fit ``arm`` (the starting profile) to the recordings ``logs``.

    ``holdout``: the episodes (by index) kept out of the fit and predicted (default: the last
    one when there are two or more). ``names``/``joints``: what is fitted; ``fit_delay``: also
    the shared command delay; ``fit_calibration``: each body joint's calibration too (default:
    when a recording's degrees are a guess: range mode without LeRobot's calibration JSON).
    ``max_evaluations`` bounds the solver's iterations (each one replays the episodes for every
    parameter at once).

    Raises:
        SettingError: no usable episodes, unknown names, joints or held-out episodes.
    """
    optimize = need("scipy.optimize", "scipy")
    start = load_profile(arm)
    bad = [n for n in names if n not in BOUNDS or n in ("delay_s", *CALIBRATION_NAMES)]
    if bad:
        raise SettingError(
            f"cannot fit {bad[0]!r}; expected servo fields among {', '.join(FIT_NAMES)}, "
            "viscous, drive_frictionloss, load_friction, max_velocity"
        )
    unknown = [j for j in joints if j not in JOINT_NAMES]
    if unknown:
        raise SettingError(f"unknown joint {unknown[0]!r}; expected {', '.join(JOINT_NAMES)}")
    max_evaluations = check_count(max_evaluations, "max_evaluations", minimum=1, maximum=10_000)
    if threads is not None:  # one MjData per thread: bounded before anything is allocated
        threads = check_count(threads, "threads", minimum=1, maximum=MAX_THREADS)
    replayer_units = arm_units(_plain_model(model))
    eps: list[Episode] = []
    guessed = False
    stops: np.ndarray | None = None
    for item in logs:
        data = item if isinstance(item, ArmLog) else read_log(
            item, replayer_units, episodes=episodes, calibration=calibration, units=units,
            robot_id=robot_id,
        )  # fmt: skip
        eps.extend(data.episodes)
        guessed = guessed or data.range_guess
        if data.stops is not None:  # several recordings of one arm: the widest stops
            stops = data.stops if stops is None else np.stack(
                [np.fmin(stops[0], data.stops[0]), np.fmax(stops[1], data.stops[1])])  # fmt: skip
    if not eps:
        raise SettingError("no episodes to fit; expected at least one recorded episode")
    fit_eps, held_eps = _split(eps, holdout)
    with_cal = guessed if fit_calibration is None else fit_calibration
    replayed, used = stall_episodes(fit_eps)
    rep = ArmReplayer(replayed, start, model_path=model, threads=threads, stops=stops)
    real = np.concatenate([e.measured for e in fit_eps])

    servo_names = [n for n in names if not (with_cal and n == "offset")]
    keys: list[tuple[str, str]] = [(j, n) for j in joints for n in servo_names]
    if with_cal:
        keys += [(j, n) for j in joints if j in JOINT_NAMES[:5] for n in CALIBRATION_NAMES]
    if fit_delay:
        keys.append(("*", "delay_s"))
    if not keys:
        raise SettingError(
            "nothing to fit: no servo field, no delay, and the recording's calibration is given "
            "(a calibration JSON or degrees); expected something to fit"
        )
    x0 = np.array([get_value(start, j, n) for j, n in keys])
    scale = np.array([max(abs(v), TYPICAL[n]) for v, (_, n) in zip(x0, keys, strict=True)])
    lo = np.array([BOUNDS[n][0] for _, n in keys]) / scale
    hi = np.array([BOUNDS[n][1] for _, n in keys]) / scale
    z0 = np.clip(x0 / scale, lo + 1e-9, hi - 1e-9)
    z_start = z0.copy()
    prior_sd = np.array([PRIOR_SD.get(n, 0.5 * abs(v) + 1e-3) for v, (_, n) in
                         zip(x0, keys, strict=True)]) / scale  # fmt: skip
    n_res = real.size
    data_w = 1.0 / np.sqrt(n_res)
    prior_w = 0.05  # arm units per prior standard deviation, spread over the data's size
    calls = [0]

    def profile_of(z: np.ndarray) -> ArmProfile:
        return with_values(start, keys, z * scale)

    def run(reps: ArmReplayer, profs: list[ArmProfile]) -> np.ndarray:
        servos = [{n: p.joint(n) for n in JOINT_NAMES} for p in profs]
        # a profile's [calibration] where compare uses it: degrees that are a guess (or fitted)
        cals = [calibration_maps(applied_calibration(p.calibration, guessed or with_cal))
                for p in profs]  # fmt: skip
        return reps.replay(servos, cals)

    def residuals_batch(zs: list[np.ndarray]) -> list[np.ndarray]:
        preds = run(rep, [profile_of(z) for z in zs])
        calls[0] += len(zs)
        out = []
        for z, p in zip(zs, preds, strict=True):
            r = ((p - real) * used * data_w).ravel()
            out.append(np.concatenate([r, (z - z_start) / prior_sd * prior_w]))
        if progress is not None:
            progress(calls[0], float(np.mean(np.abs(preds[0] - real)[used])))
        return out

    cache: dict[bytes, np.ndarray] = {}

    def fun(z: np.ndarray) -> np.ndarray:
        key = z.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = residuals_batch([z])[0]
        return cache[key]

    def jac(z: np.ndarray, step: float) -> np.ndarray:
        h = step * np.maximum(1.0, np.abs(z))
        steps = []
        for i in range(len(z)):
            zi = z.copy()
            zi[i] = zi[i] + h[i] if zi[i] + h[i] <= hi[i] else zi[i] - h[i]
            steps.append(zi)
        res = residuals_batch([z, *steps])
        pairs = enumerate(zip(res[1:], steps, strict=True))
        cols = [(r - res[0]) / (zi[i] - z[i]) for i, (r, zi) in pairs]
        return np.stack(cols, axis=1)

    start_pred = run(rep, [profile_of(z_start)])[0]
    if fit_delay:  # the delay first, on a grid, all in one batch: a good start for the solver
        zs = []
        for dl in np.arange(0.0, MAX_DELAY_S + 1e-9, 0.005):
            z = z0.copy()
            z[-1] = np.clip(dl / scale[-1], lo[-1], hi[-1])
            zs.append(z)
        preds = run(rep, [profile_of(z) for z in zs])
        calls[0] += len(zs)
        z0 = zs[int(np.argmin([float(np.mean(np.abs(p - real)[used])) for p in preds]))]
    cols = [i for i, (_, n) in enumerate(keys) if n == "load_friction"]
    if cols:  # the load's friction next, one value for every joint on a grid: out of 0's valley
        zs = [z0]  # the start's own values are a candidate too (sts3215-load: 0.38)
        for k in LOAD_FRICTION_GRID:
            z = z0.copy()
            z[cols] = np.clip(k / scale[cols], lo[cols] + 1e-9, hi[cols] - 1e-9)
            zs.append(z)
        preds = run(rep, [profile_of(z) for z in zs])
        calls[0] += len(zs)
        z0 = zs[int(np.argmin([float(np.mean(np.abs(p - real)[used])) for p in preds]))]
    sol = None
    for step, budget in zip(FD_STEPS, (max_evaluations, max_evaluations // 2), strict=True):
        if budget >= 1:  # the narrow steps get half the budget again
            sol = optimize.least_squares(
                fun, z0 if sol is None else sol.x, jac=lambda z, h=step: jac(z, h),
                bounds=(lo, hi), x_scale="jac", loss="soft_l1", f_scale=0.5 * data_w,
                max_nfev=budget,
            )  # fmt: skip
    frames = sol.fun[:n_res].reshape(real.shape) / data_w  # arm units, 0 where not used
    se = standard_errors(sol.jac, frames, [len(e.times) for e in fit_eps], data_w) * scale
    values: dict[str, dict[str, float]] = {}
    stderr: dict[str, dict[str, float]] = {}
    for (j, n), v, e in zip(keys, sol.x * scale, se, strict=True):
        values.setdefault(j, {})[n] = float(v)
        stderr.setdefault(j, {})[n] = float(e)
    best = with_values(start, keys, sol.x * scale, se)
    fit_pred = run(rep, [best])[0]
    held = _heldout(held_eps, best, start, model, threads, run, stops)
    return FitResult(
        profile=replace(
            best,
            name=f"{start.name}-fit",
            description=f"{start.name} fitted to recorded motion by so101sim fit "
            f"({len(fit_eps)} episode(s))",
            source="",
            uncertainty=spread(stderr) or dict(start.uncertainty),  # none fitted: the start's
        ),
        values=values,
        stderr=stderr,
        fit_episodes=[e.index for e in fit_eps],
        heldout_episodes=[e.index for e in held_eps],
        fit_error=mae(fit_pred, real, used),
        heldout_error=held[0],
        start_fit_error=mae(start_pred, real, used),
        start_heldout_error=held[1],
        evaluations=calls[0],
        default_heldout_error=held[2],
        command_heldout_error=held[3],
        gripper_blocked_frames=int((~used[:, -1]).sum() + held[4]),
    )


def _heldout(held_eps, best, start, model, threads, run, stops) -> tuple:
    """On the held-out episodes: the fitted profile's, the start's, the default profile's and
    the bare commands' errors, and the frames of a blocked gripper (Nones when none)."""
    if not held_eps:
        return None, None, None, None, 0
    hreal = np.concatenate([e.measured for e in held_eps])
    replayed, hused = stall_episodes(held_eps)
    hp = run(ArmReplayer(replayed, start, model_path=model, threads=threads, stops=stops),
             [best, start])  # fmt: skip
    default = load_profile(PROFILE_DEFAULT)
    dp = run(ArmReplayer(replayed, default, model_path=model, threads=threads, stops=stops),
             [default])[0]  # fmt: skip
    hcmd = np.concatenate([e.command for e in held_eps])
    return (mae(hp[0], hreal, hused), mae(hp[1], hreal, hused), mae(dp, hreal, hused),
            mae(hcmd, hreal, hused), int((~hused[:, -1]).sum()))  # fmt: skip


def _plain_model(path: str | Path | None) -> mujoco.MjModel:
    # start-up: the model loader only when a fit has no model given
    from ..model.load import load_model

    return load_model(path)
