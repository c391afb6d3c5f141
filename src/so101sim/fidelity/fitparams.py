"""What :func:`so101sim.fidelity.fit.fit` fits and returns: the parameters' bounds, typical sizes
and priors, the result (:class:`FitResult`), and how fitted values go into a profile."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..model.arm import UNCERTAIN_FIELDS, UNCERTAIN_LIMIT, ArmProfile
from ..units import JOINT_NAMES

__all__ = ["CALIBRATION_NAMES", "FIT_NAMES", "MAX_DELAY_S", "FitResult"]

FIT_NAMES: tuple[str, ...] = (
    "kp_per_p",
    "torque_limit",
    "damping",
    "frictionloss",
    "armature",
    "offset",
)
"""The per-joint servo fields :func:`fit` identifies by default (and the shared ``delay_s``)."""

CALIBRATION_NAMES: tuple[str, ...] = ("cal_scale", "cal_offset")
"""A body joint's calibration, fitted on a range-mode recording without LeRobot's calibration
JSON (the profile's ``[calibration.<joint>]`` ``scale`` and ``offset``, degrees); its servo
``offset`` is then not fitted (the calibration offset is the same thing, on the reading)."""

MAX_DELAY_S = 0.15
"""The longest command delay a fit considers, s."""

BOUNDS = {
    "kp_per_p": (0.02, 50.0),
    "torque_limit": (0.05, 20.0),
    "damping": (0.0, 20.0),
    "viscous": (0.0, 10.0),
    "frictionloss": (0.0, 3.0),
    "drive_frictionloss": (0.0, 3.0),
    "load_friction": (0.0, 0.5),
    "armature": (1e-4, 0.5),
    "offset": (-0.2, 0.2),
    "delay_s": (0.0, MAX_DELAY_S),
    "max_velocity": (0.5, 30.0),  # only from a profile with a slew-limited goal
    "cal_scale": (0.8, 1.25),
    "cal_offset": (-15.0, 15.0),
}
TYPICAL = {"kp_per_p": 0.5, "torque_limit": 1.0, "damping": 0.5, "viscous": 0.1,
           "frictionloss": 0.05, "drive_frictionloss": 0.05, "load_friction": 0.02,
           "armature": 0.01,
           "offset": 0.01, "delay_s": 0.01, "max_velocity": 1.0, "cal_scale": 0.05,
           "cal_offset": 1.0}  # fmt: skip
PRIOR_SD = {
    "offset": 0.05,
    "delay_s": 0.05,
    "cal_scale": 0.1,
    "cal_offset": 5.0,
    "load_friction": 0.1,
}
"""Absolute standard deviations of the weak prior; the others: 50 % of the starting value."""
READING_STEP_DEG = 360.0 / 4096
"""An STS3215's position reading step (4096 per turn), degrees: the least error of any reading."""
MAX_AUTOCORRELATION = 0.995
"""The largest lag-one autocorrelation of the residuals a standard error is inflated for (a
factor of at most 399 in variance, 20 in standard error)."""


@dataclass(frozen=True)
class FitResult:
    """What :func:`fit` found: the fitted profile, each fitted value and its standard error,
    and the error (mean absolute, arm units) per joint on the fitted and held-out episodes; on
    the held-out ones also the default profile's and the bare commands' (the arm reaching every
    command). ``gripper_blocked_frames``: frames left out of the gripper's error (the real
    gripper stalled on an object)."""

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
    default_heldout_error: dict[str, float] | None = None
    command_heldout_error: dict[str, float] | None = None
    gripper_blocked_frames: int = 0

    @property
    def worse_than_default(self) -> bool:
        """The fitted profile predicts the held-out episodes worse than the default profile
        (body joints' mean absolute error)."""
        if self.heldout_error is None or self.default_heldout_error is None:
            return False
        return body_mean(self.heldout_error) > body_mean(self.default_heldout_error)


def body_mean(errors: dict[str, float]) -> float:
    """The body joints' mean of per-joint errors (the gripper aside)."""
    return float(np.mean([errors[n] for n in JOINT_NAMES[:5]]))


def mae(pred: np.ndarray, real: np.ndarray, used: np.ndarray) -> dict[str, float]:
    """Per joint mean |pred - real| over the frames ``used`` (bool, like ``real``)."""
    out = {}
    for j, n in enumerate(JOINT_NAMES):
        u = used[:, j] if used[:, j].any() else slice(None)
        out[n] = float(np.mean(np.abs(pred[u, j] - real[u, j])))
    return out


def spread(stderr: dict[str, dict[str, float]]) -> dict[str, float]:
    """The fitted profile's ``[uncertainty]``: per parameter, the largest of the joints'
    standard errors (finite ones, within the table's bounds)."""
    out: dict[str, float] = {}
    for values in stderr.values():
        for name, se in values.items():
            if name in UNCERTAIN_FIELDS and math.isfinite(se):
                out[name] = max(out.get(name, 0.0), float(se))
    return {k: min(v, UNCERTAIN_LIMIT[k]) for k, v in out.items()}


def standard_errors(
    jac: np.ndarray, residuals: np.ndarray, lengths: Sequence[int], data_w: float
) -> np.ndarray:
    """Each fitted parameter's standard error (in the solver's scaled units) from the Jacobian
    at the solution (data rows weighted by ``data_w``, then the prior's rows) and the residuals
    (frames × joints, arm units; ``lengths``: the episodes' frame counts, in order).

    The residuals of a replay are far from independent: an error lasts for many frames. The
    covariance is therefore inflated by ``(1 + rho) / (1 - rho)``, rho the residuals' lag-one
    autocorrelation within each episode (pooled over joints): the variance of a mean of an
    AR(1) series, i.e. as many independent samples as the series really holds. The residuals'
    variance is at least a reading step's (:data:`READING_STEP_DEG`): no servo's log resolves a
    pose better, and a synthetic log that does (a sim read exactly) is not taken at its word."""
    n, k = residuals.size, jac.shape[1]
    s2 = max(float(np.sum(residuals**2)) / max(1, n - k), READING_STEP_DEG**2 / 12.0)
    num = den = 0.0
    start = 0
    for length in lengths:
        r = residuals[start : start + length]
        num += float(np.sum(r[1:] * r[:-1]))
        den += float(np.sum(r**2))
        start += length
    rho = float(np.clip(num / den, 0.0, MAX_AUTOCORRELATION)) if den > 0 else 0.0
    inflation = (1.0 + rho) / (1.0 - rho)
    cov = np.linalg.pinv(jac.T @ jac) * s2 * data_w**2 * inflation
    return np.sqrt(np.clip(np.diag(cov), 0.0, None))


def get_value(profile: ArmProfile, joint: str, name: str) -> float:
    """A parameter's starting value: ``joint`` ``"*"`` is the shared servo."""
    if name in CALIBRATION_NAMES:
        cal = profile.calibration.get(joint, {})
        return float(cal.get(name[4:], 1.0 if name == "cal_scale" else 0.0))
    if joint == "*":
        return float(getattr(profile.servo, name))
    return float(getattr(profile.joint(joint, scaled=False), name))


def with_values(
    profile: ArmProfile,
    keys: Sequence[tuple[str, str]],
    values: np.ndarray,
    stderr: np.ndarray | None = None,
) -> ArmProfile:
    """``profile`` with the fitted values, as its TOML holds them (at its ``measured_at_v``:
    the model gets them scaled to ``supply_v`` as for any profile); calibration values go in
    its ``[calibration]`` (with their standard errors when given)."""
    servo = profile.servo
    joints = {j: dict(d) for j, d in profile.joints.items()}
    cal = {j: dict(d) for j, d in profile.calibration.items()}
    for i, ((j, n), v) in enumerate(zip(keys, values, strict=True)):
        if n in CALIBRATION_NAMES:
            cal.setdefault(j, {})[n[4:]] = float(v)
            if stderr is not None and math.isfinite(stderr[i]):
                hi = 1.0 if n == "cal_scale" else 40.0
                cal[j][n[4:] + "_sd"] = float(min(stderr[i], hi))
        elif j == "*":
            servo = replace(servo, **{n: float(v)})
            for d in joints.values():
                d.pop(n, None)
        else:
            joints.setdefault(j, {})[n] = float(v)
    return replace(profile, servo=servo, joints=joints, calibration=cal)
