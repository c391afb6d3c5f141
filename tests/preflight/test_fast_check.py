"""``so101sim check`` steps whole blocks in C and derives its figures from what C recorded
(issue 30): the same verdicts and figures, bit for bit, as watching every physics step."""

from __future__ import annotations

import pytest
from preflight_helpers import floor_motion

from so101sim.model import load_model
from so101sim.motion import Move
from so101sim.motion.file import lab_motion_path, load_motion
from so101sim.preflight import check_motion_file, preflight
from so101sim.preflight import measure as measure_module
from so101sim.units import STARTING_POSE


def _both(monkeypatch, run):
    """``run()`` as the check runs it now, then watched after every step (the step recorder)."""
    from so101sim.sim import stepping

    calls = []
    real = stepping.step_block
    monkeypatch.setattr(stepping, "step_block", lambda *a, **k: calls.append(1) or real(*a, **k))
    fast = run()
    blocks = len(calls)
    monkeypatch.setattr(measure_module, "derivable", lambda m: False)
    calls.clear()
    slow = run()
    return fast, blocks, slow, len(calls)


@pytest.mark.parametrize("arm", [None, "official"])
def test_the_lab_motion_gets_the_same_report_stepped_in_blocks(monkeypatch, arm):
    m = load_model(arm=arm)
    motion = load_motion(lab_motion_path(), model=m)

    def run():
        return preflight(motion.steps, start=motion.start, model=m, lines=motion.lines)

    fast, blocks, slow, per_step = _both(monkeypatch, run)
    assert fast == slow  # every figure, verdict and finding, bit for bit
    assert fast.passed
    assert blocks <= 3 * len(motion.steps) and per_step >= 3000  # 3000 physics steps


def test_a_motion_into_the_floor_gets_the_same_contacts_stepped_in_blocks(monkeypatch, tmp_path):
    path = floor_motion(tmp_path, tip_line=True)
    fast, blocks, slow, per_step = _both(monkeypatch, lambda: check_motion_file(path))
    assert fast == slow
    assert not fast.passed
    contacts = [c for s in fast.steps for c in s.contacts]
    assert any("floor" in (c.body1, c.body2) for c in contacts)
    assert fast.steps[2].line_deviation_mm is not None  # the tip line measured too
    assert blocks < 20 < per_step


def test_a_long_tip_line_is_checked_in_blocks(monkeypatch):
    m = load_model()
    steps = [Move.to_tip((0.22, 0.05, 0.08), 20.0, pitch=-60)]
    fast, blocks, slow, _ = _both(
        monkeypatch, lambda: preflight(steps, start=STARTING_POSE, model=m)
    )
    assert fast == slow and fast.passed
    assert blocks <= 3  # 10,000 steps in blocks of 4096


def test_check_plans_a_files_tip_line_once(monkeypatch, tmp_path):
    import so101sim.kinematics as kinematics

    path = tmp_path / "tip.toml"
    path.write_text("[[steps]]\nmove = { tip = [0.20, 0.0, 0.05], pitch = -90 }\nduration = 0.5\n")
    calls = []
    real = kinematics.plan_line
    monkeypatch.setattr(kinematics, "plan_line", lambda *a, **k: calls.append(1) or real(*a, **k))
    report = check_motion_file(path)
    assert len(calls) == 1  # by the loader; the check reuses it (MotionFile.tip_plans)
    assert report.steps[0].line_deviation_mm is not None
