"""``so101sim policy-check``: a policy's inputs against a robot's LeRobot config (no LeRobot).

The policy folders are written here as lerobot-train writes them (config.json's
``input_features``, train_config.json's dataset root, the dataset's meta); the plugin tests
check the same on a policy lerobot-train really saved.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from so101sim.cli.main import main
from so101sim.errors import SettingError
from so101sim.robot.policycheck import FOLLOWER_STATE_NAMES, check_policy, training_fps

NAMES = list(FOLLOWER_STATE_NAMES)


def write_policy(tmp: Path, *, cameras=("front", "wrist"), size=(120, 160), env_state=False,
                 names=NAMES, sim=True, dataset=True, relative=False) -> Path:  # fmt: skip
    """A pretrained_model folder: config.json, train_config.json, the dataset's meta; with
    ``relative``, where ``lerobot-train --dataset.root=data --output_dir=outputs/run`` run in
    ``tmp`` puts them (train_config.json keeps both paths as given)."""
    inputs = {"observation.state": {"type": "STATE", "shape": [6]}}
    for cam in cameras:
        inputs[f"observation.images.{cam}"] = {"type": "VISUAL", "shape": [3, *size]}
    if env_state:
        inputs["observation.environment_state"] = {"type": "ENV", "shape": [7]}
    policy = tmp / (
        "outputs/run/checkpoints/000004/pretrained_model" if relative else "pretrained_model"
    )
    policy.mkdir(parents=True)
    outputs = {"action": {"type": "ACTION", "shape": [6]}}
    cfg = {"type": "act", "input_features": inputs, "output_features": outputs}
    (policy / "config.json").write_text(json.dumps(cfg))
    root = tmp / "data"
    dataset_cfg = {"repo_id": "local/so101sim", "root": "data" if relative else str(root)}
    train = {"dataset": dataset_cfg, "output_dir": "outputs/run" if relative else str(tmp)}
    (policy / "train_config.json").write_text(json.dumps(train))
    if dataset:
        (root / "meta").mkdir(parents=True)
        features = {"observation.state": {"dtype": "float32", "shape": [6], "names": names}}
        info = {"fps": 30, "robot_type": "so101_sim", "features": features}
        (root / "meta" / "info.json").write_text(json.dumps(info))
        if sim:
            (root / "meta" / "so101sim.json").write_text(json.dumps({"task": "pick_cube"}))
    return policy


def robot_file(tmp: Path, name="robot.json", *, cameras=None, use_degrees=None, section=True,
               kind="so101_follower") -> Path:  # fmt: skip
    """A robot config as lerobot-record --config_path takes it (or its robot section)."""
    if cameras is None:
        cameras = {
            c: {"type": "opencv", "index_or_path": i, "width": 160, "height": 120, "fps": 30}
            for i, c in enumerate(("front", "wrist"))
        }
    robot: dict = {"type": kind, "port": "/dev/ttyACM0", "id": "arm", "cameras": cameras}
    if use_degrees is not None:
        robot["use_degrees"] = use_degrees
    data = {"robot": robot, "dataset": {"repo_id": "me/eval", "single_task": "pick"}}
    path = tmp / name
    content = data if section else robot
    if name.endswith((".yaml", ".yml")):
        yaml = pytest.importorskip("yaml")
        path.write_text(yaml.safe_dump(content))
    else:
        path.write_text(json.dumps(content))
    return path


def test_a_matching_robot_passes(tmp_path, capsys):
    policy = write_policy(tmp_path)
    for i, name in enumerate(("robot.json", "robot.yaml")):
        sub = tmp_path / str(i)
        sub.mkdir()
        path = robot_file(sub, name, use_degrees=True)
        result = check_policy(policy, path)
        assert result.ok and result.mismatches == ()
        assert main(["policy-check", str(policy), "--robot-config", str(path)]) == 0
        assert capsys.readouterr().out.strip().splitlines()[-1].startswith("OK")
    # the robot section alone, use_degrees left at LeRobot 0.6.1's default (True)
    assert check_policy(policy, robot_file(tmp_path, "alone.json", section=False)).ok


def test_each_mismatch_is_one_line(tmp_path, capsys):
    policy = write_policy(tmp_path)
    cams = {"front": {"type": "opencv", "index_or_path": 0, "width": 640, "height": 480,
                      "fps": 15}}  # fmt: skip
    path = robot_file(tmp_path, cameras=cams, use_degrees=False)
    result = check_policy(policy, path)
    kinds = sorted(f.what for f in result.mismatches)
    assert kinds == ["camera", "fps", "resolution", "units"]
    text = {f.what: f.message for f in result.mismatches}
    assert "missing camera 'wrist'" in text["camera"]
    assert "640x480" in text["resolution"] and "160x120" in text["resolution"]
    assert "use_degrees" in text["units"]
    assert main(["policy-check", str(policy), "--robot-config", str(path)]) == 1
    out = capsys.readouterr().out.strip().splitlines()
    lines = [line for line in out if not line.startswith(("note:", "4 mismatch"))]
    assert sorted(line.split(":")[0] for line in lines) == kinds
    assert out[-1].startswith("4 mismatch")


def test_state_names_environment_state_and_unset_sizes(tmp_path):
    policy = write_policy(tmp_path, env_state=True, names=[f"j{i}" for i in range(6)])
    cams = {c: {"type": "opencv", "index_or_path": 0} for c in ("front", "wrist")}
    result = check_policy(policy, robot_file(tmp_path, cameras=cams))
    kinds = sorted(f.what for f in result.mismatches)
    assert kinds == ["input", "resolution", "resolution", "state"]
    assert all("not set" in f.message for f in result.mismatches if f.what == "resolution")


def test_without_the_training_dataset_it_says_what_it_did_not_check(tmp_path):
    policy = write_policy(tmp_path, dataset=False)
    result = check_policy(policy, robot_file(tmp_path, use_degrees=False))
    assert result.ok  # units cannot be told without the dataset: a note, not a mismatch
    assert any("not on this machine" in n for n in result.notes)


def test_a_simulated_follower_defaults_to_640x480(tmp_path):
    policy = write_policy(tmp_path, size=(480, 640))
    path = robot_file(tmp_path, kind="so101_sim", cameras={"front": {}, "wrist": {}})
    assert check_policy(policy, path).ok


def test_unreadable_files_exit_2(tmp_path, capsys):
    policy = write_policy(tmp_path)
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert main(["policy-check", str(policy), "--robot-config", str(bad)]) == 2
    assert "JSON or YAML" in capsys.readouterr().err
    pytest.importorskip("yaml")
    bad_yaml = tmp_path / "bad.yaml"
    bad_yaml.write_text("robot: [unclosed")
    with pytest.raises(SettingError, match="not valid YAML"):
        check_policy(policy, bad_yaml)
    no_type = tmp_path / "no_type.json"
    no_type.write_text(json.dumps({"robot": {"port": "x"}}))
    with pytest.raises(SettingError, match="no robot type"):
        check_policy(policy, no_type)
    with pytest.raises(SettingError, match=r"no config\.json|not a file|does not exist"):
        check_policy(tmp_path / "nowhere", no_type)
    assert main(["policy-check", str(tmp_path), "--robot-config", str(no_type)]) == 2


def test_a_relative_dataset_root_is_found_from_another_folder(tmp_path, monkeypatch):
    """The docs' recipe trains with ``--dataset.root=data/...``: train_config.json keeps the
    root relative to where lerobot-train ran, which policy-check finds from anywhere."""
    policy = write_policy(tmp_path / "project", relative=True)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    result = check_policy(policy, robot_file(tmp_path, use_degrees=False))
    assert [f.what for f in result.mismatches] == ["units"]  # the dataset's meta was read
    assert not any("not checked" in n for n in result.notes)
    gone = write_policy(tmp_path / "gone", relative=True, dataset=False)
    notes = check_policy(gone, robot_file(tmp_path, "r2.json")).notes
    assert any("root 'data'" in n and "not on this machine" in n for n in notes), notes


def test_values_are_read_as_lerobots_config_reader_reads_them(tmp_path, capsys):
    """draccus takes ``"false"`` for false and ``"160"`` for 160: so does the check."""
    policy = write_policy(tmp_path)
    as_text = {c: {"type": "opencv", "index_or_path": i, "width": "160", "height": "120",
                   "fps": "30"} for i, c in enumerate(("front", "wrist"))}  # fmt: skip
    assert check_policy(policy, robot_file(tmp_path, cameras=as_text)).ok
    result = check_policy(policy, robot_file(tmp_path, "deg.json", use_degrees="false"))
    assert [f.what for f in result.mismatches] == ["units"]
    assert check_policy(policy, robot_file(tmp_path, "deg2.json", use_degrees="true")).ok
    for refused in ("yes", "TRUE", 1, 0.0):  # draccus takes no other spelling
        with pytest.raises(SettingError, match="expected true or false"):
            check_policy(policy, robot_file(tmp_path, "deg4.json", use_degrees=refused))
    for width in (160.0, "²", "1e3", True, [160]):  # nor a float, nor a non-ASCII digit
        cams = {**as_text, "front": {**as_text["front"], "width": width}}
        with pytest.raises(SettingError, match=r"cameras\.front\.width is .*; expected a whole"):
            check_policy(policy, robot_file(tmp_path, "w.json", cameras=cams))
    bad_fps = {**as_text, "front": {**as_text["front"], "fps": "abc"}}
    path = robot_file(tmp_path, "fps.json", cameras=bad_fps)
    with pytest.raises(SettingError, match=r"cameras\.front\.fps is 'abc'; expected a whole"):
        check_policy(policy, path)
    assert main(["policy-check", str(policy), "--robot-config", str(path)]) == 2
    with pytest.raises(SettingError, match="use_degrees is 'maybe'; expected true or false"):
        check_policy(policy, robot_file(tmp_path, "deg3.json", use_degrees="maybe"))
    null = robot_file(tmp_path, "null.json", cameras={**as_text, "front": None})
    with pytest.raises(SettingError, match=r"cameras\.front is None; expected the camera's"):
        check_policy(policy, null)


def test_a_policy_folder_that_is_not_there_is_named(tmp_path, capsys):
    missing = tmp_path / "nope"
    assert main(["policy-check", str(missing), "--robot-config", str(robot_file(tmp_path))]) == 2
    err = capsys.readouterr().err
    assert f"the policy folder {str(missing)!r} does not exist" in err
    a_file = tmp_path / "model.safetensors"
    a_file.write_bytes(b"")
    with pytest.raises(SettingError, match="is not a folder; expected the folder"):
        check_policy(a_file, robot_file(tmp_path))


def test_a_training_config_or_dataset_meta_out_of_shape_is_a_note_not_a_crash(tmp_path):
    policy = write_policy(tmp_path)
    robot = robot_file(tmp_path)
    info = tmp_path / "data" / "meta" / "info.json"
    for fps in ("NaN", "Infinity", "0", "-30"):  # json reads NaN and Infinity
        info.write_text(info.read_text().replace('"fps": 30', '"fps": ' + fps, 1))
        assert check_policy(policy, robot).ok  # the camera's fps is not checked against it
        assert training_fps(policy) is None
        info.write_text(info.read_text().replace('"fps": ' + fps, '"fps": 30', 1))
    assert training_fps(policy) == 30
    train = policy / "train_config.json"
    for dataset in ('"data"', "[1]", "3"):
        train.write_text('{"dataset": ' + dataset + "}")
        notes = check_policy(policy, robot).notes
        assert any("not a mapping with a root" in n for n in notes), notes
