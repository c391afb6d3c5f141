"""Tests of so101sim.recording.paths: output paths checked before anything runs."""

from __future__ import annotations

import errno
import os
import stat

import pytest

from so101sim import Simulation, cli
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


def test_force_never_replaces_a_device_or_a_pipe(tmp_path):
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    with pytest.raises(OutputPathError, match="named pipe, not a regular file"):
        rec.Recorder(Simulation(), log=fifo, force=True)
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    with pytest.raises(OutputPathError, match="character device"):
        rec.check_output_path("/dev/null", force=True, what="log")  # only checked, not written


def test_cli_force_onto_a_pipe_is_an_error_and_leaves_it(tmp_path, capsys):
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    assert cli.main(["hold", "--duration", "0.1", "--log", str(fifo), "--force"]) == 2
    assert "not a regular file" in capsys.readouterr().err
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe.csv"]


def test_a_legal_long_file_name_is_written(tmp_path):
    name = "a" * 246 + ".csv"  # 250 bytes: the temporary name must fit too
    sim = Simulation()
    with rec.Recorder(sim, log=tmp_path / name) as r:
        sim.hold(0.01)
    assert r.outputs == {"log": tmp_path / name} and (tmp_path / name).is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]
    pending = paths.PendingFile(tmp_path / name)
    assert len(pending.tmp.name) <= 255 and pending.tmp.name.endswith(".partial.csv")


def test_a_file_name_longer_than_the_file_system_allows_says_the_limit(tmp_path):
    with pytest.raises(OutputPathError, match=r"300 bytes long; expected at most 255 bytes"):
        rec.check_output_path(tmp_path / ("a" * 296 + ".csv"))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("folder", ["/proc", "/sys", "/proc/self"])
def test_proc_and_sys_targets_fail_before_anything_runs(folder, capsys):
    if not os.path.isdir(folder):
        pytest.skip(f"no {folder} here")
    target = f"{folder}/so101sim-test.csv"
    with pytest.raises(OutputPathError, match="cannot write the log"):
        rec.check_output_path(target, what="log")
    assert cli.main(["hold", "--duration", "0.1", "--log", target]) == 2
    err = capsys.readouterr().err
    assert "so101sim: error:" in err and "Traceback" not in err


def test_write_errors_say_what_failed_and_what_is_expected(tmp_path):
    err = paths.write_error("log", tmp_path / "a.csv", OSError(errno.ENOSPC, "No space left"))
    assert isinstance(err, OutputPathError)
    text = str(err)
    assert "could not write the log" in text and "No space left" in text
    assert "nothing was left at that path" in text and "free some space" in text


def test_a_finish_interrupted_after_the_rename_is_done_once(tmp_path):
    pending = paths.PendingFile(tmp_path / "a.csv")
    pending.tmp.write_text("x")
    pending._renaming = True  # as if interrupted between the rename and noting it
    os.replace(pending.tmp, pending.path)
    assert pending.finish(keep=True) == pending.path and pending.committed
    pending.discard()  # a committed file is never removed
    assert pending.path.read_text() == "x"
