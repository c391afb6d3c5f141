"""One motion planner and checker (issue 30, point 2): plan_segments checks every segment,
the strict servo limits included, from the start it plans for each; the run, ``--strict``,
the preflight and the robust preflight all ask it, so they say the same number."""

from __future__ import annotations

import logging
import re

import numpy as np
import pytest

from so101sim.cli.runplan import check_strict, prepare_run
from so101sim.errors import DurationError, TrajectoryLimitError
from so101sim.model import arm_units, load_model
from so101sim.motion import Hold, Move
from so101sim.motion.plan import plan_segments
from so101sim.preflight import preflight
from so101sim.preflight.rollout import plan_motion
from so101sim.sim.limited import LimitedProfile, minimum_steps
from so101sim.units import STARTING_POSE, ZERO_POSE

# the case: a tip move, then a 0.05 s `limited` move (its start: where the tip move ends)
TIP_THEN_LIMITED = [
    Move.to_tip((0.22, 0.0, 0.08), 1.0, pitch=-60),
    Move(ZERO_POSE, 0.05, shape="limited", phase="snap"),
]


def _needed_in(text: str) -> float:
    found = re.findall(r"(?:at least|stretching it to) (\d+\.\d{3}) s", text)
    assert found, text
    return float(found[0])


def test_a_limited_move_after_a_tip_move_is_checked_from_where_the_tip_move_ends(caplog):
    model = load_model()
    start = STARTING_POSE
    with caplog.at_level(logging.WARNING, logger="so101sim"):
        plan = plan_segments(model, TIP_THEN_LIMITED, start)
    [short] = plan.stretched
    assert (short.index, short.phase) == (1, "snap")
    # the figure is the limits' own, from the tip move's planned end (not the rest pose)
    tip_end = plan.segments[0].end
    goal = plan.segments[1].end
    dt = model.opt.timestep
    t_min = LimitedProfile(units=arm_units(model)).minimum_duration(tip_end, goal)
    assert short.needed == pytest.approx(minimum_steps(t_min, dt) * dt)
    assert plan.segments[1].steps * dt == pytest.approx(short.needed)  # stretched to it
    stretched_by_planner = _needed_in(caplog.text)

    with pytest.raises(TrajectoryLimitError) as strict:
        check_strict(model, TIP_THEN_LIMITED, start)
    with pytest.raises(TrajectoryLimitError) as run:
        prepare_run(TIP_THEN_LIMITED, start=start, model=model, headless=True, strict=True)
    with pytest.raises(TrajectoryLimitError) as check:
        preflight(TIP_THEN_LIMITED, start=start, model=model, strict=True)
    with pytest.raises(TrajectoryLimitError) as robust:
        plan_motion(model, TIP_THEN_LIMITED, start, strict=True)
    said = {_needed_in(str(e.value)) for e in (strict, run, check, robust)}
    assert said == {stretched_by_planner} == {round(short.needed, 3)}
    assert "step 2 (snap)" in str(strict.value)
    # and the non-strict preflight notes the same stretch
    report = preflight(TIP_THEN_LIMITED, start=start, model=model)
    assert any(f"to {short.needed:.3f} s" in n for n in report.notes)


def test_strict_names_the_first_short_move_after_checking_them_all():
    model = load_model()
    steps = [
        Move(ZERO_POSE, 0.05, shape="limited", phase="a"),
        Hold(0.1),
        Move(STARTING_POSE, 0.05, shape="limited", phase="b"),
    ]
    assert [s.phase for s in plan_segments(model, steps, STARTING_POSE).stretched] == ["a", "b"]
    with pytest.raises(TrajectoryLimitError, match=r"step 1 \(a\).*2 move\(s\) too short"):
        plan_segments(model, steps, STARTING_POSE, strict=True)


def test_each_duration_is_checked_by_the_planner_with_its_phase():
    model = load_model()
    with pytest.raises(DurationError, match="settle duration"):
        plan_segments(model, [Hold(-1.0, phase="settle")], STARTING_POSE)
    with pytest.raises(DurationError, match="one day"):
        plan_segments(model, [Hold(80_000.0), Hold(80_000.0)], STARTING_POSE)


def test_validate_segments_is_deprecated_for_the_planner():
    from so101sim.motion import validate_segments

    model = load_model()
    with pytest.warns(DeprecationWarning, match="plan_segments"):
        validate_segments(model, [Move(ZERO_POSE, 1.0)])
    with pytest.warns(DeprecationWarning), pytest.raises(DurationError):
        validate_segments(model, [Move(ZERO_POSE, 0.0)])
    assert np.isfinite(plan_segments(model, [Move(ZERO_POSE, 1.0)], STARTING_POSE).duration)


TIP_THEN_LIMITED_FILE = """\
[[steps]]
move = { tip = [0.22, 0.0, 0.08], pitch = -60 }
duration = 1.0
[[steps]]
move = "zero"
duration = 0.05
shape = "limited"
name = "snap"
"""


def test_run_strict_check_strict_and_a_plain_check_say_the_same_number(tmp_path, capsys):
    from so101sim import cli

    path = tmp_path / "snap.toml"
    path.write_text(TIP_THEN_LIMITED_FILE)
    assert cli.main(["run", "--headless", "--strict", str(path)]) == 2
    run_says = _needed_in(capsys.readouterr().err)
    assert cli.main(["check", "--strict", str(path)]) == 2
    check_says = _needed_in(capsys.readouterr().err)
    assert cli.main(["check", str(path)]) in (0, 1)
    stretched = re.findall(r"stretched from 0\.050 s to (\d+\.\d{3}) s", capsys.readouterr().out)
    assert run_says == check_says == float(stretched[0])


def test_a_limited_tip_move_in_joint_space_is_checked_too():
    model = load_model()
    steps = [Move.to_tip((0.22, 0.05, 0.08), 0.05, pitch=-60, path="joint", shape="limited")]
    [short] = plan_segments(model, steps, STARTING_POSE).stretched
    assert short.index == 0 and short.needed > 0.05
    with pytest.raises(TrajectoryLimitError, match=f"at least {short.needed:.3f} s"):
        plan_segments(model, steps, STARTING_POSE, strict=True)
    ok = [Move.to_tip((0.22, 0.05, 0.08), 3.0, pitch=-60, path="joint", shape="limited")]
    assert plan_segments(model, ok, STARTING_POSE, strict=True).stretched == ()
