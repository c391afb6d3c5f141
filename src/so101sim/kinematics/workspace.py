"""The reachable workspace: which tip positions the joint limits allow, with or without a
fixed tool pitch; a yes/no answer for one point; a picture of the region.

Only the joint limits bound it: collisions (with the floor, with the arm itself) are not
checked, so points below the floor or inside the base can appear.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from ..units import STARTING_POSE, ZERO_POSE
from ..validation import check_count, check_output_path, check_range, claim_path
from .core import N_BODY, Kinematics, for_model
from .geometry import planar_arm_of
from .ik import solve_ik

MAX_SAMPLES = 1_000_000
"""The most random poses one workspace sample may hold."""
PLOT_SUFFIXES = (".png", ".svg", ".pdf")


@dataclass(frozen=True, eq=False)
class WorkspaceSamples:
    """Tip positions of random in-limit poses (all with ``pitch`` if it is not None)."""

    points: np.ndarray  # (n, 3) metres, base frame
    values: np.ndarray  # (n, 6) the poses, arm units (gripper at 0)
    pitch: float | None  # degrees, or None for any orientation
    pan: float | None  # degrees if shoulder_pan was held there (a side section), else None

    @property
    def reach_m(self) -> float:
        """The farthest horizontal distance of a sampled tip from the base frame's origin."""
        return float(np.hypot(self.points[:, 0], self.points[:, 1]).max())


def _draw(
    kin: Kinematics, rng: np.random.Generator, n: int, pitch: float | None, pan: float | None
) -> np.ndarray:
    """``n`` random in-limit body-joint angles (radians); with ``pitch``, the wrist flex set to
    give it, the draws whose flex would leave its limits dropped."""
    q = rng.uniform(kin.lower, kin.upper, size=(n, N_BODY))
    if pan is not None:
        q[:, 0] = math.radians(pan)
    if pitch is None:
        return q
    arm = planar_arm_of(kin)
    if arm is None:  # no planar chain to solve the flex from: keep the draws that happen to fit
        return q
    s1, s2, s3 = arm.signs
    flex = (arm.pitch0 - math.radians(pitch) - s1 * q[:, 1] - s2 * q[:, 2]) / s3
    q[:, 3] = (flex + math.pi) % (2 * math.pi) - math.pi
    return q[(q[:, 3] >= kin.lower[3]) & (q[:, 3] <= kin.upper[3])]


def sample_workspace(
    samples: int = 20_000,
    *,
    pitch: float | None = None,
    pan: float | None = None,
    seed: int = 0,
    model: mujoco.MjModel | None = None,
) -> WorkspaceSamples:
    """Tip positions of ``samples`` random in-limit poses, drawn with ``seed``.

    With ``pitch`` (degrees), every pose holds the tool at that pitch (the wrist flex makes
    up for the shoulder and elbow); with ``pan`` (degrees), shoulder_pan is held there, which
    gives a section through the arm's plane (``pan=0``: the x-z plane).
    """
    kin = for_model(model)
    n = check_count(samples, "samples", minimum=1, maximum=MAX_SAMPLES)
    if pitch is not None:
        pitch = check_range(pitch, "pitch", low=-180.0, high=180.0, unit="°")
    if pan is not None:
        lo, hi = math.degrees(kin.lower[0]), math.degrees(kin.upper[0])
        pan = check_range(pan, "pan", low=lo, high=hi, unit="°")
    rng = np.random.default_rng(check_count(seed, "seed"))
    kept: list[np.ndarray] = []
    points: list[np.ndarray] = []
    count = draws = 0
    with kin.lock:
        # with the planar chain the flex gives the pitch exactly; else keep draws within 1°
        tolerance = 1e-6 if planar_arm_of(kin) is not None else 1.0
        while count < n and draws < 50 * n:
            q = _draw(kin, rng, n, pitch, pan)
            draws += n
            for row in q:
                f = kin.frame_at(row)
                if pitch is not None and abs(_wrap_deg(math.degrees(f.pitch) - pitch)) > tolerance:
                    continue
                kept.append(row)
                points.append(f.position)
                count += 1
                if count == n:
                    break
    values = np.zeros((len(kept), N_BODY + 1))
    values[:, :N_BODY] = np.degrees(np.array(kept).reshape(-1, N_BODY))
    return WorkspaceSamples(np.array(points).reshape(-1, 3), values, pitch, pan)


def _wrap_deg(angle: float) -> float:
    return (angle + 180.0) % 360.0 - 180.0


def is_reachable(
    point: Sequence[float] | np.ndarray,
    *,
    pitch: float | None = None,
    approach: Sequence[float] | np.ndarray | None = None,
    roll: float | None = None,
    rotation: Sequence[Sequence[float]] | np.ndarray | None = None,
    tolerance_mm: float = 1.0,
    tolerance_deg: float = 1.0,
    model: mujoco.MjModel | None = None,
) -> bool:
    """Whether the tip can reach ``point`` (metres, base frame) within the joint limits,
    with the asked orientation if any (see :func:`~so101sim.kinematics.solve_ik`)."""
    result = solve_ik(
        point,
        pitch=pitch,
        approach=approach,
        roll=roll,
        rotation=rotation,
        tolerance_mm=tolerance_mm,
        tolerance_deg=tolerance_deg,
        closest=True,
        model=model,
    )
    return result.reachable


