"""A full disk, for real: a tiny tmpfs (mounting needs root; skipped where it cannot be
mounted). Whatever runs out of space, the command says so and exits 2, never says "wrote",
shows no traceback, and leaves no file behind. (Without root, tests/test_recording_csvlog.py
and test_recording_video.py write to /dev/full instead.)"""

from __future__ import annotations

import os
import shutil
import subprocess
import uuid
from pathlib import Path

import pytest

from so101sim import cli

FILLER = "filler"


@pytest.fixture
def full_disk(tmp_path):
    """A 1 MiB tmpfs filled but for ``free`` bytes: call it with the free space wanted."""
    mounts: list[Path] = []

    def make(free: int) -> Path:
        folder = tmp_path / f"disk-{uuid.uuid4().hex[:6]}"
        folder.mkdir()
        if shutil.which("mount") is None or os.geteuid() != 0:
            pytest.skip("mounting a tmpfs needs root and mount(8)")
        done = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(folder)],
            capture_output=True,
            check=False,
        )
        if done.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode().strip()}")
        mounts.append(folder)
        st = os.statvfs(folder)
        (folder / FILLER).write_bytes(b"\0" * (st.f_bavail * st.f_frsize - free))
        return folder

    yield make
    for folder in mounts:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def _hold(folder: Path, *options: str) -> list[str]:
    return ["hold", "--headless", "--duration", "2", *options]


def _assert_refused(capsys, folder: Path, what: str) -> None:
    captured = capsys.readouterr()
    assert f"could not write the {what}" in captured.err and "No space left" in captured.err
    assert "Traceback" not in captured.err and f"wrote the {what}" not in captured.out
    assert sorted(p.name for p in folder.iterdir()) == [FILLER]


@pytest.mark.slow
def test_a_video_on_a_full_disk_is_an_error_not_a_written_video(full_disk, capsys):
    disk = full_disk(8192)
    options = ["--record", str(disk / "h.mp4"), "--width", "320", "--height", "240"]
    assert cli.main(_hold(disk, *options, "--quality", "draft")) == 2
    _assert_refused(capsys, disk, "video")


@pytest.mark.slow
def test_a_log_on_a_full_disk_is_an_error_without_a_traceback(full_disk, capsys):
    disk = full_disk(8192)
    assert cli.main(_hold(disk, "--log", str(disk / "h.csv"))) == 2
    _assert_refused(capsys, disk, "log")


@pytest.mark.slow
def test_a_plot_on_a_full_disk_is_an_error_without_a_traceback(full_disk, capsys):
    disk = full_disk(8192)
    assert cli.main(_hold(disk, "--plot", str(disk / "h.png"))) == 2
    _assert_refused(capsys, disk, "plot")


@pytest.mark.slow
def test_outputs_on_another_disk_are_still_written_when_one_fills_up(full_disk, tmp_path, capsys):
    disk = full_disk(8192)
    argv = _hold(disk, "--log", str(disk / "h.csv"), "--plot", str(tmp_path / "h.png"))
    assert cli.main(argv) == 2
    captured = capsys.readouterr()
    assert "could not write the log" in captured.err
    assert f"wrote the plot so far to {tmp_path / 'h.png'}" in captured.out
    assert (tmp_path / "h.png").is_file()
