"""The RL recipe (scripts/train_ppo.py, docs/rl.md): a PPO smoke run of a few hundred steps on
make_vec's reach task, where stable-baselines3 (the ``rl`` extra, and torch) is installed. CI
runs it in the LeRobot venv, which has torch; the core's own venv skips it."""

import csv
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "train_ppo.py"


def _load():
    spec = importlib.util.spec_from_file_location("train_ppo", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_ppo_smoke_run_trains_and_saves(tmp_path):
    train = _load()
    assert train.main(["--task", "reach", "--smoke", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "eval.json").read_text())
    assert summary["train_steps"] >= 256 and summary["envs"] == 2
    assert (tmp_path / "model.zip").stat().st_size > 0
    rows = list(csv.DictReader((tmp_path / "progress.csv").open()))
    assert len(rows) >= 2 and int(rows[-1]["steps"]) == summary["train_steps"]
    assert (tmp_path / "curve.png").read_bytes()[:4] == b"\x89PNG"


def test_wilson_interval():
    train = _load()
    lo, hi = train.wilson(95, 100)
    assert lo == pytest.approx(0.888, abs=1e-3) and hi == pytest.approx(0.978, abs=1e-3)
    assert train.wilson(0, 0) == (0.0, 1.0)
    flat = train.flatten({k: np.zeros((2, 3)) for k in train.OBS_KEYS})
    assert flat.shape == (2, 9) and flat.dtype == np.float32


def test_ppo_smoke_run_with_its_worlds_on_ray(tmp_path):
    """The recipe's rollouts past one machine: --ray steps the worlds on Ray actors (a local
    Ray here, two worlds on up to two workers)."""
    pytest.importorskip("ray")
    train = _load()
    assert train.main(["--task", "reach", "--smoke", "--ray", "local", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "eval.json").read_text())
    assert summary["train_steps"] >= 256 and summary["ray_workers"] >= 1
    import ray

    assert not ray.is_initialized()  # closing the environment stopped the Ray it started


def test_pick_recipe_starts_top_down_and_sees_the_cube_from_between_the_jaws():
    """The PickCube recipe's start pose points the tool straight down (its held pitch), and the
    features it adds are the tip and the cube less the point between the jaws, as the
    environment's own ``grip_centre`` puts it."""
    from so101sim.envs import make

    train = _load()
    env = make("pick_cube", **train.ENV_KWARGS["pick_cube"]).unwrapped
    try:
        obs, _ = env.reset(seed=3)
        assert env.actions._pitch == pytest.approx(-90.0, abs=0.5)
        flat = train.flatten({k: obs[k][None] for k in train.OBS_KEYS}, "pick_cube")
        assert flat.shape == (1, 6 + 6 + 7 + 6)
        tip = env.sim.data.site_xpos[env._tip_site]
        cube = env.object_pose("cube")[:3]
        assert np.allclose(flat[0, -6:-3], tip, atol=1e-4)
        assert np.allclose(flat[0, -3:], cube - env.grip_centre(), atol=1e-4)
    finally:
        env.close()
