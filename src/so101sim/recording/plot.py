"""Plotting a run (:func:`plot_run`): per joint the commanded and measured angle over time, the
phases shaded, and the tracking error of every joint. The steps come from a finished run
(:class:`RunLog`) or are collected while it runs (:class:`TraceCollector`)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..errors import RecordingError
from ..model import arm_units
from ..simulation import Observer, Trace
from ..units import GRIPPER_INDEX, JOINT_NAMES, format_value
from .paths import check_output_path, write_atomically

PLOT_SUFFIXES = (".png", ".pdf", ".svg")
_PHASE_COLOURS = ("#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860")


def _empty_arrays() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.empty(0), np.empty((0, 6)), np.empty((0, 6))


@dataclass
class RunLog:
    """Per-step arrays of a run in the arm's units, for plotting: ``times`` (n,), ``commanded``
    and ``measured`` (n, 6), ``phases`` [(name, start_time, end_time)]."""

    times: np.ndarray
    commanded: np.ndarray
    measured: np.ndarray
    phases: list[tuple[str, float, float]] = field(default_factory=list)

    @classmethod
    def from_result(cls, result: Any) -> RunLog:
        """From a :class:`so101sim.motion.RunResult` (or a single SegmentResult)."""
        segments = getattr(result, "segments", [result])
        if not segments:
            return cls(*_empty_arrays(), [])
        return cls(
            np.concatenate([s.times for s in segments]),
            np.concatenate([s.commanded for s in segments]),
            np.concatenate([s.measured for s in segments]),
            [(s.phase, s.start_time, s.end_time) for s in segments],
        )


class TraceCollector(Observer):
    """Keeps every step of a run, for a plot made after it (see :meth:`run_log`)."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.units = arm_units(model)
        self.timestep = float(model.opt.timestep)
        self._blocks: list[tuple[Trace, str]] = []

    def on_steps(self, trace: Trace, phase: str) -> None:
        if len(trace):
            block = Trace(trace.time.copy(), trace.ctrl.copy(), trace.qpos.copy())
            self._blocks.append((block, phase))

    def run_log(self) -> RunLog:
        """The steps so far; consecutive blocks of the same phase make one shaded phase."""
        if not self._blocks:
            return RunLog(*_empty_arrays(), [])
        times = np.concatenate([b.time for b, _ in self._blocks])
        cmd = self.units.from_radians(np.concatenate([b.ctrl for b, _ in self._blocks]))
        meas = self.units.from_radians(np.concatenate([b.qpos for b, _ in self._blocks]))
        return RunLog(times, cmd, meas, self._phases())

    def _phases(self) -> list[tuple[str, float, float]]:
        phases: list[tuple[str, float, float]] = []
        for block, phase in self._blocks:
            start, end = float(block.time[0]) - self.timestep, float(block.time[-1])
            if phases and phases[-1][0] == phase:
                phases[-1] = (phase, phases[-1][1], end)
            else:
                phases.append((phase, start, end))
        return phases


def plot_run(
    result: Any,
    path: str | os.PathLike[str],
    *,
    width: int = 1280,
    height: int = 960,
    dpi: int = 100,
    force: bool = False,
    title: str | None = None,
) -> Path:
    """Plot a run: per joint the commanded and measured angle over time (the gripper on its
    0–100 scale), the phases shaded, and the tracking error |commanded − measured| of every
    joint; written with matplotlib's Agg backend to ``path`` (PNG of ``width`` × ``height``
    pixels, or PDF/SVG).

    ``result``: a :class:`so101sim.motion.RunResult`, a SegmentResult, or a :class:`RunLog`.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # only to keep start-up fast
    from matplotlib.figure import Figure

    p = check_output_path(path, force=force, what="plot", suffixes=PLOT_SUFFIXES)
    run = result if isinstance(result, RunLog) else RunLog.from_result(result)
    if len(run.times) == 0:
        raise RecordingError("nothing to plot: the run took no steps; expected a run of > 0 s")
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(4, 2)
    axes = [fig.add_subplot(grid[i // 2, i % 2]) for i in range(len(JOINT_NAMES))]
    err_ax = fig.add_subplot(grid[3, :])
    for i, ax in enumerate(axes):
        _plot_joint(ax, run, i)
    axes[0].legend(loc="upper right", fontsize="small")
    _plot_errors(err_ax, run)
    fig.legend(
        *err_ax.get_legend_handles_labels(),
        loc="outside lower center",
        fontsize="small" if width >= 1000 else "x-small",
        ncol=6 if width >= 1200 else 3,
    )
    _shade_phases([*axes, err_ax], err_ax, run)
    fig.suptitle(title or "so101sim run: commanded vs measured joint angles")
    fmt = p.suffix.lstrip(".").lower()
    return write_atomically(p, lambda tmp: fig.savefig(tmp, dpi=dpi, format=fmt))


def _plot_joint(ax: Any, run: RunLog, i: int) -> None:
    """Commanded and measured value of joint ``i`` over time."""
    ax.plot(run.times, run.commanded[:, i], color="0.25", lw=1.2, ls="--", label="commanded")
    ax.plot(run.times, run.measured[:, i], color="#c44e52", lw=1.2, label="measured")
    ax.set_title(JOINT_NAMES[i], fontsize="medium")
    ax.set_ylabel("0–100" if i == GRIPPER_INDEX else "degrees")
    ax.set_ylim(*_value_range(run, i))
    ax.grid(alpha=0.3)


def _value_range(run: RunLog, i: int) -> tuple[float, float]:
    """The y range of joint ``i``: the gripper's whole scale; a body joint's values, at least
    2° wide, so a joint that does not move draws a flat line."""
    if i == GRIPPER_INDEX:
        return -5, 105
    lo = min(run.commanded[:, i].min(), run.measured[:, i].min())
    hi = max(run.commanded[:, i].max(), run.measured[:, i].max())
    mid, half = (lo + hi) / 2, max((hi - lo) / 2 * 1.08, 1.0)
    return mid - half, mid + half


def _plot_errors(ax: Any, run: RunLog) -> None:
    """The tracking error of every joint over time, each labelled with its largest value."""
    err = np.abs(run.commanded - run.measured)
    for i, name in enumerate(JOINT_NAMES):
        largest = format_value(name, err[:, i].max(), digits=2)
        ax.plot(run.times, err[:, i], lw=1.0, label=f"{name} (max {largest})")
    ax.set_title("tracking error |commanded − measured| (degrees; gripper 0–100)")
    ax.set_xlabel("simulated time (s)")
    ax.grid(alpha=0.3)


def _shade_phases(axes: list[Any], label_ax: Any, run: RunLog) -> None:
    """Shade each phase on every axis, name it on ``label_ax``, and show the run's time span."""
    for k, (phase, t0, t1) in enumerate(run.phases):
        colour = _PHASE_COLOURS[k % len(_PHASE_COLOURS)]
        for ax in axes:
            ax.axvspan(t0, t1, color=colour, alpha=0.08, lw=0)
        label_ax.text(
            (t0 + t1) / 2,
            0.97,
            phase,
            transform=label_ax.get_xaxis_transform(),
            ha="center",
            va="top",
            fontsize="small",
            color=colour,
        )
    start = min(ph[1] for ph in run.phases) if run.phases else run.times[0]
    for ax in axes:
        ax.set_xlim(start, run.times[-1])
