"""The expert's episodes as Ray tasks (issue 33, "past one machine"): the same episodes as in
this process, seed for seed, on a local Ray cluster of two workers; a cluster that does not
answer is one error line."""

from __future__ import annotations

import numpy as np
import pytest

from so101sim.envs import expert_frames, expert_frames_on_ray
from so101sim.errors import SettingError

KWARGS = {"fps": 30, "cameras": ("wrist",), "image_size": (32, 32), "randomize": "light"}


@pytest.mark.slow
def test_episodes_on_a_local_ray_with_two_workers_equal_the_local_ones() -> None:
    pytest.importorskip("ray")
    seeds = [5, 6]  # one episode a worker
    remote = list(expert_frames_on_ray("pick_cube", seeds, address="local", workers=2, **KWARGS))
    import ray

    assert not ray.is_initialized()  # the cluster it started is shut down
    assert [f.seed for f in remote] == seeds
    for got in remote:
        want = expert_frames("pick_cube", got.seed, **KWARGS)
        assert got.success == want.success and got.success_frame == want.success_frame
        np.testing.assert_array_equal(got.actions, want.actions)
        np.testing.assert_array_equal(got.states, want.states)
        np.testing.assert_array_equal(got.images["wrist"], want.images["wrist"])
        assert got.randomization == want.randomization


def test_a_ray_address_that_does_not_answer_is_one_error() -> None:
    pytest.importorskip("ray")
    with pytest.raises(SettingError, match="not an address"):
        next(expert_frames_on_ray("pick_cube", [1], address="nowhere"))
    with pytest.raises(SettingError, match=r"no Ray cluster reached at 127\.0\.0\.1:9"):
        next(expert_frames_on_ray("pick_cube", [1], address="127.0.0.1:9"))
