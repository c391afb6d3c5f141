"""Found trying issue 29 as a new user: check names the servo model it ran, and a closed
pipe (``so101sim check | head``) ends the command quietly, without a traceback."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from so101sim.cli.main import main

SRC = str(Path(__file__).parents[2] / "src")


def test_check_names_the_servo_model_it_ran(tmp_path, capsys):
    motion = tmp_path / "mine.toml"
    motion.write_text('start = "rest"\n[[steps]]\nhold = 0.2\n')
    assert main(["check", str(motion)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"checked {motion}"
    assert lines[1].startswith("servo model: sts3215 (STS3215 fitted")
    assert main(["check", str(motion), "--arm", "official"]) == 0
    second = capsys.readouterr().out.splitlines()[1]
    assert second == "servo model: official (the model file's own ideal position actuators)"
    assert main(["check", str(motion), "--json", "--arm", "official"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["servo_model"].startswith("official (")
    assert report["motion"] == str(motion)


def test_a_closed_pipe_ends_the_command_without_a_traceback():
    env = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.Popen(
        [sys.executable, "-m", "so101sim", "model-path"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    proc.stdout.close()  # as `| head` does once it has read its lines: the print fails
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141, err  # 128 + SIGPIPE, as a shell reports it
    assert "Traceback" not in err and "BrokenPipeError" not in err and "Exception" not in err


def test_a_scripts_error_shows_the_scripts_traceback_not_so101sims(tmp_path, capsys):
    helper = tmp_path / "utils.py"
    helper.write_text("def angle(pose):\n    return pose['elbow_flex']\n")
    script = tmp_path / "my_lab.py"
    script.write_text("from utils import angle\n\nstart = {'elbow_flx': 88.0}\nangle(start)\n")
    assert main(["record", str(script), "--log", str(tmp_path / "lab.csv")]) == 1
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert lines[0] == "Traceback (most recent call last):"
    assert lines[1] == f'  File "{script}", line 4, in <module>'  # the script's frame first
    assert f'File "{helper}", line 2, in angle' in err
    assert "runpy" not in err and "handin.py" not in err and "cli/tools.py" not in err
    assert lines[-2] == "KeyError: 'elbow_flex'"
    assert lines[-1] == f"so101sim: {script}:4 raised KeyError"

    script.write_text("x = (1,\ny = 2)\n")  # a syntax error in the script: no traceback
    assert main(["record", str(script), "--log", str(tmp_path / "lab.csv")]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.startswith(f'  File "{script}", line ')
    assert err.splitlines()[-2].startswith("SyntaxError: ")


def test_check_variants_names_the_servo_model_it_perturbs(tmp_path, capsys):
    motion = tmp_path / "mine.toml"
    motion.write_text('start = "rest"\n[[steps]]\nhold = 0.1\n')
    main(["check", str(motion), "--variants", "2", "--threads", "1", "--arm", "official"])
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("robust preflight: 2 variants of ")
    assert lines[1] == (
        "servo model: official (the model file's own ideal position actuators)"
        " (perturbed per variant)"
    )
    main(["check", str(motion), "--variants", "2", "--threads", "1", "--json"])
    assert json.loads(capsys.readouterr().out)["servo_model"].startswith("sts3215 (")


def test_a_script_that_fails_after_recording_says_which_files_hold_what_ran(tmp_path, capsys):
    """Found by a new user: the video of a script that raised after opening its viewer was
    finished (playable) but not mentioned; now each file is named after the error."""
    script = tmp_path / "typo_lab.py"
    script.write_text(
        "import mujoco, mujoco.viewer\n"
        "from so101sim import scene_path\n"
        "m = mujoco.MjModel.from_xml_path(str(scene_path()))\n"
        "d = mujoco.MjData(m)\n"
        "with mujoco.viewer.launch_passive(m, d) as viewer:\n"
        "    for _ in range(100):\n"
        "        mujoco.mj_step(m, d)\n"
        "        viewer.sync()\n"
        "    hold_positon(m, d)\n"
    )
    log = tmp_path / "typo.csv"
    assert main(["record", str(script), "--log", str(log)]) == 1
    lines = capsys.readouterr().err.splitlines()
    assert lines[-2] == f"so101sim: {script}:9 raised NameError"
    assert lines[-1] == f"so101sim: the log holds what ran before the error: {log}"
    rows = log.read_text().splitlines()
    assert rows[0].startswith("time,") and len(rows) > 50  # what ran: 0.2 s of steps
