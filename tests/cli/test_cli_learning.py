"""``so101sim dataset`` and ``so101sim eval`` without their LeRobot plugins: one line saying what
to install, exit status 2, nothing written (the core never imports LeRobot)."""

from __future__ import annotations

import importlib.util
import sys

import pytest

from so101sim.cli import learning
from so101sim.cli.main import main

REAL_FIND_SPEC = importlib.util.find_spec


@pytest.fixture
def no_plugins(monkeypatch):
    plugins = {package for package, _, _ in learning.PLUGINS.values()}

    def find_spec(name, *args, **kwargs):
        if name.split(".")[0] in plugins:
            return None
        return REAL_FIND_SPEC(name, *args, **kwargs)

    monkeypatch.setattr(importlib.util, "find_spec", find_spec)


@pytest.mark.parametrize(
    ("argv", "package"),
    [
        (["dataset", "pick_cube", "--episodes", "2", "-o", "OUT"], "lerobot_robot_so101sim"),
        (
            ["eval", "POLICY", "--task", "pick_cube", "--episodes", "2", "-o", "OUT"],
            "lerobot_env_so101sim",
        ),
    ],
)
def test_without_the_plugin_the_command_says_what_to_install(
    no_plugins, tmp_path, capsys, argv, package
):
    argv = [a.replace("OUT", str(tmp_path / "out")) for a in argv]
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert f"pip install ./plugins/{package}" in lines[0] and f"so101sim {argv[0]}" in lines[0]
    assert not (tmp_path / "out").exists()
    assert "lerobot" not in sys.modules and "torch" not in sys.modules


def test_eval_help_prints_one_percent_sign(capsys):
    with pytest.raises(SystemExit):
        main(["eval", "--help"])
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    assert "95 % (Wilson) interval" in text and "%%" not in text


def test_image_size_is_width_by_height():
    import argparse

    assert learning._size("160x120") == (120, 160)  # (height, width), as the settings hold it
    with pytest.raises(argparse.ArgumentTypeError, match="WIDTHxHEIGHT"):
        learning._size("160")


def test_policy_check_needs_no_plugin(no_plugins, tmp_path, capsys):
    """policy-check reads JSON/YAML only: it runs without LeRobot's plugins."""
    import json

    policy = tmp_path / "policy"
    policy.mkdir()
    features = {"observation.state": {"type": "STATE", "shape": [6]}}
    (policy / "config.json").write_text(json.dumps({"input_features": features}))
    robot = tmp_path / "robot.json"
    robot.write_text(json.dumps({"type": "so101_follower", "port": "/dev/ttyACM0"}))
    assert main(["policy-check", str(policy), "--robot-config", str(robot)]) == 0
    assert "OK" in capsys.readouterr().out
