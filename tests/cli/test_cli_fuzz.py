"""A fuzz of the command line (issue 23): every option of every subcommand given hostile
values (empty, huge, NaN, negative, names and paths too long for the file system, missing,
unwritable and read-only paths, folders, /dev/zero) through ``main([...])`` in-process. Each
ends with a status (0, 1, 2; argparse's own refusal is SystemExit 2) and, on an error, one
``so101sim: error:`` line: never a traceback.

Each command runs from a cheap base (a 10 ms hold, a 10 ms motion file, a script of a few
steps, 16 workspace samples, a 1 s demo episode, a fit of 2 solver evaluations), so the whole
fuzz takes well under a minute.
In-process, ``record`` stops at drawing once a headless command has turned OpenGL off for the
process: its options and paths are all checked before that."""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import time
import traceback
from pathlib import Path

import pytest

from so101sim.cli import build_parser, main
from so101sim.cli.output import SIGNALS

LONG_NAME = "n" * 300
LONG_PATH = "/tmp/" + "/".join(["p" * 200] * 22)

NUMBERS = ["", "nan", "inf", "-inf", "-1", "0", "1e309", "9" * 30, "-" + "9" * 30, "abc", "1e-320"]


def _paths(tmp: Path, suffix: str) -> list[str]:
    folder = tmp / "a-folder"
    folder.mkdir(exist_ok=True)
    ro = tmp / "read-only"
    ro.mkdir(exist_ok=True)
    ro.chmod(0o555)
    return [
        "",
        " ",
        LONG_NAME + suffix,
        LONG_PATH + suffix,
        f"/nonexistent/x{suffix}",
        f"/proc/x{suffix}",  # no file can be created there, even by root
        f"{ro}/x{suffix}",
        str(folder),
        "/dev/zero",
        "/dev/null",
    ]


TEXTS = ["", " ", LONG_NAME, "\u00e9\u00e8", "-1", "nan", "..", "/"]

PATH_OPTIONS = {  # option -> the suffix of the file it names
    "--model": ".xml",
    "--record": ".mp4",
    "--plot": ".png",
    "--log": ".csv",
    "--output": ".mp4",
    "--calibration": ".json",
    "motion": ".toml",
    "script": ".py",
    "folder": "",
    "handin": ".csv",
    "--video": ".mp4",
    "--summary": ".csv",
    "policy": "",
    "--robot-config": ".json",
}
TEXT_OPTIONS = {"--camera", "--title", "--id", "--port", "--ray", "--lookat", "task", "action"}


def _bases(tmp: Path) -> dict[str, list[str]]:
    motion = tmp / "tiny.toml"
    motion.write_text('start = "rest"\n[[steps]]\nhold = 0.01\n')
    script = tmp / "tiny.py"
    script.write_text(
        "import mujoco, mujoco.viewer\n"
        "from so101sim.model import scene_path\n"
        "m = mujoco.MjModel.from_xml_path(str(scene_path()))\n"
        "d = mujoco.MjData(m)\n"
        "with mujoco.viewer.launch_passive(m, d) as v:\n"
        "    for _ in range(3):\n"
        "        mujoco.mj_step(m, d)\n"
        "        v.sync()\n"
    )
    log = tmp / "tiny.csv"  # a so101sim CSV log: 10 frames at 30 fps, the arm at rest
    names = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper")
    rest = "0.0,-98.0,88.0,60.0,0.0,0.0"
    rows = [
        "time,phase,"
        + ",".join([f"{n}_commanded" for n in names] + [f"{n}_measured" for n in names])
    ]
    rows += [f"{k / 30:.4f},hold,{rest},{rest}" for k in range(10)]
    log.write_text("\n".join(rows) + "\n")
    policy = tmp / "pretrained_model"  # a policy's inputs, as lerobot-train saves them
    policy.mkdir(exist_ok=True)
    (policy / "config.json").write_text(
        '{"type": "act", "input_features": {"observation.state": {"type": "STATE", '
        '"shape": [6]}}, "output_features": {"action": {"type": "ACTION", "shape": [6]}}}'
    )
    robot = tmp / "robot.json"
    robot.write_text('{"robot": {"type": "so101_follower", "port": "/dev/null", "id": "arm"}}')
    return {
        "run": ["run", "--headless", str(motion)],
        "compare": ["compare", str(log)],
        "grade": ["grade", str(log)],
        "policy-check": ["policy-check", str(policy), "--robot-config", str(robot)],
        # without the LeRobot plugins (the core's venv) these three say what to install, exit 2
        "dataset": ["dataset", "pick_cube", "--episodes", "1", "-o", str(tmp / "out" / "ds")],
        "eval": ["eval", str(tmp / "policy"), "--episodes", "1"],
        "pretrain-backbone": ["pretrain-backbone", str(tmp / "ds"), "-o", str(tmp / "out" / "p")],
        # 2 solver evaluations: a fit the values let through ends in a moment, as it does
        "fit": ["fit", str(log), "-o", str(tmp / "out" / "arm.toml"), "--iterations", "2"],
        "hold": ["hold", "--headless", "--duration", "0.01"],
        "check": ["check", str(motion)],
        "view": ["view"],
        "pose": ["pose"],
        "model-path": ["model-path"],
        "teleop": ["teleop", "--headless", "--port", "/nonexistent", "--duration", "0.01"],
        "record": ["record", str(script), "-o", str(tmp / "out" / "r.mp4")],
        "workspace": ["workspace", "--plot", str(tmp / "out" / "w.png"), "--samples", "16"],
        "cache": ["cache", "info"],
        "examples": ["examples", str(tmp / "out" / "examples")],
        "demo": ["demo", "reach", "--headless", "--seed", "0"],  # a 1 s episode
    }


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _cases(tmp: Path) -> list[tuple[str, str, str, list[str]]]:
    """(command, option, value, argv) for every option of every command and each hostile
    value."""
    bases = _bases(tmp)
    cases = []
    for name, sp in _subcommands().items():
        assert name in bases, f"the fuzz has no base for the new command {name!r}"
        base = bases[name]
        for action in sp._actions:
            if isinstance(action, argparse._HelpAction) or action.nargs == 0:
                continue
            flag = action.option_strings[-1] if action.option_strings else action.dest
            key = flag if flag in PATH_OPTIONS or flag in TEXT_OPTIONS else None
            if flag == "script_args":
                continue
            if key in PATH_OPTIONS:
                values = _paths(tmp, PATH_OPTIONS[key])
            elif key in TEXT_OPTIONS or action.choices:
                values = TEXTS
            else:
                values = NUMBERS
            for value in values:
                cases.append((name, flag, value, _with(base, action, flag, value)))
    return cases


