"""Shared helpers of the recording tests: a small video setting, readers of what was written,
and a driver that interrupts ``so101sim hold`` recordings with signals at random points.

Run as a script, the driver does many of each signal and prints the counts::

    PYTHONPATH=src:tests python tests/recording_helpers.py --runs 30
"""

from __future__ import annotations

import contextlib
import csv
import os
import random
import signal
import subprocess
import sys
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import imageio.v2 as imageio
import numpy as np

from so101sim import recording as rec

SMALL = rec.VideoSettings(width=64, height=48, fps=30, quality="draft")
"""A 64×48 draft video at 30 frames/s, with caption: quick to render on a CPU."""


def read_video(path) -> tuple[list[np.ndarray], float]:
    reader = imageio.get_reader(path)
    try:
        fps = reader.get_meta_data()["fps"]
        return [np.asarray(f) for f in reader], fps
    finally:
        reader.close()


def read_csv(path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def count_frames(path) -> int:
    """Frames in a video file, read back by ffmpeg (imageio-ffmpeg's own reader, not the
    recorder's); raises if the file does not open."""
    import imageio_ffmpeg

    return int(imageio_ffmpeg.count_frames_and_secs(str(path))[0])


def no_partial_files(folder) -> bool:
    return not [p for p in Path(folder).iterdir() if ".partial" in p.name]


def csv_problems(path, timestep: float = 0.002) -> list[str]:
    """What is wrong with a CSV log (empty list: a complete log): the header, every row's
    field count, and times that go on step by step from the first step."""
    header, rows = read_csv(path)
    problems = [] if header == rec.csv_columns() else ["bad header"]
    if any(len(row) != len(header) for row in rows):
        problems.append("a row has the wrong number of fields")
    times = np.array([float(row[0]) for row in rows]) if rows else np.empty(0)
    expected = timestep * np.arange(1, len(times) + 1)
    if not np.allclose(times, expected, atol=1e-4):
        problems.append("times do not go on step by step")
    return problems


# ---------------------------------------------------------------------------- signal driver
_CHILD = r"""
import faulthandler, signal, sys
faulthandler.enable()  # a crash leaves its stack in the child's stderr
for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):  # between runs: ignored
    signal.signal(s, lambda *a: None)
from so101sim import cli
for line in sys.stdin:
    try:
        code = cli.main(line.rstrip("\n").split("\t"))
    except SystemExit as exc:
        code = exc.code
    print(f"\nEXIT {code}", flush=True)
"""


@dataclass
class Outcome:
    """What one interrupted recording left: exit status, files, and what was wrong."""

    signals: tuple[str, ...]
    code: int
    files: list[str]
    problems: list[str] = field(default_factory=list)
    frames: int | None = None
    rows: int | None = None


def _check_outputs(folder: Path, printed: str, outcome: Outcome) -> None:
    """Each output either complete (and said to be written) or absent; no temporary files."""
    names = sorted(p.name for p in folder.iterdir())
    outcome.files = names
    if not no_partial_files(folder):
        outcome.problems.append("temporary files left")
    for name, key in (("h.mp4", "video"), ("h.csv", "log"), ("h.png", "plot")):
        said = f"wrote the {key} so far to {folder / name}" in printed
        if said != (name in names):
            outcome.problems.append(f"{name}: on disk {name in names}, said written {said}")
    if "h.mp4" in names:
        try:
            outcome.frames = count_frames(folder / "h.mp4")
        except Exception as exc:  # the video does not open
            outcome.problems.append(f"h.mp4 does not open: {exc}")
        else:
            if f"({outcome.frames} frames)" not in printed:
                outcome.problems.append("h.mp4: frame count differs from the one printed")
    if "h.csv" in names:
        outcome.rows = len(read_csv(folder / "h.csv")[1])
        outcome.problems += [f"h.csv: {p}" for p in csv_problems(folder / "h.csv")]
    if "h.png" in names and imageio.imread(folder / "h.png").ndim != 3:
        outcome.problems.append("h.png does not open")


def _stepping(run: Path) -> bool:
    """Whether the recording in ``run`` has stepped: its partial log holds a row (the log file
    exists from the start, before the first frame is drawn, which on a busy machine can take
    longer than the delay before the signal)."""
    for partial in run.glob(".h.*.partial.csv"):
        try:
            if partial.read_text().count("\n") >= 2:  # the header and a row
                return True
        except OSError:  # renamed meanwhile
            pass
    return False


def _wait_for(condition, timeout: float = 300.0) -> None:
    end = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > end:
            raise TimeoutError("the recording did not start")
        time.sleep(0.01)


def _dump_and_kill(child: subprocess.Popen) -> None:
    """A hung child: its threads' stacks to its stderr (faulthandler on SIGABRT), then kill."""
    with contextlib.suppress(OSError, subprocess.TimeoutExpired):
        child.send_signal(signal.SIGABRT)
        child.wait(timeout=10)
    with contextlib.suppress(OSError):
        child.kill()


def interrupt_recordings(
    folder: Path,
    plans: list[tuple[signal.Signals, ...]],
    *,
    seed: int = 0,
    delay: tuple[float, float] = (0.0, 3.0),
    gap: tuple[float, float] = (0.0, 1.0),
    plot: bool = True,
    hang_s: float = 300.0,
) -> list[Outcome]:
    """Record ``so101sim hold`` (video, log and, with ``plot``, a plot) once per plan in one
    child process and send the plan's signals: the first a random ``delay`` after the run
    began stepping, each next one a random ``gap`` later (so they land while it runs, while
    its files are finished, or after). Returns what each recording left; raises if a command
    has not ended ``hang_s`` seconds after its signals."""
    rng = random.Random(seed)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "PYTHONUNBUFFERED": "1"}
    errors = open(folder / "child-stderr.txt", "w")  # noqa: SIM115 (closed with the child)
    child = subprocess.Popen(
        [sys.executable, "-c", _CHILD],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=errors,
        text=True,
        env=env,
    )
    assert child.stdin is not None and child.stdout is not None

    def start(run: Path, duration: str) -> str:
        run.mkdir()
        argv = [
            "hold", "--headless", "--duration", duration, "--record", str(run / "h.mp4"),
            "--log", str(run / "h.csv"), "--width", "64", "--height", "48", "--quality", "draft",
        ]  # fmt: skip
        if plot:
            argv += ["--plot", str(run / "h.png")]
        child.stdin.write("\t".join(argv) + "\n")
        child.stdin.flush()
        return child.stdout.readline()  # "holding the starting pose: ..."

    outcomes = []
    try:
        start(folder / "warm-up", "0.05")  # the model, renderer and plotting loaded once
        while (line := child.stdout.readline()) and not line.startswith("EXIT"):
            pass
        for i, plan in enumerate(plans):
            run = folder / f"run{i}"
            printed = start(run, "60")
            _wait_for(lambda run=run: _stepping(run))
            time.sleep(rng.uniform(*delay))
            for k, sig in enumerate(plan):
                if k:
                    time.sleep(rng.uniform(*gap))
                child.send_signal(sig)
            # a hung command ends the test, its threads' stacks first in the child's stderr
            # (SIGABRT: faulthandler's dump), then killed
            watchdog = threading.Timer(hang_s, _dump_and_kill, (child,))
            watchdog.start()
            while not (line := child.stdout.readline()).startswith("EXIT") and line:
                printed += line
            watchdog.cancel()
            if not line:
                try:
                    status = child.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    status = None
                # the watchdog's abort (the stacks) or kill
                hung = status is None or status in (-signal.SIGABRT, -signal.SIGKILL)
                what = f"hung for {hang_s} s" if hung else f"died (status {status})"
                stderr = (folder / "child-stderr.txt").read_text()[-8000:]  # with the stacks
                raise AssertionError(f"run {i} {plan} {what}:\n{printed}\nstderr:\n{stderr}")
            outcome = Outcome(tuple(s.name for s in plan), int(line.split()[1]), [])
            if outcome.code != 128 + plan[0]:
                outcome.problems.append(f"exit status {outcome.code}")
            _check_outputs(run, printed, outcome)
            outcomes.append(outcome)
    finally:
        child.stdin.close()
        child.kill()
        child.wait()
        errors.close()
    return outcomes


def _main() -> None:
    import argparse
    import tempfile

    p = argparse.ArgumentParser(description="interrupt recordings with signals; print counts")
    p.add_argument("--runs", type=int, default=30, help="recordings per kind of signal")
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args()
    kinds = [(signal.SIGTERM,), (signal.SIGHUP,), (signal.SIGINT, signal.SIGINT)]
    plans = [kind for kind in kinds for _ in range(args.runs)]
    random.Random(args.seed).shuffle(plans)
    with tempfile.TemporaryDirectory() as tmp:
        outcomes = interrupt_recordings(Path(tmp), plans, seed=args.seed)
    tally: Counter[tuple[str, str]] = Counter()
    for o in outcomes:
        kind = "+".join(o.signals)
        tally[kind, "runs"] += 1
        tally[kind, "good"] += not o.problems
        tally[kind, "with video"] += o.frames is not None
        tally[kind, "with log"] += o.rows is not None
        for problem in o.problems:
            print(f"{kind}: {problem}")
    for kind in sorted({k for k, _ in tally}):
        parts = ", ".join(
            f"{tally[kind, c]} {c}" for c in ("runs", "good", "with video", "with log")
        )
        print(f"{kind}: {parts}")


if __name__ == "__main__":
    _main()
