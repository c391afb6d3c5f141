"""Long runs keep memory flat: ``so101sim hold --log --plot`` peaks at the same resident size
for 60 s and for 300 s of simulated time (the log streams to disk, the plot keeps a bounded
envelope, nothing else keeps per-step data). An hour-long hold is measured in docs/recording.md.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

import so101sim

pytestmark = pytest.mark.skipif(not hasattr(os, "wait4"), reason="needs os.wait4 (POSIX)")


def _peak_rss_mb(tmp_path, seconds: int) -> float:
    """Peak resident memory (MB) of ``so101sim hold --headless --log --plot`` in a child."""
    src = os.path.dirname(os.path.dirname(so101sim.__file__))
    argv = [
        sys.executable, "-m", "so101sim", "hold", "--headless", "--duration", str(seconds),
        "--log", str(tmp_path / f"h{seconds}.csv"), "--plot", str(tmp_path / f"h{seconds}.png"),
    ]  # fmt: skip
    path = [src, *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(path)}
    child = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _, status, usage = os.wait4(child.pid, 0)
    child.returncode = os.waitstatus_to_exitcode(status)
    assert child.returncode == 0, child.stderr.read().decode() if child.stderr else ""
    scale = 1024 if sys.platform != "darwin" else 1  # kB on Linux, bytes on macOS
    return usage.ru_maxrss * scale / 1e6


@pytest.mark.slow
def test_a_five_times_longer_hold_with_log_and_plot_needs_no_more_memory(tmp_path):
    short, long = _peak_rss_mb(tmp_path, 60), _peak_rss_mb(tmp_path, 300)
    # 120k more steps: per-step arrays of ~100 B/step kept anywhere would add 12 MB or more
    assert long - short < 8.0, f"peak {short:.1f} MB for 60 s, {long:.1f} MB for 300 s"
    assert (tmp_path / "h300.csv").stat().st_size > 5 * (tmp_path / "h60.csv").stat().st_size * 0.99
