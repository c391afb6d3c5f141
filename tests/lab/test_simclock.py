import time

import mujoco
import pytest

from so101sim.lab.simclock import SimClock, simulated_time
from so101sim.model import load_model


@pytest.fixture
def md():
    m = load_model()
    return m, mujoco.MjData(m)


def test_a_wall_clock_loop_runs_exactly_the_simulated_time_it_asks_for(md):
    m, d = md
    clock = SimClock()
    clock.follow(d)
    with simulated_time(clock):
        start = time.time()
        steps = 0
        while time.time() - start < 2.0:  # the handout's loop
            mujoco.mj_step(m, d)
            steps += 1
    assert steps in (1000, 1001)  # 2 s of simulated time, whatever the machine's speed
    assert d.time == pytest.approx(steps * m.opt.timestep)


def test_sleeping_to_keep_pace_is_not_counted_twice(md):
    m, d = md
    clock = SimClock()
    clock.follow(d)
    with simulated_time(clock):
        start = time.perf_counter()
        steps = 0
        while time.perf_counter() - start < 1.0:
            mujoco.mj_step(m, d)
            steps += 1
            time.sleep(m.opt.timestep)  # a pacing sleep, as scripts do
        assert time.monotonic() > 0
    assert 499 <= steps <= 501  # each step+sleep moves the clock one step, not two


def test_a_script_that_only_sleeps_does_not_hang_and_the_clock_never_goes_back(md):
    m, d = md
    clock = SimClock()
    with simulated_time(clock):
        t0 = time.time()
        for _ in range(100):
            time.sleep(0.1)
        assert time.time() - t0 == pytest.approx(10.0)
        clock.follow(d)
        mujoco.mj_step(m, d)
        t1 = time.time()
        mujoco.mj_resetData(m, d)  # simulated time goes back to 0
        assert time.time() >= t1
        assert time.time_ns() >= int(t1 * 1e9) - 1000
    assert time.time() != pytest.approx(t0 + 10.0, abs=1.0)  # the real clock is back


def test_negative_sleep_is_refused_as_python_does():
    with pytest.raises(ValueError):
        SimClock().sleep(-1)
