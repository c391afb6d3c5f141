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
from ..sim.simulation import Simulation
from ..units import JOINT_NAMES
from .logs import ArmLog, Episode, read_log

__all__ = ["CompareResult", "compare", "replay_episode"]

MAX_LAG_S = 0.5


@dataclass(frozen=True)
class JointError:
    mae: float
    rms: float
    max: float
    lag_s: float


@dataclass(frozen=True)
class CompareResult:
    """Per joint errors (arm units: degrees, gripper 0–100) of the sim against the real arm,
    and of the commands against the real arm (the baseline)."""

    frames: int
    episodes: list[int]
    fps: float
    profile: str
    joints: dict[str, JointError]
    command_baseline: dict[str, float]
    warnings: list[str] = field(default_factory=list)
    traces: list[dict[str, np.ndarray]] = field(default_factory=list, repr=False)

    def to_json(self) -> dict[str, Any]:
        """The ``--json`` object: ``frames``, ``episodes``, ``joints`` {mae, rms, max, lag_s},
        ``command_baseline`` {mae}."""
        return {
            "frames": int(self.frames),
            "episodes": [int(e) for e in self.episodes],
            "joints": {
                n: {"mae": e.mae, "rms": e.rms, "max": e.max, "lag_s": e.lag_s}
                for n, e in self.joints.items()
            },
            "command_baseline": {n: {"mae": v} for n, v in self.command_baseline.items()},
        }


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
    the sim), searched within ±:data:`MAX_LAG_S`."""
    n = len(real)
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
) -> CompareResult:
    """Replay ``log``'s commands in the sim (profile ``arm``) and measure it against the real
    arm. ``episodes``: which ones (all by default); ``calibration``: LeRobot's calibration JSON
    for a range-mode dataset; ``units``: the dataset's units (``"auto"``, ``"degrees"``,
    ``"range"``: :func:`~so101sim.fidelity.logs.read_log`). Errors in arm units (degrees;
    gripper 0–100)."""
    prof = load_profile(arm)
    sim = Simulation(model, arm=prof)
    data = log if isinstance(log, ArmLog) else read_log(
        log, sim.units, episodes=episodes, calibration=calibration, units=units
    )  # fmt: skip
    real, simd, cmd, traces, lags = [], [], [], [], []
    for ep in data.episodes:
        pred = replay_episode(sim, ep)
        real.append(ep.measured)
        simd.append(pred)
        cmd.append(ep.command)
        if keep_traces:
            traces.append({"t": ep.times, "real": ep.measured, "sim": pred, "command": ep.command})
        period = float(np.median(np.diff(ep.times)))
        lags.append([_lag(ep.measured[:, j], pred[:, j], period) for j in range(len(JOINT_NAMES))])
    r, s, c = (np.concatenate(x) for x in (real, simd, cmd))
    weights = np.array([len(e.times) for e in data.episodes], dtype=float)
    lag = np.average(np.array(lags), axis=0, weights=weights)
    err = s - r
    joints = {
        n: JointError(
            mae=float(np.mean(np.abs(err[:, j]))),
            rms=float(np.sqrt(np.mean(err[:, j] ** 2))),
            max=float(np.max(np.abs(err[:, j]))),
            lag_s=float(lag[j]),
        )
        for j, n in enumerate(JOINT_NAMES)
    }
    base = {n: float(np.mean(np.abs(c[:, j] - r[:, j]))) for j, n in enumerate(JOINT_NAMES)}
    return CompareResult(
        frames=len(r), episodes=[e.index for e in data.episodes], fps=data.fps,
        profile=prof.name, joints=joints, command_baseline=base,
        warnings=list(data.warnings), traces=traces,
    )  # fmt: skip


def plot_overlay(result: CompareResult, path: str | Path, *, force: bool = False) -> Path:
    """Real, sim and command per joint (the first episode kept in ``result.traces``), written
    to ``path`` (PNG) atomically."""
    from ..recording.paths import check_output_path, write_atomically

    out = check_output_path(path, force=force, what="plot")
    if not result.traces:
        raise ValueError("compare(..., keep_traces=True) keeps what the plot draws")
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    tr = result.traces[0]
    fig = Figure(figsize=(11, 12))
    axes = fig.subplots(len(JOINT_NAMES), 1, sharex=True)
    for j, (ax, name) in enumerate(zip(axes, JOINT_NAMES, strict=True)):
        ax.plot(tr["t"], tr["command"][:, j], ":", color="gray", label="command")
        ax.plot(tr["t"], tr["real"][:, j], color="black", label="real")
        ax.plot(tr["t"], tr["sim"][:, j], color="tab:orange", label=f"sim ({result.profile})")
        e = result.joints[name]
        ax.set_ylabel(f"{name}\n{'0-100' if name == 'gripper' else 'deg'}")
        ax.set_title(
            f"{name}: sim mae {e.mae:.2f}, command mae {result.command_baseline[name]:.2f}",
            fontsize=9,
        )
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time, s")
    fig.tight_layout()
    return write_atomically(out, lambda p: fig.savefig(p, format="png", dpi=90), "plot")
