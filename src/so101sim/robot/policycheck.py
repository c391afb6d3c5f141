"""``so101sim policy-check POLICY --robot-config FILE``: will a trained policy run on this robot?

A policy saved by ``lerobot-train`` (its ``pretrained_model`` folder) says in ``config.json``
which inputs it reads (``input_features``: ``observation.state`` with its size,
``observation.images.<camera>`` with (channels, height, width), perhaps
``observation.environment_state``); its ``train_config.json`` names the dataset it was trained
on, whose ``meta/info.json`` (when that folder is here) gives the state's names, the frame rate
and the robot type, and whose ``meta/so101sim.json`` says it came from ``so101sim dataset``
(body joints in degrees, the gripper 0..100).

A robot config is the file ``lerobot-record --config_path FILE`` takes (JSON or YAML, its
``robot`` section), or that section alone: ``type`` (``so101_follower``, ``so100_follower``,
``so_follower`` or ``so101_sim``), ``use_degrees``, ``cameras`` (``{name: {type, width, height,
fps, ...}}``). :func:`check_policy` compares them and returns one :class:`Finding` per mismatch
(a camera the policy reads that the robot lacks, a resolution, the state's size or names,
degrees against range mode, a frame rate, an input no real robot has), plus notes on what it
could not check. It reads JSON and YAML only: no LeRobot, no torch.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import MissingDependencyError, SettingError
from ..scenes import CameraSpec
from ..units import JOINT_NAMES
from ..validation import check_input_file

FOLLOWER_STATE_NAMES = tuple(f"{j}.pos" for j in JOINT_NAMES)
"""What the SO-100/SO-101 follower (real and simulated) calls its state's six numbers."""
REAL_TYPES = ("so101_follower", "so100_follower", "so_follower")
SIM_TYPES = ("so101_sim",)
USE_DEGREES_DEFAULT = True
"""LeRobot 0.6.1's ``SOFollowerConfig.use_degrees`` default (body joints in degrees)."""
MAX_CONFIG_BYTES = 1_000_000


@dataclass(frozen=True)
class Finding:
    """One mismatch (``what`` names the part: camera, resolution, state, units, ...)."""

    what: str
    message: str


@dataclass(frozen=True)
class PolicyCheck:
    """What :func:`check_policy` found: ``mismatches`` (the policy would not run as trained)
    and ``notes`` (what could not be checked, and why)."""

    policy: Path
    robot_config: Path
    mismatches: tuple[Finding, ...]
    notes: tuple[str, ...] = field(default=())

    @property
    def ok(self) -> bool:
        return not self.mismatches


def _read_mapping(path: Path, what: str) -> dict[str, Any]:
    """A JSON or YAML file holding a mapping."""
    name = what.removeprefix("the ")  # check_input_file says "the {name}"
    path = check_input_file(path, name, expected=f"{what} as a JSON or YAML file")
    if path.stat().st_size > MAX_CONFIG_BYTES:
        raise SettingError(
            f"{what} {str(path)!r} is over {MAX_CONFIG_BYTES} bytes; expected a config"
        )
    text = path.read_text(encoding="utf-8", errors="replace")
    try:
        if path.suffix.lower() in (".yaml", ".yml"):
            try:
                import yaml  # only for YAML files: imported when one is read
            except ImportError as exc:
                raise MissingDependencyError(
                    f"{path} is YAML: reading it needs PyYAML (`pip install pyyaml`); or give the "
                    "config as JSON"
                ) from exc
            data = yaml.safe_load(text)
        else:
            data = json.loads(text)
    except ValueError as exc:  # json.JSONDecodeError
        raise SettingError(
            f"{what} {str(path)!r} cannot be read ({exc}); expected JSON or YAML"
        ) from exc
    except Exception as exc:  # yaml.YAMLError does not derive from ValueError
        if type(exc).__module__.startswith("yaml"):
            raise SettingError(f"{what} {str(path)!r} is not valid YAML ({exc})") from exc
        raise
    if not isinstance(data, dict):
        raise SettingError(f"{what} {str(path)!r} holds {type(data).__name__}; expected a mapping")
    return data