def plot_workspace(
    path: str | os.PathLike[str],
    *,
    pitch: float = -90.0,
    samples: int = 20_000,
    seed: int = 0,
    force: bool = False,
    model: mujoco.MjModel | None = None,
) -> Path:
    """Draw the reachable tip positions to ``path`` (.png, .svg or .pdf): a side view (the
    arm's plane at ``shoulder_pan = 0``, x forward, z up) and a top view (x forward, y left),
    for any orientation and for the tool held at ``pitch`` (degrees; -90: pointing straight
    down). The file is written under a temporary name and renamed, so it is never half
    written. Returns the path.

    Raises:
        OutputPathError: the path cannot be written (see
            :func:`so101sim.validation.check_output_path`: a missing or read-only folder, a
            name too long, ...), the extension is not one of ``.png/.svg/.pdf``, or the file
            exists and ``force`` is False.
        SettingError: ``pitch``, ``samples`` or ``seed`` is not valid.
    """
    # the one output check (an empty, too long or read-only path fails now, not after the work)
    p = check_output_path(path, force=force, what="workspace plot", suffixes=PLOT_SUFFIXES)
    kin = for_model(model)
    rows = []
    for pt in (None, pitch):
        side = sample_workspace(samples, pitch=pt, pan=0.0, seed=seed, model=model)
        top = sample_workspace(samples, pitch=pt, seed=seed + 1, model=model)
        rows.append((pt, side, top))
    fig = _figure(kin, rows, samples)
    tmp = p.with_name(f".{p.stem}.{os.getpid()}.partial{p.suffix}")
    try:
        fig.savefig(tmp, dpi=120)
        if force:
            os.replace(tmp, p)
        else:
            claim_path(tmp, p)  # another process's plot there by now: one error, not two files
    finally:
        tmp.unlink(missing_ok=True)
    return p


def _chain_xz(kin: Kinematics, pose: dict[str, float]) -> np.ndarray:
    """Pan axis foot, shoulder, elbow, wrist and tip of ``pose`` in the x-z plane."""
    values = kin.units.pose_to_array(pose)
    with kin.lock:
        kin.frame_at(np.radians(values[:N_BODY]))
        d = kin.data
        joints = [
            d.xanchor[mujoco.mj_name2id(kin.model, mujoco.mjtObj.mjOBJ_JOINT, n)]
            for n in ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex")
        ]
        tip = d.site_xpos[kin.tip_site].copy()
    pts = np.array([[joints[0][0], 0.0, 0.0], *joints, tip])
    return pts[:, [0, 2]]


def _region(ax, x: np.ndarray, y: np.ndarray) -> None:
    """The sampled points as a region: every hexagon (about 1 cm) that holds one."""
    ax.hexbin(x, y, gridsize=45, mincnt=1, cmap="tab10", vmin=0, vmax=1e9, edgecolors="face")


def _figure(kin: Kinematics, rows: list, samples: int):
    # matplotlib is imported here, not at the top, to keep importing so101sim.kinematics fast
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 9.5), layout="constrained")
    axes = fig.subplots(2, 2)
    for (pt, side, top), (ax_side, ax_top) in zip(rows, axes, strict=True):
        label = "any orientation" if pt is None else f"tool pitch {pt:g}°"
        _region(ax_side, side.points[:, 0], side.points[:, 2])
        for pose, style in ((ZERO_POSE, "k-o"), (STARTING_POSE, "k:o")):
            xz = _chain_xz(kin, pose)
            ax_side.plot(xz[:, 0], xz[:, 1], style, lw=1.2, ms=3)
        ax_side.axhline(0.0, color="0.4", lw=1.0)
        ax_side.set(
            title=f"side (shoulder_pan = 0), {label}",
            xlabel="x forward (m)",
            ylabel="z up (m)",
            aspect="equal",
        )
        _region(ax_top, top.points[:, 0], top.points[:, 1])
        ax_top.plot([0.0], [0.0], "k+", ms=10)
        ax_top.set(
            title=f"top, {label}: reach {top.reach_m:.3f} m",
            xlabel="x forward (m)",
            ylabel="y left (m)",
            aspect="equal",
        )
        for ax in (ax_side, ax_top):
            ax.grid(True, lw=0.3)
    fig.suptitle(
        f"SO-101: where the tip can go ({samples} random in-limit poses per view; joint limits "
        "only, collisions not checked)\nside views: the zero pose (line), the starting pose "
        "(dotted), the floor (grey)"
    )
    return fig
