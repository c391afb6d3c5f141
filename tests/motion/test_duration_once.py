"""A move's duration is checked once (issue 30): the motion planner checks each segment's
duration and hands its step count on, so ``Simulation.plan_move``/``plan_tip_move`` do not check
it again; a move asked of the simulation directly is still checked there, with the same
messages as before."""

from __future__ import annotations

import pytest

import so101sim.sim.profiles as profiles
from so101sim import load_model
from so101sim.errors import DurationError
from so101sim.motion import Hold, Move
from so101sim.motion.plan import plan_segments
from so101sim.sim.simulation import Simulation
from so101sim.units import STARTING_POSE, ZERO_POSE

STEPS = [
    Move(ZERO_POSE, 0.4, phase="joint"),
    Hold(0.1, phase="rest"),
    Move.to_tip((0.22, 0.0, 0.12), 0.3, pitch=-60, phase="line"),
    Move.to_tip((0.2, 0.05, 0.1), 1.0, pitch=-60, path="joint", shape="limited", phase="ik"),
    Move(STARTING_POSE, 0.5, shape="minimum_jerk", phase="back"),
]


@pytest.fixture
def checks(monkeypatch):
    """The phases whose duration steps_for checked (every duration check of a plan goes
    through it)."""
    seen: list[str] = []
    real = profiles.check_duration

    def counting(value, what, **kw):
        seen.append(what)
        return real(value, what, **kw)

    monkeypatch.setattr(profiles, "check_duration", counting)
    return seen


def test_the_planner_checks_each_duration_once(checks):
    plan = plan_segments(load_model(), STEPS, STARTING_POSE)
    assert [p.steps for p in plan.segments] == [200, 50, 150, 500, 250]
    assert checks == [f"{s.phase} duration" for s in STEPS]  # one each, in order


def test_a_move_asked_of_the_simulation_is_checked_there_once(checks):
    sim = Simulation()
    sim.plan_move(ZERO_POSE, 0.2)
    sim.plan_tip_move((0.22, 0.0, 0.12), 0.2, pitch=-60)
    assert checks == ["duration", "duration"]


@pytest.mark.parametrize(
    ("duration", "message"),
    [(0.0, "expected a finite number of seconds > 0"), (4000.0, "at most 3600 s"),
     (float("nan"), "finite"), ("2", "not a number")],
)  # fmt: skip
def test_the_messages_are_the_same_from_the_planner_and_the_simulation(duration, message):
    with pytest.raises(DurationError, match=message) as planned:
        plan_segments(load_model(), [Move(ZERO_POSE, duration, phase="to_zero")], STARTING_POSE)
    assert "to_zero duration" in str(planned.value)
    with pytest.raises(DurationError, match=message):
        Simulation().plan_move(ZERO_POSE, duration)
    with pytest.raises(DurationError, match=message):
        Simulation().plan_tip_move((0.22, 0.0, 0.12), duration, pitch=-60)