def _with(base: list[str], action: argparse.Action, flag: str, value: str) -> list[str]:
    """``base`` with ``flag`` set to ``value`` (a positional replaced where the base has it)."""
    if action.option_strings:
        argv = list(base)
        if flag in argv:  # replace the base's own value
            i = argv.index(flag)
            return [*argv[: i + 1], value, *argv[i + 2 :]]
        short = [s for s in action.option_strings if s in argv]
        if short:
            i = argv.index(short[0])
            return [*argv[: i + 1], value, *argv[i + 2 :]]
        return [*argv, f"{flag}={value}"]  # '=' so that a value starting with '-' is a value
    # a positional: the base's word after the command (motion, script, folder, task, action,
    # handin)
    positionals = [w for w in base[1:] if not w.startswith("-")]
    if positionals and action.dest in ("motion", "script", "folder", "task", "action", "handin"):
        i = base.index(positionals[0])
        return [*base[:i], value, *base[i + 1 :]]
    return [*base, "--", value] if value.startswith("-") else [*base, value]


def _run(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse refused the value
            code = exc.code if isinstance(exc.code, int) else 2
        except Exception:  # what main() let through: the user would see a traceback
            traceback.print_exc(file=err)
            code = -1
    return code, err.getvalue()


def test_every_option_with_hostile_values_gives_no_traceback(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "out").mkdir()
    cases = _cases(tmp_path)
    assert len(cases) > 500
    t0 = time.monotonic()
    problems = []
    for _, flag, value, argv in cases:
        code, err = _run(argv)
        if flag in PATH_OPTIONS and not value.strip() and code != 2:  # "" is not "no file"
            problems.append((argv, code, "an empty path was not refused"))
        lines = [line for line in err.splitlines() if line.startswith("so101sim: error:")]
        if "Traceback" in err or code not in (0, 1, 2) or (code == 2 and len(lines) > 1):
            problems.append((argv, code, err[-600:]))
        elif code == 2 and not lines and "usage:" not in err:
            problems.append((argv, code, "no error line: " + err[-300:]))
    elapsed = time.monotonic() - t0
    shown = "\n\n".join(f"{[a[:60] for a in p[0]]} -> {p[1]}\n{p[2]}" for p in problems[:10])
    assert not problems, f"{len(problems)} of {len(cases)} cases failed:\n{shown}"
    print(f"{len(cases)} cases, 0 tracebacks, {elapsed:.1f} s")
    assert math.isfinite(elapsed)


def test_the_fuzz_covers_every_subcommand_and_option(tmp_path) -> None:
    covered = {(name, flag) for name, flag, _, _ in _cases(tmp_path)}
    for name, sp in _subcommands().items():
        for action in sp._actions:
            if isinstance(action, argparse._HelpAction) or action.nargs == 0:
                continue
            flag = action.option_strings[-1] if action.option_strings else action.dest
            if flag != "script_args":
                assert (name, flag) in covered, (name, flag)


@pytest.fixture(autouse=True)
def _no_signal_handlers_left(monkeypatch):
    """main() installs its handlers per command and puts them back: nothing to undo here."""
    yield
    assert SIGNALS._previous == {}
