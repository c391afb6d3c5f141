"""Tests of so101sim.recording.envelope: a bounded summary of a run's steps for plotting."""

from __future__ import annotations

import numpy as np
import pytest

from so101sim.recording.envelope import Envelope


def _feed(env: Envelope, values: np.ndarray, rng: np.random.Generator) -> Envelope:
    """Add ``values`` (n, channels, joints) in blocks of random sizes, as stepping sends them."""
    times = 0.002 * np.arange(1, len(values) + 1)
    i = 0
    while i < len(values):
        k = int(rng.integers(1, 4097))
        env = env.add(times[i : i + k], values[i : i + k])
        i += k
    return env


def test_a_short_run_is_kept_step_by_step():
    rng = np.random.default_rng(0)
    values = rng.normal(size=(777, 3, 6))
    env = _feed(Envelope.empty(3, 6, max_buckets=1000), values, rng)
    times, points = env.points()
    assert env.width == 1 and env.steps == 777
    np.testing.assert_array_equal(points, values)
    np.testing.assert_allclose(times, 0.002 * np.arange(1, 778))


@pytest.mark.parametrize("n", [1001, 65_537, 1_000_003])
def test_a_long_run_keeps_at_most_the_bound_and_every_extreme(n):
    rng = np.random.default_rng(n)
    values = rng.normal(size=(n, 3, 6))
    spike = int(rng.integers(n))
    values[spike, 1, 4] = 1e6  # one step's spike of one joint
    values[n // 3, 0, 0] = -1e6
    env = _feed(Envelope.empty(3, 6, max_buckets=1000), values, rng)
    times, points = env.points()
    assert env.steps == n
    assert len(times) <= 2 * (1000 + 1)  # buckets, plus the unfinished one
    assert np.all(np.diff(times) >= 0)
    np.testing.assert_array_equal(points.max(axis=0), values.max(axis=0))
    np.testing.assert_array_equal(points.min(axis=0), values.min(axis=0))
    assert times[np.argmax(points[:, 1, 4])] == pytest.approx(
        0.002 * (spike + 1), abs=env.width * 0.002
    )


def test_an_envelope_is_never_changed_by_adding_to_it():
    rng = np.random.default_rng(1)
    env = _feed(Envelope.empty(3, 6, max_buckets=8), rng.normal(size=(37, 3, 6)), rng)
    before = [a.copy() for a in env.points()]
    env.add(np.full(100, 9.0), np.full((100, 3, 6), 99.0))  # the result is dropped
    after = env.points()
    for a, b in zip(before, after, strict=True):
        np.testing.assert_array_equal(a, b)
