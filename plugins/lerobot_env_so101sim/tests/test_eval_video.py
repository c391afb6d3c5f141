"""The failure video's frame: the front view with the policy's own camera images beside it."""

from __future__ import annotations

import numpy as np
from lerobot_env_so101sim.evaluate import _SeenImages, side_by_side


def test_the_policys_images_are_scaled_to_the_front_views_height_pixel_for_pixel():
    front = np.zeros((480, 640, 3), np.uint8)
    wrist = np.arange(120 * 160 * 3, dtype=np.uint32).reshape(120, 160, 3).astype(np.uint8)
    frame = side_by_side(front, {"front": np.full((120, 160, 3), 7, np.uint8), "wrist": wrist})
    assert frame.shape == (480, 640 + 640 + 640, 3)
    assert (frame[:, 640:1280] == 7).all()
    right = frame[:, 1280:]
    np.testing.assert_array_equal(right[::4, ::4], wrist)  # each pixel a 4x4 block
    np.testing.assert_array_equal(right[3::4, 3::4], wrist)
    assert side_by_side(front, {}).shape == front.shape  # a state policy: the front view only


def test_the_seen_images_are_the_last_observations():
    class Vec:
        num_envs = 1

        def reset(self, **kwargs):
            return {"pixels": {"wrist": np.ones((1, 4, 6, 3), np.uint8)}}, {}

        def step(self, action):
            obs = {"pixels": {"wrist": np.full((1, 4, 6, 3), 2, np.uint8)}}
            return obs, 0.0, False, False, {}

    seen = _SeenImages(Vec())
    assert seen.num_envs == 1 and seen.pixels == {}
    seen.reset(seed=[0])
    assert seen.pixels["wrist"].shape == (4, 6, 3) and seen.pixels["wrist"].max() == 1
    seen.step(None)
    assert seen.pixels["wrist"].min() == 2