def _policy_folder(policy: Path) -> Path:
    """The ``pretrained_model`` folder given (or the folder of its ``config.json``)."""
    if policy.is_dir():
        return policy
    if policy.is_file() and policy.name == "config.json":
        return policy.parent
    what = "is not a folder" if policy.exists() else "does not exist"
    raise SettingError(
        f"the policy folder {str(policy)!r} {what}; expected the folder lerobot-train saved "
        "the policy in (.../checkpoints/last/pretrained_model, with config.json)"
    )


def _policy_config(folder: Path) -> dict[str, Any]:
    cfg = _read_mapping(folder / "config.json", "the policy's config.json")
    if not isinstance(cfg.get("input_features"), dict):
        raise SettingError(
            f"{folder / 'config.json'} has no input_features; expected a policy saved by "
            "lerobot-train (.../checkpoints/last/pretrained_model)"
        )
    return cfg


def dataset_roots(folder: Path, root: str | Path) -> list[Path]:
    """Where the training dataset of the policy in ``folder`` may be, given its ``root`` as
    train_config.json keeps it (as it was given to lerobot-train): an absolute root as it is;
    a relative one from the current folder, then from each folder above the policy's, nearest
    first (lerobot-train ran in one of them when its ``--output_dir`` was relative, and a
    dataset is usually kept beside the outputs)."""
    root = Path(root)
    if root.is_absolute():
        return [root]
    # the folders above the policy's as named (a symlinked outputs/ too) and as they really are
    above = [*folder.absolute().parents, *folder.resolve().parents]
    return list(dict.fromkeys([Path.cwd() / root, *(d / root for d in above)]))


def training_meta(folder: Path) -> tuple[dict[str, Any] | None, dict[str, Any] | None, str]:
    """The training dataset's meta/info.json and meta/so101sim.json of the policy saved in
    ``folder``, or (None, None, why they are not here).

    Raises:
        SettingError: train_config.json or the meta files unreadable."""
    train_file = folder / "train_config.json"
    if not train_file.is_file():
        return None, None, f"{train_file} is missing"
    train = _read_mapping(train_file, "the policy's train_config.json")
    ds = train.get("dataset") or {}
    if not isinstance(ds, dict):
        return None, None, f"train_config.json's dataset is {ds!r}, not a mapping with a root"
    if not ds.get("root"):
        return None, None, f"train_config.json names dataset {ds.get('repo_id')!r} without a root"
    roots = dataset_roots(folder, str(ds["root"]))
    meta = next((r / "meta" for r in roots if (r / "meta" / "info.json").is_file()), None)
    if meta is None:
        where = "" if len(roots) == 1 else ", nor in a folder above the policy's"
        why = (
            f"the training dataset (root {str(ds['root'])!r} in train_config.json) is not on "
            f"this machine: no {roots[0] / 'meta' / 'info.json'}{where}"
        )
        return None, None, why
    info = _read_mapping(meta / "info.json", "the dataset's info.json")
    sim = meta / "so101sim.json"
    return info, _read_mapping(sim, "so101sim.json") if sim.is_file() else None, ""


def training_fps(policy: str | Path) -> int | None:
    """The frame rate of the data the policy saved at ``policy`` was trained on (its training
    dataset's ``meta/info.json``), or None when that dataset is not here."""
    info, _, _ = training_meta(_policy_folder(Path(policy)))
    return _frame_rate((info or {}).get("fps"))


def _frame_rate(fps: Any) -> int | None:
    """A dataset's ``fps`` as a whole number of frames a second, or None when it is not a
    finite positive number (then it is not checked)."""
    if isinstance(fps, bool) or not isinstance(fps, (int, float)):
        return None
    return round(fps) if math.isfinite(fps) and 0.5 <= fps <= 10_000 else None


