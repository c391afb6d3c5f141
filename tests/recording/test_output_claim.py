"""Output files claimed atomically (issue 30): two processes writing the same ``--log`` both
reported success and one file was lost. The finished file is now linked to its path, which
fails if anything is there: a race gives one file and one error, never two successes."""

from __future__ import annotations

import pytest

from so101sim import cli
from so101sim.errors import OutputPathError
from so101sim.model import load_model
from so101sim.recording import paths
from so101sim.recording.csvlog import CsvLog
from so101sim.sim.simulation import Simulation
from so101sim.validation import STALE_TEMP_S


def _logged(path, model):
    sim = Simulation(model)
    log = CsvLog(path, model)  # both checks pass: nothing is at the path yet
    sim.observers.append(log)
    sim.hold(0.05)
    return log


def test_two_logs_of_the_same_path_give_one_file_and_one_error(tmp_path):
    model = load_model(physics_only=True)
    path = tmp_path / "run.csv"
    first, second = _logged(path, model), _logged(path, model)
    assert first.close() == path
    text = path.read_text()
    with pytest.raises(OutputPathError, match=r"appeared while this run wrote it.*--force"):
        second.close()
    assert path.read_text() == text  # the first one's file, whole
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv"]  # no temporary left


def test_force_replaces_what_appeared(tmp_path):
    path = tmp_path / "out.txt"
    pending = paths.PendingFile(path, force=True)
    pending.tmp.write_text("new")
    path.write_text("old")
    assert pending.finish(keep=True) == path
    assert path.read_text() == "new"


def test_write_atomically_refuses_a_file_that_appeared(tmp_path):
    path = tmp_path / "plot.png"

    def write(tmp):
        tmp.write_bytes(b"mine")
        path.write_bytes(b"theirs")  # another process finished first

    with pytest.raises(OutputPathError, match="appeared"):
        paths.write_atomically(path, write, "plot")
    assert path.read_bytes() == b"theirs"
    assert [p.name for p in tmp_path.iterdir()] == ["plot.png"]


def test_without_hard_links_the_path_is_still_claimed_once(tmp_path, monkeypatch):
    def no_links(src, dst):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(paths.os, "link", no_links)
    path = tmp_path / "a.csv"
    pending = paths.PendingFile(path)
    pending.tmp.write_text("mine")
    assert pending.finish(keep=True) == path
    assert path.read_text() == "mine" and not pending.tmp.exists()
    again = paths.PendingFile(path)
    again.tmp.write_text("second")
    with pytest.raises(OutputPathError, match="appeared"):
        again.finish(keep=True)
    assert path.read_text() == "mine"


def test_a_commit_interrupted_after_the_link_is_resumed(tmp_path, monkeypatch):
    path = tmp_path / "b.csv"
    pending = paths.PendingFile(path)
    pending.tmp.write_text("rows")
    real_unlink = paths.Path.unlink
    calls = []

    def interrupted_unlink(self, *a, **k):
        if not calls:
            calls.append(1)
            raise KeyboardInterrupt
        return real_unlink(self, *a, **k)

    monkeypatch.setattr(paths.Path, "unlink", interrupted_unlink)
    with pytest.raises(KeyboardInterrupt):
        pending.commit()
    pending.commit()  # goes on where it stopped: no "appeared" for its own link
    assert pending.committed and path.read_text() == "rows" and not pending.tmp.exists()


def test_the_command_line_reports_a_race_as_one_error(tmp_path, capsys, monkeypatch):
    path = tmp_path / "run.csv"
    real = paths.PendingFile._claim

    def other_process_first(self):
        self.path.write_text("another run's log\n")
        return real(self)

    monkeypatch.setattr(paths.PendingFile, "_claim", other_process_first)
    code = cli.main(["hold", "--duration", "0.05", "--headless", "--log", str(path)])
    out, err = capsys.readouterr()
    assert code == 2
    errors = [line for line in err.splitlines() if line.startswith("so101sim: error")]
    assert len(errors) == 1 and "appeared while this run wrote it" in errors[0], err
    assert "wrote the log" not in out
    assert path.read_text() == "another run's log\n"


def test_the_workspace_plot_is_claimed_too(tmp_path, monkeypatch):
    from so101sim.kinematics import workspace

    path = tmp_path / "ws.png"

    def other_process_first(kin, rows, samples):
        path.write_bytes(b"another run's plot")
        return real(kin, rows, samples)

    real = workspace._figure
    monkeypatch.setattr(workspace, "_figure", other_process_first)
    with pytest.raises(OutputPathError, match="appeared"):
        workspace.plot_workspace(path, samples=200)
    assert path.read_bytes() == b"another run's plot"
    assert [p.name for p in tmp_path.iterdir()] == ["ws.png"]


def test_temporary_files_a_killed_run_left_are_deleted_by_the_next_run(tmp_path):
    """SIGKILL leaves ``.<stem>.<pid>.partial<suffix>``: the next run of the same output
    deletes it once its process is gone and it is an hour old; anything unsure stays."""
    import os
    import subprocess
    import sys

    gone_pid = subprocess.Popen([sys.executable, "-c", "pass"])  # a pid now unused
    gone_pid.wait()
    path = tmp_path / "run.csv"
    stale = tmp_path / f".run.{gone_pid.pid}.partial.csv"
    recent = tmp_path / f".run.{gone_pid.pid + 1}.partial.csv"
    alive = tmp_path / f".run.{os.getppid()}.partial.csv"  # a running process: left
    other = tmp_path / f".runs.{gone_pid.pid}.partial.csv"  # another output's: left
    for f in (stale, recent, alive, other):
        f.write_text("half a log")
    old = os.path.getmtime(stale) - STALE_TEMP_S - 60
    for f in (stale, alive, other):
        os.utime(f, (old, old))
    pending = paths.PendingFile(path)
    assert not stale.exists()
    assert recent.exists() and alive.exists() and other.exists()
    pending.discard()
