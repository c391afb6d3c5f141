"""Preparing and running a motion as ``so101sim run``/``hold`` do (so101sim.cli.runplan)."""

from __future__ import annotations

import pytest

from so101sim.cli.runplan import Outputs, check_strict, prepare_run
from so101sim.errors import SettingError, TrajectoryLimitError
from so101sim.model import load_model
from so101sim.motion import Hold, Move
from so101sim.units import STARTING_POSE, ZERO_POSE


def test_check_strict_refuses_a_limited_move_that_is_too_short():
    m = load_model()
    check_strict(m, [Move(ZERO_POSE, 2.0, shape="limited")])  # long enough
    with pytest.raises(TrajectoryLimitError, match="--strict"):
        check_strict(m, [Move(ZERO_POSE, 0.05, shape="limited")], STARTING_POSE)


def test_prepare_checks_everything_then_runs_headless(monkeypatch, tmp_path):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(SettingError, match="speed"):
        prepare_run([Hold(0.1)], speed=0.0)
    log = tmp_path / "h.csv"
    run = prepare_run([Hold(0.1)], outputs=Outputs(log=log))
    assert not run.viewer.use and "running headless" in run.viewer.note
    assert run.video_frames is None and run.duration == pytest.approx(0.1)
    assert not log.exists()  # nothing is written before the run
    result = run.execute()
    assert run.recorder.close() == {"log": log}
    assert result.completed and result.segments[0].steps == 50
