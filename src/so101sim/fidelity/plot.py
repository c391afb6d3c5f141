"""``so101sim compare --plot``: real, sim and command per joint, every compared episode.

The episodes are drawn one after another on one time axis (each from its first frame, a short
gap between two), a dashed line and the episode's number where each starts, the worst windows
of error shaded red on every joint and the frames where the real gripper is blocked shaded blue.
At most :data:`MAX_PLOT_EPISODES` episodes are drawn (the first ones; the heading says so); the
errors in the panels' titles are always over every compared episode.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..units import JOINT_NAMES
from .compare import CompareResult

__all__ = [
    "BOUNDARY",
    "MAX_PLOT_EPISODES",
    "WORST",
    "episode_layout",
    "overlay_figure",
    "plot_heading",
    "plot_overlay",
]

MAX_PLOT_EPISODES = 10
"""Episodes drawn at most by ``--plot`` (the first ones); beyond, the heading says how many."""
GAP_S = 0.5  # seconds of axis between two episodes
BOUNDARY = "episode-start"  # the gid of the dashed line where an episode starts
WORST = "worst-window"  # the gid of a worst window's red shading


@dataclass(frozen=True)
class Placed:
    """One drawn episode: its trace and where it starts on the plot's time axis."""

    episode: int
    offset: float  # plot time = offset + (t - t[0])
    trace: dict[str, Any]

    def x(self, t: np.ndarray | float) -> np.ndarray | float:
        return self.offset + (np.asarray(t) - float(self.trace["t"][0]))


def episode_layout(traces: list[dict[str, Any]], limit: int = MAX_PLOT_EPISODES) -> list[Placed]:
    """The first ``limit`` traces placed one after another, :data:`GAP_S` apart."""
    placed, offset = [], 0.0
    for tr in traces[: max(1, int(limit))]:
        placed.append(Placed(int(tr["episode"]), offset, tr))
        offset += float(tr["t"][-1] - tr["t"][0]) + GAP_S
    return placed


def plot_heading(result: CompareResult, blocked: bool, drawn: int | None = None) -> str:
    """The plot's heading: which episodes it draws (``drawn``: how many; all by default), that
    the panels' mae are over every compared episode, and what the lines and shading mean."""
    eps = result.episodes
    n = len(eps) if drawn is None else min(drawn, len(eps))
    if len(eps) == 1:
        head = f"episode {eps[0]}"
    elif n == len(eps):
        head = (
            f"episodes {', '.join(map(str, eps))}, one after another (dashed: where each "
            "starts); each panel's mae is over all of them"
        )
    else:
        head = (
            f"the first {n} of the {len(eps)} compared episodes ({eps[0]}..{eps[n - 1]}; "
            f"at most {MAX_PLOT_EPISODES} are drawn), one after another (dashed: where each "
            f"starts); each panel's mae is over all {len(eps)}"
        )
    keys = ["shaded red: the worst windows of error"] if result.worst else []
    keys += ["blue: the real gripper blocked"] if blocked else []
    return head + ("\n" + "; ".join(keys) if keys else "")


def overlay_figure(result: CompareResult) -> Any:
    """The matplotlib ``Figure`` of :func:`plot_overlay` (one panel per joint)."""
    if not result.traces:
        raise ValueError("compare(..., keep_traces=True) keeps what the plot draws")
    # start-up: matplotlib (~0.3 s) only when a plot is drawn
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    placed = episode_layout(result.traces)
    width = min(11.0 + 1.3 * (len(placed) - 1), 24.0)
    fig = Figure(figsize=(width, 12))
    axes = fig.subplots(len(JOINT_NAMES), 1, sharex=True)
    blocked_any = False
    for j, (ax, name) in enumerate(zip(axes, JOINT_NAMES, strict=True)):
        for k, p in enumerate(placed):
            tr, x = p.trace, p.x(p.trace["t"])
            first = k == 0  # one legend entry per line
            ax.plot(x, tr["command"][:, j], ":", color="gray", label="command" if first else None)
            ax.plot(x, tr["real"][:, j], color="black", label="real" if first else None)
            ax.plot(x, tr["sim"][:, j], color="tab:orange",
                    label=f"sim ({result.profile})" if first else None)  # fmt: skip
            for w in result.worst:  # the worst windows, marked on every joint
                if w.episode == p.episode:
                    ax.axvspan(p.x(w.t0), p.x(w.t1), color="tab:red", alpha=0.12, lw=0, gid=WORST)
            if k > 0:
                ax.axvline(p.offset - GAP_S / 2, color="tab:blue", ls="--", lw=0.8, gid=BOUNDARY)
            if j == len(JOINT_NAMES) - 1 and tr["blocked"].any():
                label = "gripper blocked" if not blocked_any else None
                blocked_any = True
                ax.fill_between(
                    x, 0, 1, where=tr["blocked"], color="tab:blue", alpha=0.1,
                    transform=ax.get_xaxis_transform(), label=label,
                )  # fmt: skip
        e = result.joints[name]
        ax.set_ylabel(f"{name}\n{'0-100' if name == 'gripper' else 'deg'}")
        ax.set_title(
            f"{name}: sim mae {e.mae:.2f}, command mae {result.command_baseline[name]:.2f}",
            fontsize=9,
        )
    for p in placed:  # the episode's number over the top panel, where it starts
        axes[0].annotate(
            f"episode {p.episode}", (p.offset, 1.0), xycoords=("data", "axes fraction"),
            xytext=(3, -3), textcoords="offset points", fontsize=8, color="tab:blue",
            va="top", bbox={"fc": "white", "ec": "none", "alpha": 0.7, "pad": 1},
        )  # fmt: skip
    axes[0].legend(loc="upper right", fontsize=8)
    fig.suptitle(plot_heading(result, blocked_any, len(placed)), fontsize=9)
    axes[-1].set_xlabel(
        "time, s" if len(placed) == 1 else "time, s (the episodes one after another)"
    )
    fig.tight_layout()
    return fig


def plot_overlay(result: CompareResult, path: str | Path, *, force: bool = False) -> Path:
    """Real, sim and command per joint over the compared episodes (:func:`overlay_figure`),
    written to ``path`` (PNG) atomically."""
    # start-up: the recording package only when a plot is written
    from ..recording.paths import check_output_path, write_atomically

    out = check_output_path(path, force=force, what="plot")
    fig = overlay_figure(result)
    return write_atomically(
        out, lambda p: fig.savefig(p, format="png", dpi=90), "plot", force=force
    )