def robot_section(config: Mapping[str, Any]) -> dict[str, Any]:
    """The robot's part of a ``lerobot-record --config_path`` file (``robot``), or the file
    itself when it is that part (it has a ``type``)."""
    robot = config.get("robot", config)
    if not isinstance(robot, dict) or "type" not in robot:
        raise SettingError(
            "the robot config has no robot type; expected lerobot-record's config (a 'robot' "
            "section with 'type', 'cameras', 'use_degrees') or that section alone"
        )
    return robot


SIM_CAMERA_SIZE = (CameraSpec.width, CameraSpec.height)
"""A simulated follower's camera size when its entry gives none (:mod:`so101sim.scenes`)."""


MAX_CAMERA_NUMBER = 100_000


def _as_bool(value: Any, name: str) -> bool:
    """A true/false setting as LeRobot's config reader (draccus) takes it: a boolean, or the
    word ``"true"`` or ``"false"`` (nothing else: it refuses ``"yes"``, ``1``, ``"TRUE"``)."""
    if isinstance(value, bool):
        return value
    if value in ("true", "false"):
        return value == "true"
    raise SettingError(
        f"the robot config's {name} is {value!r}; expected true or false (LeRobot's config "
        "reader takes nothing else)"
    )


def _as_count(value: Any, name: str) -> int | None:
    """A camera's width, height or fps as draccus reads them (``int | None``): a whole number,
    or the digits of one (not a float: LeRobot refuses ``160.0``); None when it is not set."""
    if value is None:
        return None
    n: int | None = None
    if isinstance(value, int) and not isinstance(value, bool):
        n = value
    elif isinstance(value, str) and value.strip().isdecimal() and value.strip().isascii():
        n = int(value.strip())
    if n is None or not 0 < n <= MAX_CAMERA_NUMBER:
        raise SettingError(
            f"the robot config's {name} is {value!r}; expected a whole number from 1 to "
            f"{MAX_CAMERA_NUMBER}"
        )
    return n


def _camera_size(cam: Mapping[str, Any], name: str, sim: bool) -> tuple[Any, Any]:
    w = _as_count(cam.get("width"), f"cameras.{name}.width")
    h = _as_count(cam.get("height"), f"cameras.{name}.height")
    if sim:
        return w or SIM_CAMERA_SIZE[0], h or SIM_CAMERA_SIZE[1]
    return w, h


def _check_cameras(
    inputs: dict[str, Any], robot: dict[str, Any], fps: Any, notes: list[str]
) -> list[Finding]:
    out: list[Finding] = []
    cameras = robot.get("cameras") or {}
    if not isinstance(cameras, dict):
        return [Finding("cameras", f"robot cameras = {cameras!r}; expected {{name: {{...}}}}")]
    wanted = {k.removeprefix("observation.images."): v for k, v in inputs.items()
              if k.startswith("observation.images.")}  # fmt: skip
    for name, cam in cameras.items():
        if not isinstance(cam, dict):
            raise SettingError(
                f"the robot config's cameras.{name} is {cam!r}; expected the camera's settings "
                "({type: opencv, index_or_path: ..., width: ..., height: ..., fps: ...})"
            )
    for name, ft in wanted.items():
        shape = list(ft.get("shape") or [])
        h, w = (shape[1], shape[2]) if len(shape) == 3 else (None, None)
        cam = cameras.get(name)
        if cam is None:
            have = ", ".join(sorted(cameras)) or "none"
            out.append(Finding("camera", f"missing camera {name!r}: the policy reads "
                       f"observation.images.{name} ({w}x{h}); the robot has {have}: add "
                       f"cameras.{name} (or rename one)"))  # fmt: skip
            continue
        cw, ch = _camera_size(cam, name, robot.get("type") in SIM_TYPES)
        if (cw, ch) != (w, h):
            got = "not set (the camera's default)" if cw is None or ch is None else f"{cw}x{ch}"
            out.append(Finding("resolution", f"camera {name!r}: {got}, the policy was trained "
                       f"on {w}x{h} (width x height): set width={w}, height={h} (LeRobot does "
                       "not resize a camera's frames for a policy)"))  # fmt: skip
        cam_fps = _as_count(cam.get("fps"), f"cameras.{name}.fps")
        if fps is not None and cam_fps is not None and cam_fps != fps:
            out.append(Finding("fps", f"camera {name!r} runs at {cam_fps} fps, the policy was "
                       f"trained on {fps} fps data: set fps={fps}"))  # fmt: skip
    for name in sorted(set(cameras) - set(wanted)):
        notes.append(f"camera {name!r} is not an input of the policy (recorded, never read)")
    return out


