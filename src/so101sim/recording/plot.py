"""Plotting a run (:func:`plot_run`): per joint the commanded and measured angle over time, the
phases shaded, and the tracking error of every joint. The steps come from a finished run
(:class:`RunLog`) or are collected while it runs (:class:`TraceCollector`); a long run is drawn
from its envelope (:mod:`.envelope`: each bucket's smallest and largest value, so spikes stay),
at most :data:`MAX_PLOT_POINTS` points per curve, however long the run."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..errors import RecordingError
from ..model.load import arm_units
from ..sim.simulation import Observer, Trace
from ..units import GRIPPER_INDEX, JOINT_NAMES, format_value
from ..validation import check_count
from .envelope import MAX_BUCKETS, Envelope
from .paths import check_output_path, write_atomically

PLOT_SUFFIXES = (".png", ".pdf", ".svg")
MIN_PLOT_SIZE = 200
MAX_PLOT_SIZE = 8192
"""A plot's width and height in pixels: from :data:`MIN_PLOT_SIZE` to this."""
_PHASE_COLOURS = ("#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860")


def _empty_arrays() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.empty(0), np.empty((0, 6)), np.empty((0, 6))


@dataclass
class RunLog:
    """Arrays of a run in the arm's units, for plotting: ``times`` (n,), ``commanded`` and
    ``measured`` (n, 6), ``phases`` [(name, start_time, end_time)], and ``errors`` (n, 6), the
    tracking error to draw (None: ``|commanded - measured|``).

    A run's per-step arrays, or (from :class:`TraceCollector` or :meth:`bounded`) an envelope
    of them: each bucket's smallest and largest value, at most :data:`MAX_PLOT_POINTS` points.
    """

    times: np.ndarray
    commanded: np.ndarray
    measured: np.ndarray
    phases: list[tuple[str, float, float]] = field(default_factory=list)
    errors: np.ndarray | None = None

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

    @property
    def tracking_errors(self) -> np.ndarray:
        return np.abs(self.commanded - self.measured) if self.errors is None else self.errors

    def bounded(self, max_buckets: int = MAX_BUCKETS) -> RunLog:
        """This log if it has at most ``2 * max_buckets`` points, else its envelope."""
        if len(self.times) <= 2 * max_buckets:
            return self
        env = Envelope.empty(3, len(JOINT_NAMES), max_buckets)
        values = np.stack([self.commanded, self.measured, self.tracking_errors], axis=1)
        return _from_envelope(env.add(self.times, values), self.phases)


MAX_PLOT_POINTS = 2 * MAX_BUCKETS
"""Points per joint and curve a plot draws at most (a bucket's minimum and maximum)."""


def _from_envelope(env: Envelope, phases: list[tuple[str, float, float]]) -> RunLog:
    times, values = env.points()
    return RunLog(times, values[:, 0], values[:, 1], list(phases), values[:, 2])


class TraceCollector(Observer):
    """Keeps a run's steps for a plot made after it (see :meth:`run_log`): every step of a run
    up to ``max_buckets`` steps, else an :class:`~.envelope.Envelope` of them (the smallest and
    largest value per bucket of steps), so memory stays flat however long the run."""

    def __init__(self, model: mujoco.MjModel, *, max_buckets: int = MAX_BUCKETS) -> None:
        self.units = arm_units(model)
        self.timestep = float(model.opt.timestep)
        self.max_buckets = check_count(max_buckets, "max_buckets", minimum=2, maximum=10**7)
        # (envelope, phases), replaced as a whole: an interruption leaves the last whole state
        self._state: tuple[Envelope | None, tuple[tuple[str, float, float], ...]] = (None, ())

    @property
    def steps(self) -> int:
        """Steps collected."""
        env = self._state[0]
        return 0 if env is None else env.steps

    def on_steps(self, trace: Trace, phase: str) -> None:
        if not len(trace.time):
            return
        env, phases = self._state
        if env is None:
            env = Envelope.empty(3, len(JOINT_NAMES), self.max_buckets)
        cmd = self.units.from_radians(trace.ctrl)
        meas = self.units.from_radians(trace.qpos)
        values = np.stack([cmd, meas, np.abs(cmd - meas)], axis=1)
        start, end = float(trace.time[0]) - self.timestep, float(trace.time[-1])
        if phases and phases[-1][0] == phase:
            phases = (*phases[:-1], (phase, phases[-1][1], end))
        else:
            phases = (*phases, (phase, start, end))
        self._state = (env.add(trace.time, values), phases)

    def run_log(self) -> RunLog:
        """The steps so far (or their envelope); consecutive blocks of the same phase make one
        shaded phase."""
        env, phases = self._state
        if env is None:
            return RunLog(*_empty_arrays(), [])
        return _from_envelope(env, list(phases))


def plot_run(
    result: Any,
    path: str | os.PathLike[str],
    *,
    width: int = 1280,
    height: int = 960,
    dpi: int = 100,
    force: bool = False,
    title: str | None = None,
    servo: str | None = None,
) -> Path:
    """Plot a run: per joint the commanded and measured angle over time (the gripper on its
    0–100 scale), the phases shaded, and the tracking error |commanded − measured| of every
    joint; written with matplotlib's Agg backend to ``path`` (PNG of ``width`` × ``height``
    pixels, or PDF/SVG).

    ``result``: a :class:`so101sim.motion.RunResult`, a SegmentResult, or a :class:`RunLog`.
    ``servo``: the run's servo model in words, named under the title.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # only to keep start-up fast
    from matplotlib.figure import Figure

    p = check_output_path(path, force=force, what="plot", suffixes=PLOT_SUFFIXES)
    size = {"width": width, "height": height}
    for name, value in size.items():
        check_count(value, name, minimum=MIN_PLOT_SIZE, maximum=MAX_PLOT_SIZE, unit=" pixels",
                    error=RecordingError)  # fmt: skip
    check_count(dpi, "dpi", minimum=10, maximum=1000, error=RecordingError)
    run = result if isinstance(result, RunLog) else RunLog.from_result(result)
    run = run.bounded()
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
    heading = title or "so101sim: commanded vs measured joint angles"  # run, hold or record
    fig.suptitle(f"{heading}\nservo model: {servo}" if servo else heading)
    fmt = p.suffix.lstrip(".").lower()
    save = lambda tmp: fig.savefig(tmp, dpi=dpi, format=fmt)  # noqa: E731
    return write_atomically(p, save, what="plot", force=force)


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
    err = run.tracking_errors
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
