"""Tests of so101sim.recording.paths: output paths checked before anything runs."""

from __future__ import annotations

import pytest

from so101sim import Simulation
from so101sim import recording as rec
from so101sim.errors import OutputPathError
from so101sim.recording import paths


def test_missing_output_folder_fails_before_anything_runs(tmp_path):
    sim = Simulation()
    for kwargs in ({"video": tmp_path / "no" / "a.mp4"}, {"log": tmp_path / "no" / "a.csv"}):
        with pytest.raises(OutputPathError, match="does not exist"):
            rec.Recorder(sim, **kwargs)
    assert sim.time == 0.0
    assert list(tmp_path.iterdir()) == []


def test_unwritable_output_folder_fails(tmp_path, monkeypatch):
    monkeypatch.setattr(paths.os, "access", lambda path, mode: False)
    with pytest.raises(OutputPathError, match="not writable"):
        rec.check_output_path(tmp_path / "a.csv")


def test_existing_file_is_kept_unless_forced(tmp_path):
    sim = Simulation()
    path = tmp_path / "old.csv"
    path.write_text("keep me")
    with pytest.raises(OutputPathError, match="already exists"):
        rec.Recorder(sim, log=path)
    assert path.read_text() == "keep me"
    with rec.Recorder(sim, log=path, force=True):
        sim.hold(0.01)
    assert path.read_text().startswith("time,phase,")