def check_policy(policy: str | Path, robot_config: str | Path) -> PolicyCheck:
    """Compare the inputs of the policy saved at ``policy`` with the robot of
    ``robot_config`` (see the module's text).

    Raises:
        SettingError: a file missing or unreadable, or not what it should be;
        MissingDependencyError: a YAML file without PyYAML.
    """
    policy, robot_config = Path(policy), Path(robot_config)
    folder = _policy_folder(policy)
    cfg = _policy_config(folder)
    robot = robot_section(_read_mapping(robot_config, "the robot config"))
    use_degrees = _as_bool(robot.get("use_degrees", USE_DEGREES_DEFAULT), "use_degrees")
    inputs: dict[str, Any] = cfg["input_features"]
    info, sim_meta, why = training_meta(folder)
    notes: list[str] = []
    out: list[Finding] = []
    kind = str(robot["type"])
    if kind not in REAL_TYPES + SIM_TYPES:
        out.append(Finding("robot", f"robot type {kind!r}: the check knows the SO-100/SO-101 "
                   f"follower ({', '.join(REAL_TYPES + SIM_TYPES)})"))  # fmt: skip
    state = inputs.get("observation.state")
    if state is None:
        notes.append("the policy reads no observation.state")
    elif list(state.get("shape") or []) != [len(FOLLOWER_STATE_NAMES)]:
        out.append(Finding("state", f"the policy's observation.state has shape {state.get('shape')}"
                   f", the follower sends {len(FOLLOWER_STATE_NAMES)} numbers"))  # fmt: skip
    if "observation.environment_state" in inputs:
        out.append(Finding("input", "the policy reads observation.environment_state (the objects' "
                   "poses from the simulator): no real robot has that sensor; train on cameras "
                   "and joints only (so101sim dataset without --environment-state)"))  # fmt: skip
    fps = None
    if info is None:
        notes.append(f"state names, units and fps not checked: {why}")
    else:
        fps = _frame_rate(info.get("fps"))
        names = ((info.get("features") or {}).get("observation.state") or {}).get("names")
        if isinstance(names, dict):  # older datasets: {"motors": [...]}
            names = next(iter(names.values()), None)
        if names is not None and tuple(names) != FOLLOWER_STATE_NAMES:
            out.append(Finding("state", f"the policy's state names {list(names)}; the follower's "
                       f"are {list(FOLLOWER_STATE_NAMES)}"))  # fmt: skip
        if sim_meta is not None:
            if not use_degrees:
                out.append(Finding("units", "use_degrees is false (range mode, -100..100): the "
                           "policy was trained on so101sim data in degrees (gripper 0..100); "
                           "set use_degrees: true"))  # fmt: skip
        elif sim_meta is None:
            notes.append("units not checked: the training dataset is not so101sim's")
    out += _check_cameras(inputs, robot, fps, notes)
    return PolicyCheck(policy, robot_config, tuple(out), tuple(notes))


__all__ = [
    "FOLLOWER_STATE_NAMES",
    "Finding",
    "PolicyCheck",
    "check_policy",
    "dataset_roots",
    "robot_section",
    "training_fps",
    "training_meta",
]
