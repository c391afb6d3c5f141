"""Replaying a real arm's commands in the sim and measuring how far the sim is from the real arm.

:func:`compare` reads a recording (:func:`~so101sim.fidelity.logs.read_log`), and for each
episode places the simulated arm at the first measured pose, then writes each frame's command
at the recording's own times (a goal held until the next frame, as the real servos get them)
and reads the simulated pose at each frame's time, before that frame's command (LeRobot reads
the observation, then sends the action). Per joint it reports the sim's error against the real
arm (mean absolute, RMS, max, and the lag that best aligns them) beside the baseline "the arm
reaches every command" (the command's own error against the real arm): a twin worth having
beats the baseline.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..model.arm import ArmLike, load_profile
from ..model.index import arm_units
from ..model.load import load_model
from ..sim.simulation import Simulation
from ..units import JOINT_NAMES
from .calibration import (
    GUESSED_CALIBRATION,
    applied_calibration,
    calibration_maps,
    from_log,
    to_log,
)
from .logs import ArmLog, Episode, read_log
from .stops import stop_limits, with_stops
from .windows import Window, still_frames, with_stall, worst_windows

__all__ = ["CompareResult", "compare", "replay_episode"]

MAX_LAG_S = 0.5
MIN_LAG_MOTION = 1.0
"""A lag is found only for a joint whose real trace moves at least this much in an episode
(arm units: degrees, gripper 0-100): a still joint matches at every shift (its lag: NaN)."""


@dataclass(frozen=True)
class JointError:
    mae: float
    rms: float
    max: float
    lag_s: float


@dataclass(frozen=True)
class CompareResult:
    """Per joint errors (arm units: degrees, gripper 0–100) of the sim against the real arm,
    and of the commands against the real arm (the baseline). ``traces`` (with
    ``keep_traces``): per compared episode, ``episode`` (its index), ``t`` (s), ``real``,
    ``sim``, ``command`` (readings, ``(n, 6)``), ``blocked`` (the real gripper blocked), and
    ``real_pose``/``sim_pose``: the same poses as angles (what poses an arm: they differ from
    the readings only under a profile's ``[calibration]``). ``limits``: the replayed arm's
    joint limits (arm units, lower and upper), widened to the recording's stops
    (:mod:`so101sim.fidelity.stops`): what poses the studio's arms (``compare --web``)."""

    frames: int
    episodes: list[int]
    fps: float
    profile: str
    joints: dict[str, JointError]
    command_baseline: dict[str, float]
    warnings: list[str] = field(default_factory=list)
    traces: list[dict[str, Any]] = field(default_factory=list, repr=False)
    holds: dict[str, float] = field(default_factory=dict)
    moves: dict[str, float] = field(default_factory=dict)
    worst: list[Window] = field(default_factory=list)
    gripper_blocked_frames: int = 0
    limits: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    def to_json(self) -> dict[str, Any]:
        """The ``--json`` object: ``frames``, ``episodes``, ``joints`` {mae, rms, max, lag_s
        (null for a joint that never moved)}, ``command_baseline`` {mae}, ``holds`` and
        ``moves`` (mae while each joint's command holds still / moves; null where there is
        none), ``worst_windows`` [{episode, t0, t1, mae, joint}], ``gripper_blocked_frames``."""
        return {
            "frames": int(self.frames),
            "episodes": [int(e) for e in self.episodes],
            "joints": {
                n: {"mae": e.mae, "rms": e.rms, "max": e.max, "lag_s": _num(e.lag_s)}
                for n, e in self.joints.items()
            },
            "command_baseline": {n: {"mae": v} for n, v in self.command_baseline.items()},
            "holds": {n: _num(v) for n, v in self.holds.items()},
            "moves": {n: _num(v) for n, v in self.moves.items()},
            "worst_windows": [
                {"episode": w.episode, "t0": w.t0, "t1": w.t1, "mae": w.mae, "joint": w.joint}
                for w in self.worst
            ],
            "gripper_blocked_frames": int(self.gripper_blocked_frames),
        }


def _num(v: float) -> float | None:
    return None if not np.isfinite(v) else float(v)


def _mean_lag(lags: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Per joint, the episodes' lags (``(episodes, joints)``) averaged by their lengths over the
    episodes where the joint moved (NaN where it moved in none)."""
    found = np.isfinite(lags)
    w = np.where(found, weights[:, None], 0.0)
    total = w.sum(axis=0)
    summed = (np.where(found, lags, 0.0) * w).sum(axis=0)
    return np.where(total > 0, summed / np.where(total > 0, total, 1.0), np.nan)


def _split_mae(err: np.ndarray, mask: np.ndarray) -> dict[str, float]:
    """Per joint, the mean |error| over the frames of ``mask`` (NaN where there are none)."""
    out = {}
    for j, n in enumerate(JOINT_NAMES):
        m = mask[:, j]
        out[n] = float(np.mean(np.abs(err[m, j]))) if m.any() else float("nan")
    return out


def replay_episode(sim: Simulation, episode: Episode) -> np.ndarray:
    """The simulated pose (arm units, ``(n, 6)``) at each frame of ``episode``, its commands
    replayed from its first measured pose at its own times."""
    lo, hi = sim.units.limits
    start = np.clip(episode.measured[0], lo, hi)
    sim.reset()
    sim.set_pose(sim.units.array_to_pose(start), clip=True)
    t0 = sim.time
    out = np.empty_like(episode.measured)
    dt = sim.timestep
    cmd = np.clip(episode.command, lo, hi)
    n = len(episode.times)
    for k in range(n):
        out[k] = sim.pose_array()
        sim.command_array(cmd[k], check=False)
        if k + 1 < n:
            steps = round((t0 + episode.times[k + 1] - sim.time) / dt)
            if steps > 0:
                sim.step(steps, trace=False)
    return out


def _lag(real: np.ndarray, sim: np.ndarray, period: float) -> float:
    """The shift (s) of the sim that best matches the real trace (positive: the real arm lags
    the sim), searched within ±:data:`MAX_LAG_S`; NaN for a real trace that moves less than
    :data:`MIN_LAG_MOTION` (any shift matches it as well)."""
    n = len(real)
    if n == 0 or float(np.ptp(real)) < MIN_LAG_MOTION:
        return float("nan")
    k_max = min(int(MAX_LAG_S / period), n // 2)
    best, best_k = np.inf, 0
    for k in range(-k_max, k_max + 1):
        a = real[k:] if k >= 0 else real[: n + k]
        b = sim[: n - k] if k >= 0 else sim[-k:]
        if len(a) == 0:
            continue
        e = float(np.mean(np.abs(a - b)))
        if e < best - 1e-12:
            best, best_k = e, k
    return best_k * period


def compare(
    log: str | Path | ArmLog,
    *,
    arm: ArmLike = None,
    episodes: list[int] | None = None,
    calibration: str | Path | None = None,
    model: str | Path | None = None,
    keep_traces: bool = False,
    units: str = "auto",
    robot_id: str | None = None,
) -> CompareResult:
    """Replay ``log``'s commands in the sim (profile ``arm``) and measure it against the real
    arm. ``episodes``: which ones (all by default); ``calibration``: LeRobot's calibration JSON
    for a range-mode dataset; ``units``: the dataset's units (``"auto"``, ``"degrees"``,
    ``"range"``: :func:`~so101sim.fidelity.logs.read_log`). Errors in arm units (degrees;
    gripper 0–100). ``robot_id``: the follower's LeRobot id, whose calibration JSON is read
    from LeRobot's folder. A profile's ``[calibration]`` (fitted by ``so101sim fit`` on a
    range-mode recording without that JSON) maps such a recording's readings to angles;
    a recording in exact degrees is taken as it is. A range-mode recording's body joints reach
    the ends of its calibration sweep, past the model's limits where those are narrower
    (:mod:`so101sim.fidelity.stops`)."""
    prof = load_profile(arm)
    loaded = load_model(model, arm=prof)
    data = log if isinstance(log, ArmLog) else read_log(
        log, arm_units(loaded), episodes=episodes, calibration=calibration, units=units,
        robot_id=robot_id,
    )  # fmt: skip
    cal = applied_calibration(prof.calibration, data.range_guess)
    # the real arm's stops, where the recording tells them (stops.py): the replay reaches them
    limits = stop_limits(arm_units(loaded), data.stops, *calibration_maps(cal))
    sim = Simulation(with_stops(loaded, *limits))
    warnings = list(data.warnings)
    if prof.calibration and not data.range_guess:
        warnings.append(
            "the profile's [calibration] is not used: this recording's degrees are exact "
            "(a calibration JSON or degrees), taken as given"
        )
    elif cal:  # the typical mapping, corrected by the profile's calibration: one warning
        warnings = [w for w in warnings if not w.startswith(GUESSED_CALIBRATION)]
        named = [j for j in JOINT_NAMES[:5] if j in cal]
        rest = [j for j in JOINT_NAMES[:5] if j not in cal]
        warnings.append(
            f"{GUESSED_CALIBRATION}: mapped with a typical SO-101's calibration, corrected by "
            f"the profile's [calibration] on "
            + (
                "every body joint"
                if not rest
                else f"{', '.join(named)}; {', '.join(rest)} approximate (a few degrees: "
                "give LeRobot's calibration JSON, or fit their calibration too)"
            )
        )
    real, simd, cmd, traces, lags, still, used, per_ep = [], [], [], [], [], [], [], []
    for ep in data.episodes:
        command, blocked = with_stall(ep.command, ep.measured, ep.times)
        angles = Episode(ep.index, ep.times, from_log(command, cal), from_log(ep.measured, cal))
        pred_pose = replay_episode(sim, angles)  # angles: what poses the arm (compare --web)
        pred = to_log(pred_pose, cal)
        real.append(ep.measured)
        simd.append(pred)
        cmd.append(ep.command)
        still.append(still_frames(ep.command, ep.times))
        keep = np.ones(ep.measured.shape, dtype=bool)
        keep[:, -1] = ~blocked
        used.append(keep)
        per_ep.append((ep.index, ep.times, np.abs(pred - ep.measured)))
        if keep_traces:
            traces.append({"episode": ep.index, "t": ep.times, "real": ep.measured, "sim": pred,
                           "command": ep.command, "blocked": ~keep[:, -1],
                           "real_pose": angles.measured, "sim_pose": pred_pose})  # fmt: skip
        period = float(np.median(np.diff(ep.times)))
        lags.append([_lag(ep.measured[:, j], pred[:, j], period) for j in range(len(JOINT_NAMES))])
    r, s, c, st, ok = (np.concatenate(x) for x in (real, simd, cmd, still, used))
    weights = np.array([len(e.times) for e in data.episodes], dtype=float)
    lag = _mean_lag(np.array(lags), weights)
    err = s - r
    joints = {}
    for j, n in enumerate(JOINT_NAMES):
        e = err[ok[:, j], j] if ok[:, j].any() else err[:, j]  # a blocked gripper left out
        joints[n] = JointError(
            mae=float(np.mean(np.abs(e))),
            rms=float(np.sqrt(np.mean(e**2))),
            max=float(np.max(np.abs(e))),
            lag_s=float(lag[j]),
        )
    base = {
        n: float(np.mean(np.abs((c - r)[ok[:, j] if ok[:, j].any() else slice(None), j])))
        for j, n in enumerate(JOINT_NAMES)
    }
    blocked = int((~ok[:, -1]).sum())
    if blocked:
        warnings.append(
            f"the real gripper is blocked (stalled short of its command, on an object) in "
            f"{blocked} frames: left out of the gripper's error (the sim has no object)"
        )
    return CompareResult(
        frames=len(r), episodes=[e.index for e in data.episodes], fps=data.fps,
        profile=prof.name, joints=joints, command_baseline=base,
        warnings=warnings, traces=traces,
        holds=_split_mae(err, st & ok), moves=_split_mae(err, ~st & ok),
        worst=worst_windows(per_ep, JOINT_NAMES), gripper_blocked_frames=blocked,
        limits=limits,
    )  # fmt: skip
