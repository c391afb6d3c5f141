"""Choice parameters are typed with ``Literal`` (issue 30), and each Literal names exactly the
choices the code accepts at run time (one list, checked here)."""

from __future__ import annotations

import inspect
from typing import get_args, get_type_hints

import pytest

from so101sim.envs.actions import CONTROL_MODES, ControlMode, ControlSettings
from so101sim.envs.base import RENDER_MODES, REWARD_MODES, RenderMode, RewardMode, So101TaskEnv
from so101sim.envs.vector import BACKENDS, Backend, make_vec
from so101sim.errors import RobotConfigError, SettingError
from so101sim.motion.tip import PATHS
from so101sim.recording.framing import NAMED_VIEWS, ViewName, view_direction, view_for_run
from so101sim.recording.settings import QUALITY_CHOICES, Quality, QualityChoice, VideoSettings
from so101sim.robot.config import MODES, RobotMode, SO101SimFollowerConfig
from so101sim.scenes.objects import (
    CONES,
    SHAPES,
    SURFACES,
    Cone,
    ContactSettings,
    ObjectShape,
    SceneObject,
    Surface,
    Table,
)
from so101sim.sim.moveplan import ShapeName, TipPath
from so101sim.sim.profiles import PROFILES
from so101sim.sim.results import SegmentKind, SegmentResult
from so101sim.sim.simulation import Simulation
from so101sim.viewer.passive import VIEWER_QUALITIES, ViewerQuality, open_viewer


def test_each_literal_is_the_list_the_code_checks():
    assert set(get_args(ShapeName)) == set(PROFILES)
    assert set(get_args(TipPath)) == set(PATHS)
    assert set(get_args(ViewName)) == set(NAMED_VIEWS)
    assert get_args(QualityChoice) == QUALITY_CHOICES == ("auto", *get_args(Quality))
    assert get_args(ViewerQuality) == VIEWER_QUALITIES
    assert set(get_args(SegmentKind)) == {"move", "hold", "step"}


def test_public_choice_parameters_carry_their_literal():
    move_to = inspect.signature(Simulation.move_to).parameters
    assert "TipPath" in str(move_to["path"].annotation)
    assert "Shape" in str(move_to["shape"].annotation)
    assert "ViewerQuality" in str(inspect.signature(open_viewer).parameters["quality"].annotation)
    assert "ViewName" in str(inspect.signature(view_for_run).parameters["view"].annotation)
    assert "ViewName" in str(inspect.signature(view_direction).parameters["name"].annotation)
    hints = get_type_hints(VideoSettings)
    assert hints["quality"] == QualityChoice and hints["view"] == ViewName
    assert get_type_hints(SegmentResult)["kind"] == SegmentKind


def test_the_apps_and_scenes_choices_are_literals_their_checks_use():
    assert MODES == get_args(RobotMode) == ("realtime", "lockstep")
    assert RENDER_MODES == get_args(RenderMode) == ("human", "rgb_array")
    assert REWARD_MODES == get_args(RewardMode) == ("dense", "sparse")
    assert get_args(ControlMode) == CONTROL_MODES
    assert get_args(Backend) == BACKENDS
    assert get_args(ObjectShape) == SHAPES and "open_box" in SHAPES
    assert get_args(Surface) == SURFACES and get_args(Cone) == CONES
    robot = get_type_hints(SO101SimFollowerConfig)
    assert robot["mode"] == RobotMode and robot["viewer_quality"] == ViewerQuality
    env = inspect.signature(So101TaskEnv.__init__).parameters
    assert "RenderMode" in str(env["render_mode"].annotation)
    assert env["reward"].annotation == "RewardMode" and env["control"].annotation == "ControlMode"
    assert "Backend" in str(inspect.signature(make_vec).parameters["backend"].annotation)
    assert get_type_hints(SceneObject)["shape"] == ObjectShape
    assert get_type_hints(Table)["surface"] == Surface
    assert get_type_hints(ContactSettings)["cone"] == Cone
    assert get_type_hints(ControlSettings)["mode"] == ControlMode


def test_a_choice_outside_the_literal_is_refused_naming_the_literals_values():
    with pytest.raises(RobotConfigError, match="realtime, lockstep"):
        SO101SimFollowerConfig(mode="fast")
    with pytest.raises(SettingError, match="box, cylinder, sphere, bowl, open_box"):
        SceneObject("cube", shape="cone").validated()
    with pytest.raises(SettingError, match="table, floor"):
        Table(surface="sand").validated()
    with pytest.raises(SettingError, match="dense, sparse"):
        So101TaskEnv(reward="shaped")
    with pytest.raises(SettingError, match="human, rgb_array"):
        So101TaskEnv(render_mode="window")
