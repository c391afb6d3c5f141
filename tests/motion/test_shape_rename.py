"""A move's shape is ``shape`` (issue 30: "profile" also names the arm profile); the old name
``profile`` still works for one release: a DeprecationWarning in Python, one logged warning
per motion file."""

import dataclasses
import logging
import warnings

import mujoco
import numpy as np
import pytest

from so101sim import load_model
from so101sim.errors import MotionFileError, SettingError
from so101sim.motion import Move
from so101sim.motion import move as move_md
from so101sim.motion import plan_move as plan_move_md
from so101sim.motion.file import parse_motion
from so101sim.units import STARTING_POSE, ZERO_POSE

NEW = """shape = "minimum_jerk"
[[steps]]
move = "zero"
duration = 1.0
shape = "limited"
[[steps]]
gripper = 40
duration = 0.5
[[steps]]
move = "rest"
duration = 1.0
shape = "linear"
"""


def test_move_takes_shape_and_no_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = Move(ZERO_POSE, 1.0, shape="minimum_jerk")
        assert m.shape == "minimum_jerk"
        assert Move(ZERO_POSE, 1.0).shape == "linear"
        assert Move(ZERO_POSE, 1.0, "limited").shape == "limited"  # third positional
        assert Move.to_tip((0.2, 0.0, 0.1), 1.0, shape="minimum_jerk").shape == "minimum_jerk"
        assert dataclasses.replace(m, shape="limited").shape == "limited"


def test_the_old_profile_name_warns_once_and_means_shape():
    with pytest.warns(DeprecationWarning, match="use shape") as caught:
        old = Move(ZERO_POSE, 1.0, profile="limited", phase="a")
    assert len(caught) == 1 and caught[0].filename == __file__  # points at the caller
    assert old == Move(ZERO_POSE, 1.0, shape="limited", phase="a")
    with pytest.warns(DeprecationWarning, match="use shape"):
        assert old.profile == "limited"
    with pytest.warns(DeprecationWarning, match="use shape") as caught:
        replaced = dataclasses.replace(Move(ZERO_POSE, 1.0), profile="minimum_jerk")
    assert replaced.shape == "minimum_jerk" and caught[0].filename == __file__
    with pytest.warns(DeprecationWarning, match="use shape"):
        tip = Move.to_tip((0.2, 0.0, 0.1), 1.0, profile="minimum_jerk")
    assert tip.shape == "minimum_jerk"


def test_the_md_functions_take_shape_and_the_old_keyword_warns():
    m = load_model()
    d = mujoco.MjData(m)
    _, new = plan_move_md(m, d, ZERO_POSE, 0.2, shape="minimum_jerk")
    with pytest.warns(DeprecationWarning, match="use shape="):
        _, old = plan_move_md(m, d, ZERO_POSE, 0.2, profile="minimum_jerk")
    np.testing.assert_array_equal(old, new)
    _, lin = plan_move_md(m, d, ZERO_POSE, 0.2)
    assert not np.array_equal(lin, new)  # the shape changed the targets
    with pytest.raises(SettingError, match="shape= only"):
        plan_move_md(m, d, ZERO_POSE, 0.2, shape="linear", profile="linear")
    with pytest.warns(DeprecationWarning, match="use shape="):
        r = move_md(m, d, STARTING_POSE, 0.1, profile="linear")
    assert r.completed


def test_a_file_with_shape_keys_logs_nothing(caplog):
    with caplog.at_level(logging.WARNING):
        mf = parse_motion(NEW, path="new.toml")
    assert [s.shape for s in mf.steps] == ["limited", "minimum_jerk", "linear"]
    assert not [r for r in caplog.records if "profile" in r.getMessage()]


def test_a_file_with_the_old_key_loads_the_same_with_one_warning(caplog):
    old = NEW.replace("shape =", "profile =")
    with caplog.at_level(logging.WARNING):
        mf = parse_motion(old, path="old.toml")
    assert mf.steps == parse_motion(NEW, path="new.toml").steps
    said = [r.getMessage() for r in caplog.records if "'profile'" in r.getMessage()]
    assert len(said) == 1, said
    assert "old.toml" in said[0] and "line 1, 5, 12" in said[0] and "'shape'" in said[0]


def test_shape_and_profile_in_one_step_is_an_error_at_its_line():
    text = '[[steps]]\nmove = "zero"\nduration = 1.0\nshape = "linear"\nprofile = "limited"\n'
    with pytest.raises(MotionFileError, match="both shape and profile") as err:
        parse_motion(text, path="both.toml")
    assert err.value.line == 5


@pytest.mark.parametrize("key", ["shape", "profile"])
def test_a_limited_line_is_refused_at_its_shape_key(key):
    text = (
        "[[steps]]\nmove = { tip = [0.2, 0.0, 0.1], pitch = -60 }\n"
        f'duration = 1.0\n{key} = "limited"\n'
    )
    with pytest.raises(MotionFileError) as err:
        parse_motion(text, path="tip.toml")
    assert err.value.line == 4
