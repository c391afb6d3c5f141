"""``compare --plot`` draws every compared episode (issue 32, point 4): one after another on
one time axis, a dashed line and the episode's number where each starts, the worst windows of
each shaded where they are; at most MAX_PLOT_EPISODES drawn, the heading saying so."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("pyarrow")
pytest.importorskip("matplotlib")

from fidelity_helpers import record, write_lerobot

from so101sim.cli import main
from so101sim.fidelity.compare import compare
from so101sim.fidelity.logs import ArmLog, Episode
from so101sim.fidelity.plot import (
    BOUNDARY,
    GAP_S,
    MAX_PLOT_EPISODES,
    WORST,
    episode_layout,
    overlay_figure,
    plot_heading,
)
from so101sim.model.arm import load_profile
from so101sim.units import JOINT_NAMES


@pytest.fixture(scope="module")
def three():
    """Three 1.5 s episodes of the sim's own arm; the real elbow 8 deg off in 0.6-1.1 s of
    episode 1 (its worst window) and in 0.2-0.7 s of episode 2."""
    arm = load_profile("sts3215")
    eps = record(arm, [4, 5, 6], seconds=1.5)
    real = []
    for ep, bump in zip(eps, [None, (0.6, 1.1), (0.2, 0.7)], strict=True):
        meas = ep.measured.copy()
        if bump is not None:
            meas[(ep.times > bump[0]) & (ep.times < bump[1]), 2] += 8.0
        real.append(Episode(ep.index, ep.times, ep.command, meas))
    log = ArmLog(30.0, real, "synthetic", "csv")
    return real, compare(log, arm=arm, keep_traces=True)


def _spans(ax):
    """(x0, x1) of the red shading on ``ax`` (the worst windows)."""
    out = []
    for patch in ax.patches:
        if patch.get_gid() != WORST:
            continue
        if hasattr(patch, "get_width"):  # a Rectangle (matplotlib >= 3.9)
            out.append((patch.get_x(), patch.get_x() + patch.get_width()))
        else:  # a Polygon
            xy = np.asarray(patch.get_xy())
            out.append((float(xy[:, 0].min()), float(xy[:, 0].max())))
    return sorted(out)


def test_the_plot_draws_every_episode_with_its_start_and_worst_windows(three):
    real, res = three
    assert [tr["episode"] for tr in res.traces] == [0, 1, 2]
    fig = overlay_figure(res)
    axes = fig.axes
    assert len(axes) == len(JOINT_NAMES)
    placed = episode_layout(res.traces)
    assert [p.episode for p in placed] == [0, 1, 2]
    assert placed[1].offset == pytest.approx(real[0].times[-1] + GAP_S)
    for ax in axes:
        # three lines per episode (command, real, sim) and a dashed start before episodes 1, 2
        data_lines = [ln for ln in ax.lines if ln.get_gid() != BOUNDARY]
        starts = [ln for ln in ax.lines if ln.get_gid() == BOUNDARY]
        assert len(data_lines) == 3 * 3 and len(starts) == 2
        xs = sorted(float(ln.get_xdata()[0]) for ln in starts)
        assert xs == pytest.approx([placed[1].offset - GAP_S / 2, placed[2].offset - GAP_S / 2])
        # the real elbow's line of episode 2 is drawn where episode 2 is placed
        x_end = max(float(np.max(ln.get_xdata())) for ln in data_lines)
        assert x_end == pytest.approx(placed[2].offset + real[2].times[-1])
    labels = [t.get_text() for t in axes[0].texts]
    assert labels == ["episode 0", "episode 1", "episode 2"]
    # each worst window shaded where its episode is placed, on every joint
    windows = [w for w in res.worst if w.episode in (1, 2)]
    assert {w.episode for w in windows} == {1, 2} and all(w.joint == "elbow_flex" for w in windows)
    spans = _spans(axes[2])
    for w in windows:
        p = placed[w.episode]
        assert (pytest.approx(p.offset + w.t0), pytest.approx(p.offset + w.t1)) in spans
    assert len(_spans(axes[0])) == len(res.worst)
    assert fig._suptitle.get_text().startswith("episodes 0, 1, 2, one after another")


def test_more_episodes_than_drawn_are_capped_and_the_heading_says_so(three):
    _, res = three
    many = [dict(tr, episode=k) for k, tr in enumerate(res.traces * 4)]  # 12 episodes
    big = dataclasses.replace(res, traces=many, episodes=list(range(12)), worst=[])
    fig = overlay_figure(big)
    starts = [ln for ln in fig.axes[0].lines if ln.get_gid() == BOUNDARY]
    assert len(starts) == MAX_PLOT_EPISODES - 1
    assert len(fig.axes[0].texts) == MAX_PLOT_EPISODES
    head = plot_heading(big, False, MAX_PLOT_EPISODES)
    assert head.startswith(f"the first {MAX_PLOT_EPISODES} of the 12 compared episodes (0..9")
    assert "over all 12" in head
    assert fig._suptitle.get_text() == head


def test_compare_plot_writes_every_episode(three, tmp_path, capsys):
    real, _ = three
    root = write_lerobot(tmp_path / "ds", real)
    png = tmp_path / "o.png"
    argv = ["compare", str(root), "--units", "degrees", "--episodes", "1-2", "--plot", str(png)]
    assert main(argv) == 0
    assert png.stat().st_size > 1000
    out = capsys.readouterr().out
    assert "wrote" in out and str(png) in out
    import imageio.v3 as iio

    # two episodes: the figure widens by one step beyond one episode's 11 inches (at 90 dpi)
    assert iio.imread(png).shape[1] == pytest.approx((11.0 + 1.3) * 90, abs=2)
