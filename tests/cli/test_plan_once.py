"""`so101sim run FILE` plans a motion once: the loader's tip-move plan is the run's, the
video's framing and the run use the same plan, and nothing wraps (m, d) back (issue 21.3)."""

from __future__ import annotations

import numpy as np
import pytest

TIP_MOVE = """
[[steps]]
move = { tip = [0.20, 0.0, 0.05], pitch = -90 }
duration = 0.5
"""


@pytest.fixture
def counted(monkeypatch):
    import so101sim.kinematics as kinematics
    from so101sim.sim.simulation import Simulation

    calls = {"plan_line": 0, "attach": 0}
    real_line, real_attach = kinematics.plan_line, Simulation.attach.__func__

    def plan_line(*args, **kwargs):
        calls["plan_line"] += 1
        return real_line(*args, **kwargs)

    def attach(cls, *args, **kwargs):
        calls["attach"] += 1
        return real_attach(cls, *args, **kwargs)

    monkeypatch.setattr(kinematics, "plan_line", plan_line)
    monkeypatch.setattr(Simulation, "attach", classmethod(attach))
    return calls


def test_a_headless_run_plans_its_tip_move_once(tmp_path, counted):
    from so101sim.cli.main import main

    path = tmp_path / "tip.toml"
    path.write_text(TIP_MOVE)
    assert main(["run", str(path), "--headless"]) == 0
    assert counted == {"plan_line": 1, "attach": 0}


@pytest.mark.slow
def test_a_recorded_run_plans_its_tip_move_once(tmp_path, counted):
    from so101sim.cli.main import main

    path = tmp_path / "tip.toml"
    path.write_text(TIP_MOVE)
    video = tmp_path / "tip.mp4"
    args = ["run", str(path), "--headless", "--record", str(video), "--width", "160"]
    assert main([*args, "--height", "120"]) == 0
    assert video.stat().st_size > 0
    assert counted == {"plan_line": 1, "attach": 0}


def test_the_run_commands_what_the_plan_says(tmp_path):
    from so101sim.cli.runplan import prepare_run
    from so101sim.motion.file import load_motion

    path = tmp_path / "tip.toml"
    path.write_text(TIP_MOVE + "\n[[steps]]\nhold = 0.2\n")
    motion = load_motion(path)
    run = prepare_run(motion.steps, start=motion.start, headless=True)
    _, planned = run.plan.path()
    result = run.execute()
    ran = np.vstack([s.commanded for s in result.segments])
    assert len(ran) == len(planned) == 350
    assert np.allclose(ran, planned, atol=1e-9)


def test_a_plan_refuses_another_start():
    from so101sim import Simulation
    from so101sim.errors import SettingError
    from so101sim.motion import Hold
    from so101sim.motion.plan import plan_segments, run_plan
    from so101sim.units import ZERO_POSE

    sim = Simulation()
    plan = plan_segments(sim.model, [Hold(0.1)], ZERO_POSE)
    with pytest.raises(SettingError, match="another commanded pose"):
        run_plan(sim, plan)
