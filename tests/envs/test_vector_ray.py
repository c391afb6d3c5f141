"""``make_vec(..., backend="ray")`` (issue 33, "past one machine"): the worlds split over Ray
actors give the same observations, rewards, ends and ``info`` as ``make_vec`` in this process,
bit for bit, auto-resets included; tested on a local Ray of two workers."""

from __future__ import annotations

import numpy as np
import pytest

from so101sim.envs import make_vec
from so101sim.envs.rayvec import merge_infos, split
from so101sim.errors import SettingError

KWARGS = {"episode_seconds": 0.6, "randomize": "light"}  # 15 steps: episodes end and restart


def test_split_gives_nearly_equal_shares_in_order() -> None:
    assert split(5, 2) == [(0, 3), (3, 5)]
    assert split(4, 4) == [(0, 1), (1, 2), (2, 3), (3, 4)]


def test_merge_infos_masks_a_key_a_share_lacks() -> None:
    a = {"x": np.array([1.0, 2.0]), "_x": np.array([True, True])}
    b = {
        "final_info": {"y": np.array([3]), "_y": np.array([True])},
        "_final_info": np.array([True]),
    }
    out = merge_infos([a, b], [2, 1])
    np.testing.assert_array_equal(out["x"], [1.0, 2.0, 0.0])
    np.testing.assert_array_equal(out["_x"], [True, True, False])
    np.testing.assert_array_equal(out["final_info"]["y"], [0, 0, 3])
    np.testing.assert_array_equal(out["_final_info"], [False, False, True])


def _same(a, b, what: str) -> None:
    if isinstance(a, dict):
        assert set(a) == set(b), what
        for k in a:
            _same(a[k], b[k], f"{what}.{k}")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert len(a) == len(b), what
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"{what}[{i}]")
    else:
        np.testing.assert_array_equal(a, b, err_msg=what)


@pytest.mark.slow
def test_worlds_on_a_local_ray_with_two_workers_equal_make_vec() -> None:
    pytest.importorskip("ray")
    import ray

    local = make_vec("reach", 5, **KWARGS)
    remote = make_vec("reach", 5, backend="ray", address="local", workers=2, **KWARGS)
    try:
        assert remote.workers == 2
        assert remote.single_observation_space == local.single_observation_space
        obs_l, info_l = local.reset(seed=7)
        obs_r, info_r = remote.reset(seed=7)
        _same(obs_l, obs_r, "reset obs")
        _same(info_l, info_r, "reset info")
        rng = np.random.default_rng(0)
        ends = 0
        for t in range(20):
            action = rng.uniform(-1, 1, local.action_space.shape).astype(np.float32)
            got_l, got_r = local.step(action), remote.step(action)
            for k, name in enumerate(("obs", "reward", "terminated", "truncated", "info")):
                _same(got_l[k], got_r[k], f"step {t} {name}")
            ends += int(np.sum(got_l[2] | got_l[3]))
        assert ends >= 5  # every world's episode ended at least once: auto-reset compared too
        with pytest.raises(SettingError, match="one row per world"):
            remote.step(np.zeros((2, *local.single_action_space.shape)))
    finally:
        local.close()
        remote.close()
    assert not ray.is_initialized()  # the Ray it started is shut down


def test_a_ray_backend_refuses_rendering_and_a_bad_address() -> None:
    pytest.importorskip("ray")
    with pytest.raises(SettingError, match="render_mode"):
        make_vec("reach", 2, backend="ray", render_mode="rgb_array")
    with pytest.raises(SettingError, match="not an address"):
        make_vec("reach", 2, backend="ray", address="nowhere")
