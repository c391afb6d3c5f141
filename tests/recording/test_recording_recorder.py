"""Tests of so101sim.recording.Recorder: misuse, and finishing every file whatever lands
while they are finished (a second Ctrl-C, another exception)."""

from __future__ import annotations

import imageio.v2 as imageio
import pytest
from recording_helpers import SMALL, csv_problems, no_partial_files, read_video

from so101sim import Simulation
from so101sim import recording as rec
from so101sim.errors import RecordingError, So101SimError


@pytest.mark.parametrize("target", ["not a sim", None, 42, object()])
def test_recording_something_that_is_not_a_simulation_says_what_is_expected(target, tmp_path):
    with pytest.raises(RecordingError, match=r"expected a so101sim\.Simulation") as info:
        rec.Recorder(target, log=tmp_path / "a.csv")
    assert isinstance(info.value, So101SimError)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"plot_size": (10**9, 480)}, "plot width"),
        ({"plot_size": (640,)}, "plot_size"),
        ({"settings": "hd"}, "not a VideoSettings"),
    ],
)
def test_bad_recorder_arguments_are_refused_before_anything_runs(kwargs, match, tmp_path):
    with pytest.raises(RecordingError, match=match):
        rec.Recorder(Simulation(), plot=tmp_path / "p.png", **kwargs)
    assert list(tmp_path.iterdir()) == []


def _interrupt_first_call(monkeypatch, cls, exc: BaseException) -> None:
    """``cls.close`` raises ``exc`` the first time, before doing anything."""
    close, calls = cls.close, []

    def close_once(self):
        calls.append(1)
        if len(calls) == 1:
            raise exc
        return close(self)

    monkeypatch.setattr(cls, "close", close_once)


def _record(tmp_path):
    sim = Simulation()
    r = rec.Recorder(
        sim,
        video=tmp_path / "v.mp4",
        log=tmp_path / "v.csv",
        plot=tmp_path / "v.png",
        settings=SMALL,
        plot_size=(640, 480),
    )
    with r:
        sim.hold(0.2)
    return r


def test_a_second_ctrl_c_while_the_files_are_finished_still_finishes_them(tmp_path, monkeypatch):
    _interrupt_first_call(monkeypatch, rec.VideoRecorder, KeyboardInterrupt())
    with pytest.raises(KeyboardInterrupt):
        _record(tmp_path)  # raised once every file is finished
    assert len(read_video(tmp_path / "v.mp4")[0]) == 7
    assert csv_problems(tmp_path / "v.csv") == []
    assert imageio.imread(tmp_path / "v.png").shape[:2] == (480, 640)
    assert no_partial_files(tmp_path)


def test_ctrl_c_while_the_plot_is_drawn_draws_it_again(tmp_path, monkeypatch):
    plot_run, calls = rec.recorder.plot_run, []

    def interrupted_plot(*args, **kwargs):
        calls.append(1)
        path = plot_run(*args, **kwargs)
        if len(calls) == 1:
            raise KeyboardInterrupt  # written, then interrupted before it was noted
        return path

    monkeypatch.setattr(rec.recorder, "plot_run", interrupted_plot)
    with pytest.raises(KeyboardInterrupt):
        _record(tmp_path)
    assert len(calls) == 2 and imageio.imread(tmp_path / "v.png").ndim == 3
    assert no_partial_files(tmp_path)


def test_other_exceptions_while_finishing_drop_what_is_not_finished(tmp_path, monkeypatch):
    _interrupt_first_call(monkeypatch, rec.VideoRecorder, SystemExit(3))
    with pytest.raises(SystemExit):
        _record(tmp_path)
    assert list(tmp_path.iterdir()) == []  # no partial file, no half-finished output


def test_many_ctrl_cs_while_finishing_finally_give_up_what_they_interrupt(tmp_path, monkeypatch):
    def always_interrupted(self):
        raise KeyboardInterrupt

    monkeypatch.setattr(rec.VideoRecorder, "close", always_interrupted)
    with pytest.raises(KeyboardInterrupt):
        _record(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.csv", "v.png"]  # the others
