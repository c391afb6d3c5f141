"""SIGINT, SIGTERM and SIGHUP during a recording: every one finishes the files as Ctrl-C does,
and a second signal while they are finished waits until they are.

The signals here are sent to this process from inside the run (an observer at a simulated
time, or the recorder's close), so where they land is deterministic; the last test sends them
from outside at random times to a child process that records again and again
(``tests/recording_helpers.py --runs 30`` does many more).
"""

from __future__ import annotations

import os
import signal
import sys

import imageio.v2 as imageio
import pytest
from recording_helpers import count_frames, csv_problems, interrupt_recordings, no_partial_files

from so101sim import cli
from so101sim.cli import runplan
from so101sim.recording import Recorder
from so101sim.sim.simulation import Observer

pytestmark = pytest.mark.skipif(
    not hasattr(signal, "SIGHUP") or sys.platform == "win32", reason="POSIX signals"
)


class SignalAt(Observer):
    """Sends ``signum`` to this process when simulated time reaches ``t``."""

    def __init__(self, t: float, signum: int) -> None:
        self.t, self.signum, self.sent = t, signum, False

    def next_time(self) -> float:
        return self.t if not self.sent else float("inf")

    def on_time(self, m, d) -> bool:
        self.sent = True
        os.kill(os.getpid(), self.signum)
        return True


def _signal_during_run(monkeypatch, t: float, signum: int) -> None:
    """Make the CLI's run send ``signum`` just after simulated time ``t`` (its frame drawn)."""
    t += 0.001
    original = runplan.run_plan

    def run_plan(sim, plan, *, observers=(), **kw):
        return original(sim, plan, observers=[*observers, SignalAt(t, signum)], **kw)

    monkeypatch.setattr(runplan, "run_plan", run_plan)


def _record(tmp_path) -> list[str]:
    out = tmp_path
    return [
        "hold", "--headless", "--duration", "30", "--record", str(out / "h.mp4"),
        "--log", str(out / "h.csv"), "--plot", str(out / "h.png"), "--width", "64",
        "--height", "48", "--quality", "draft",
    ]  # fmt: skip


def _assert_complete(tmp_path, printed: str, until: float) -> None:
    frames = count_frames(tmp_path / "h.mp4")
    assert frames == round(until * 30) + 1 and f"({frames} frames)" in printed
    assert csv_problems(tmp_path / "h.csv") == []
    assert imageio.imread(tmp_path / "h.png").ndim == 3
    for key in ("video", "log", "plot"):
        assert f"wrote the {key} so far to" in printed
    assert no_partial_files(tmp_path)


@pytest.mark.parametrize(
    "signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT], ids=["TERM", "HUP", "INT"]
)
def test_each_signal_finishes_the_files_as_ctrl_c_does(monkeypatch, tmp_path, capsys, signum):
    _signal_during_run(monkeypatch, 0.5, signum)
    assert cli.main(_record(tmp_path)) == 128 + signum
    captured = capsys.readouterr()
    _assert_complete(tmp_path, captured.out, 0.5)
    assert f"interrupted ({signal.Signals(signum).name})" in captured.err


@pytest.mark.parametrize("second", [signal.SIGINT, signal.SIGTERM], ids=["INT", "TERM"])
def test_a_second_signal_while_the_files_are_finished_waits(monkeypatch, tmp_path, capfd, second):
    _signal_during_run(monkeypatch, 0.3, signal.SIGINT)
    close = Recorder.close

    def close_with_a_signal(self):  # the second signal lands as the finish begins
        os.kill(os.getpid(), second)
        return close(self)

    monkeypatch.setattr(Recorder, "close", close_with_a_signal)
    assert cli.main(_record(tmp_path)) == 130  # the first signal says how it ended
    captured = capfd.readouterr()  # the notice is written to file descriptor 2
    _assert_complete(tmp_path, captured.out, 0.3)
    assert "finishing with the output files first" in captured.err


def test_a_signal_while_a_finished_run_writes_its_files_is_honoured_after(
    monkeypatch, tmp_path, capsys
):
    close = Recorder.close

    def close_with_a_signal(self):
        os.kill(os.getpid(), signal.SIGTERM)
        return close(self)

    monkeypatch.setattr(Recorder, "close", close_with_a_signal)
    argv = _record(tmp_path)
    argv[argv.index("30")] = "0.2"
    assert cli.main(argv) == 128 + signal.SIGTERM
    out = capsys.readouterr().out
    assert count_frames(tmp_path / "h.mp4") == 7 and "wrote the video to" in out
    assert csv_problems(tmp_path / "h.csv") == [] and no_partial_files(tmp_path)


def test_the_signal_handlers_are_put_back_after_the_command(tmp_path):
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    assert cli.main(["hold", "--headless", "--duration", "0.01"]) == 0
    assert {s: signal.getsignal(s) for s in before} == before


@pytest.mark.slow
def test_signals_at_random_points_leave_playable_files_and_no_temporary_ones(tmp_path):
    plans = [(signal.SIGTERM,), (signal.SIGHUP,), (signal.SIGINT, signal.SIGINT)] * 2
    # without a plot (drawing it takes seconds; the tests above check it)
    outcomes = interrupt_recordings(tmp_path, plans, seed=7, delay=(0.0, 1.5), plot=False)
    assert [o.problems for o in outcomes] == [[] for _ in plans]
    assert [o.code for o in outcomes] == [128 + p[0] for p in plans]
    assert all(o.frames and o.rows for o in outcomes)  # each had begun: video and log kept


def test_a_signal_inside_a_c_call_still_ends_as_that_signal(monkeypatch, tmp_path, capsys):
    """A signal that lands while ctypes converts a C call's argument (PyOpenGL's EGL calls
    while a frame renders) comes out as ctypes.ArgumentError, not as the Interrupted the
    handler raised: it must still finish the files and exit 128 + the signal."""
    import ctypes

    from so101sim.recording.frames import FrameRenderer

    class SignalledArgument:
        @classmethod
        def from_param(cls, value):
            os.kill(os.getpid(), signal.SIGTERM)  # the handler raises here, inside ctypes
            return value

    c_abs = ctypes.CDLL(None).abs
    c_abs.argtypes = [SignalledArgument]
    render = FrameRenderer.render
    calls = []

    def render_then_call_c(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 5:
            c_abs(1)
        return render(self, *args, **kwargs)

    monkeypatch.setattr(FrameRenderer, "render", render_then_call_c)
    assert cli.main(_record(tmp_path)) == 128 + signal.SIGTERM
    captured = capsys.readouterr()
    assert "interrupted (SIGTERM)" in captured.err
    assert count_frames(tmp_path / "h.mp4") == 4 and "wrote the video so far" in captured.out
    assert csv_problems(tmp_path / "h.csv") == [] and no_partial_files(tmp_path)
