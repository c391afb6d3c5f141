"""The pose finders' warnings: the tip or a part of the arm below the floor or in the table."""

from __future__ import annotations

import mujoco
import pytest

from so101sim import cli
from so101sim.model import arm_index
from so101sim.units import STARTING_POSE
from so101sim.viewer.clearance import pose_warnings, scene_geoms
from so101sim.viewer.posefinder import pose_scene, watch_poses

# the wrist folded down in front of the base: the tip 8 mm below z = 0 (worked out with
# so101sim.kinematics: tip_pose(LOW)), the gripper's jaws lower still
LOW = {**STARTING_POSE, "shoulder_lift": 30.0, "elbow_flex": 60.0, "wrist_flex": 60.0}


def _at(pose):
    m, d = pose_scene(None, pose)
    return m, d


def test_the_rest_pose_is_clear_of_the_floor():
    m, d = _at(STARTING_POSE)
    assert pose_warnings(m, d) == ()


def test_a_tip_below_the_floor_is_said_with_its_depth():
    from so101sim.kinematics import tip_pose

    m, d = _at(LOW)
    warnings = pose_warnings(m, d)
    tip_z = float(tip_pose(LOW).position[2])  # base frame: its origin is on the floor
    assert tip_z < -0.003
    assert f"the tip is {-tip_z * 1000:.0f} mm below the floor" in warnings
    assert any(w.startswith("gripper is ") and w.endswith("below the floor") for w in warnings)


def test_a_part_of_the_arm_in_the_floor_is_named_even_when_the_tip_is_clear():
    # the forearm swung down past the floor, the wrist turned up: the tip may be above
    pose = {**STARTING_POSE, "shoulder_lift": 100.0, "elbow_flex": 0.0, "wrist_flex": 0.0}
    m, d = _at(pose)
    warnings = pose_warnings(m, d)
    assert any(w.startswith("lower_arm is ") for w in warnings), warnings


def test_the_table_of_a_scene_counts_as_the_floor_does():
    from so101sim.scenes import build_model, preset_scene

    model = build_model(scene=preset_scene("pick_cube"))
    fixed, arm = scene_geoms(model)
    names = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in fixed}
    assert "table_top" in names and len(arm) >= 6
    m, d = pose_scene(model, LOW)
    warnings = pose_warnings(m, d)
    assert any(w.startswith("the tip is ") and "into the table top" in w for w in warnings)
    m, d = pose_scene(model, STARTING_POSE)
    assert pose_warnings(m, d) == ()


class _Sliders:
    """A viewer whose joint sliders are set to ``pose`` at the 5th sync (see test_posefinder)."""

    def __init__(self, m, d, pose, syncs=30):
        self.m, self.d, self.pose, self.syncs, self.calls = m, d, pose, syncs, 0

    def is_running(self):
        return self.calls < self.syncs

    def sync(self):
        self.calls += 1
        if self.calls == 5:
            from so101sim.model import arm_units

            u = arm_units(self.m)
            self.d.qpos[arm_index(self.m).qpos] = u.to_radians(u.pose_to_array(self.pose))

    def lock(self):
        import contextlib

        return contextlib.nullcontext()


def test_the_desktop_pose_finder_reports_the_warnings_with_the_pose():
    from so101sim.sim.simulation import Pacer

    t = [0.0]
    pacer = Pacer(clock=lambda: t[0], sleep=lambda s: t.__setitem__(0, t[0] + s))
    m, d = pose_scene()
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)  # a slider goes through
    changes = list(watch_poses(_Sliders(m, d, LOW), m, d, pacer=pacer))
    assert [c.number for c in changes] == [1, 2]
    assert changes[0].warnings == ()
    assert any("below the floor" in w for w in changes[1].warnings)


def test_cli_pose_prints_a_warning_line_under_a_pose_in_the_floor(monkeypatch):
    import builtins
    import time

    lines: list[str] = []
    original = builtins.print

    def keep(*args, **kwargs):
        lines.append(" ".join(map(str, args)))
        original(*args, **kwargs)

    def fake_managed_viewer(m, d):
        """MuJoCo's viewer: a person drags the sliders to LOW and leaves the arm there until
        the pose is printed (an event, with a generous deadline: a busy machine is slow)."""
        from so101sim.model import arm_units

        def wait_for(text: str) -> None:
            deadline = time.monotonic() + 120.0
            while time.monotonic() < deadline and not any(text in s for s in lines):
                time.sleep(0.05)

        wait_for("# pose 1")  # the start pose, reported first
        u = arm_units(m)
        d.qpos[arm_index(m).qpos] = u.to_radians(u.pose_to_array(LOW))
        wait_for("# pose 2")

    monkeypatch.setattr("builtins.print", keep)
    monkeypatch.setattr("so101sim.viewer.view", fake_managed_viewer)
    monkeypatch.setattr("so101sim.viewer.has_display", lambda: True)
    assert cli.main(["pose"]) == 0
    pose2 = next(s for s in lines if "# pose 2" in s)
    assert "\nwarning: the tip is " in pose2 and "below the floor" in pose2, pose2
    pose1 = next(s for s in lines if "# pose 1" in s)
    assert "warning:" not in pose1


@pytest.mark.parametrize("command", [["pose"], ["view"]])
def test_without_a_display_pose_and_view_suggest_web(monkeypatch, capsys, command):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    assert cli.main(command) == 2
    err = capsys.readouterr().err.strip()
    assert f"so101sim {command[0]} --web" in err and len(err.splitlines()) == 1


def test_the_warnings_quoted_in_the_docs_are_the_ones_given():
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "motions.md").read_text("utf-8")
    m, d = _at(LOW)
    block = "\n".join(f"warning: {w}" for w in pose_warnings(m, d))
    assert f"```\n{block}\n```" in doc
