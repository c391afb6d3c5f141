"""Motion files: the TOML schema, every loader error with its file and line, the lab file."""

from __future__ import annotations

import math
import os
import signal
import textwrap
from contextlib import contextmanager

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from so101sim import cli, lab
from so101sim.errors import MotionFileError, So101SimError
from so101sim.model import default_units, load_model
from so101sim.motion import LAB_MOTION, Hold, Move, run_motion
from so101sim.motion.file import lab_motion_path, load_motion, parse_motion
from so101sim.motion.lines import MAX_FILE_BYTES, KeyLines
from so101sim.sim.simulation import Simulation
from so101sim.units import (
    JOINT_NAMES,
    LIMIT_TOLERANCE,
    STARTING_POSE,
    ZERO_POSE,
    format_value,
)


def _parse(text: str):
    return parse_motion(textwrap.dedent(text), path="m.toml")


def _error(text: str) -> MotionFileError:
    with pytest.raises(MotionFileError) as exc:
        _parse(text)
    return exc.value


GOOD = """\
description = "test"
shape = "minimum_jerk"

[poses]
up = { shoulder_lift = 0, elbow_flex = 0 }

[poses.left]
shoulder_pan = 45
"wrist_roll.pos" = 10

[[steps]]
move = "up"
duration = 1.0

[[steps]]
hold = 0.5

[[steps]]
move = "left"
duration = 2.0
shape = "limited"
name = "turn"

[[steps]]
gripper = 40
duration = 0.5

[[steps]]
move = { wrist_flex = -20 }
duration = 1.0
"""


def test_a_motion_file_loads_into_full_pose_steps():
    mf = _parse(GOOD)
    assert mf.description == "test"
    assert mf.start == STARTING_POSE
    assert mf.poses["left"] == {"shoulder_pan": 45.0, "wrist_roll": 10.0}
    kinds = [type(s).__name__ for s in mf.steps]
    assert kinds == ["Move", "Hold", "Move", "Move", "Move"]
    up, _, left, grip, wrist = mf.steps
    # a partial pose moves only the joints it names; the others keep their last target
    assert up.target == {**STARTING_POSE, "shoulder_lift": 0.0, "elbow_flex": 0.0}
    assert left.target == {**up.target, "shoulder_pan": 45.0, "wrist_roll": 10.0}
    assert grip.target == {**left.target, "gripper": 40.0}
    assert wrist.target == {**grip.target, "wrist_flex": -20.0}
    assert up.shape == "minimum_jerk" and left.shape == "limited"
    assert [s.phase for s in mf.steps] == ["to_up", "hold", "turn", "gripper", "move"]
    assert mf.lines == (11, 15, 18, 24, 28)


def test_radians_are_converted_for_body_joints_only():
    mf = _parse(
        """\
        units = "rad"
        start = { shoulder_pan = 0, shoulder_lift = -1.5, elbow_flex = 1.5,
                  wrist_flex = 1, wrist_roll = 0, gripper = 10 }
        [[steps]]
        move = { shoulder_pan = 0.5, gripper = 50 }
        duration = 1
        """.replace(",\n                  ", ", ")
    )
    assert mf.start["shoulder_lift"] == pytest.approx(math.degrees(-1.5))
    assert mf.start["gripper"] == 10.0
    assert mf.steps[0].target["shoulder_pan"] == pytest.approx(math.degrees(0.5))
    assert mf.steps[0].target["gripper"] == 50.0


LIMIT = default_units().limits_dict()


@pytest.mark.parametrize(
    ("text", "line", "reason"),
    [
        ("[[steps]]\nhold = 1\nhold = 2\n", 3, "not valid TOML"),
        ("steps = [\n", 1, "end of the file"),
        ("[[steps]]\nhold = 1\nx = [\n\n", 4, "end of the file"),
        ("colour = 'red'\n[[steps]]\nhold = 1\n", 1, "unknown key 'colour'"),
        ("[[steps]]\nhold = 1\n\n[[steps]]\nhold = 1\nspeed = 3\n", 6, "unknown key 'speed'"),
        ("[[steps]]\nmove = 'zero'\nduration = 1\ncolour = 1\n", 4, "unknown key 'colour'"),
        ("[[steps]]\nhold = 1\n[[steps]]\nmove = 'wave'\nduration = 1\n", 4, "unknown pose 'wave'"),
        ("start = 'nowhere'\n[[steps]]\nhold = 1\n", 1, "unknown pose 'nowhere'"),
        ("[poses.a]\nshoulder_pan = 0\nelbo = 3\n[[steps]]\nhold = 1\n", 3, "unknown joint 'elbo'"),
        ("[poses]\na = { shoulder_pan = 0, knee = 3 }\n[[steps]]\nhold = 1\n", 2, "'knee'"),
        ("[[steps]]\nmove = { elbow = 1 }\nduration = 1\n", 2, "unknown joint 'elbow'"),
        ("units = 'grad'\n[[steps]]\nhold = 1\n", 1, "unknown units 'grad'"),
        ("[poses]\na = { shoulder_pan = 200 }\n[[steps]]\nhold = 1\n", 2, "outside the joint"),
        ("\n[poses.a]\ngripper = 101\n[[steps]]\nhold = 1\n", 3, "gripper = 101"),
        ("[[steps]]\ngripper = -5\nduration = 1\n", 2, "outside the joint"),
        ("[[steps]]\nmove = { elbow_flex = 'x' }\nduration = 1\n", 2, "not a number"),
        ("[[steps]]\nmove = { elbow_flex = nan }\nduration = 1\n", 2, "not finite"),
        ("[[steps]]\nmove = 'zero'\nduration = -1\n", 3, "expected a finite number of seconds"),
        ("[[steps]]\nmove = 'zero'\nduration = 0\n", 3, "expected a finite number of seconds"),
        ("[[steps]]\nhold = 1\n[[steps]]\nhold = 0\n", 4, "> 0"),
        ("[[steps]]\nhold = 'long'\n", 2, "not a number"),
        ("[[steps]]\nmove = 'zero'\n", 1, "needs a duration"),
        ("[[steps]]\nmove = 'zero'\nhold = 1\nduration = 1\n", 1, "exactly one of"),
        ("[[steps]]\nname = 'x'\n", 1, "exactly one of"),
        ("[[steps]]\nmove = 'zero'\nduration = 1\nshape = 'fast'\n", 4, "unknown shape"),
        ("shape = 'fast'\n[[steps]]\nhold = 1\n", 1, "unknown shape"),
        ("profile = 'fast'\n[[steps]]\nhold = 1\n", 1, "unknown profile"),  # the old key
        ("[poses]\nrest = { gripper = 5 }\n[[steps]]\nhold = 1\n", 2, "built in"),
        ("start = 1\n[poses]\nup = { shoulder_lift = 0 }\n", 1, "a pose must be a table"),
        ("[poses]\nup = { shoulder_lift = 0 }\nstart = 1\n[[steps]]\nhold = 1\n", 3, "table"),
        ("start = { gripper = 5 }\n[[steps]]\nhold = 1\n", 1, "missing shoulder_pan"),
        ("start = 'half'\n[poses]\nhalf = { gripper = 5 }\n[[steps]]\nhold = 1\n", 1, "six"),
        ("description = 'x'\n", 1, "at least one step"),
        ("poses.a.shoulder_pan = 0\nposes.a.elbow = 1\n[[steps]]\nhold = 1\n", 2, "'elbow'"),
        ("[poses.a]\nelbow_flex = 1\n'elbow_flex.pos' = 2\n[[steps]]\nhold = 1\n", 3, "twice"),
    ],
)
def test_every_loader_error_names_file_line_and_reason(text, line, reason):
    err = _error(text)
    assert err.path == "m.toml"
    assert err.line == line, str(err)
    assert reason in err.reason
    assert str(err).startswith(f"m.toml:{line}: ")
    assert isinstance(err, So101SimError)


def test_errors_in_the_nth_steps_table_point_at_that_table():
    text = "[[steps]]\nhold = 1\n" * 4 + "[[steps]]\nmove = 'zero'\nduration = 1\nspin = 1\n"
    assert _error(text).line == 12


def test_a_limit_error_gives_the_limits():
    err = _error("[[steps]]\nmove = { elbow_flex = 120 }\nduration = 1\n")
    lo, hi = LIMIT["elbow_flex"]
    assert f"{format_value('elbow_flex', lo)}..{format_value('elbow_flex', hi)}" in err.reason


def test_joint_values_are_checked_like_the_apis_poses():
    lo, hi = LIMIT["gripper"]
    # within the units' tolerance of a limit (a joint resting on its stop): the limit itself
    near = hi + 0.9 * LIMIT_TOLERANCE
    mf = _parse(f"[[steps]]\ngripper = {near!r}\nduration = 1\n")
    assert mf.steps[0].target["gripper"] == hi
    assert default_units().check_limits(np.array([0, 0, 0, 0, 0, near]))[5] == hi
    # past the tolerance: the units' error, at the value's line, without the API's clip advice
    far = hi + 2 * LIMIT_TOLERANCE
    err = _error(f"[[steps]]\nhold = 1\n[[steps]]\nduration = 1\ngripper = {far!r}\n")
    assert err.line == 5 and "outside the joint's limits" in err.reason
    assert "clip" not in err.reason
    closed = _parse(f"[poses]\nshut = {{ gripper = {lo - 0.1!r} }}\n[[steps]]\nhold = 1\n")
    assert closed.poses["shut"] == {"gripper": lo}


def test_loading_a_file(tmp_path):
    path = tmp_path / "wave.toml"
    path.write_text(GOOD)
    mf = load_motion(path)
    assert mf.path == str(path) and len(mf.steps) == 5
    path.write_text("[[steps]]\nhold = -1\n")
    with pytest.raises(MotionFileError) as exc:
        load_motion(path)
    assert str(exc.value).startswith(f"{path}:2: ")


def test_a_file_saved_with_a_utf8_bom_loads(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_text(GOOD, encoding="utf-8-sig")  # starts with EF BB BF, as Notepad saves
    assert path.read_bytes().startswith(b"\xef\xbb\xbf")
    mf = load_motion(path)
    plain = tmp_path / "plain.toml"
    plain.write_text(GOOD)
    assert mf.steps == load_motion(plain).steps and mf.start == load_motion(plain).start
    path.write_text("[[steps]]\nhold = -1\n", encoding="utf-8-sig")
    with pytest.raises(MotionFileError) as exc:
        load_motion(path)
    assert str(exc.value).startswith(f"{path}:2: ")  # line numbers unchanged by the BOM


def test_a_missing_file_is_a_motion_file_error(tmp_path):
    with pytest.raises(MotionFileError, match="no such file") as exc:
        load_motion(tmp_path / "nope.toml")
    assert exc.value.line == 0


def test_the_loader_never_evaluates_code(tmp_path):
    marker = tmp_path / "pwned"
    code = f"__import__('pathlib').Path('{marker}').touch()"
    text = f'description = "{code}"\n[[steps]]\nhold = 1\n'
    mf = _parse(text)
    assert not marker.exists()
    assert "__import__" in mf.description


def test_the_shipped_lab_file_is_the_lab_motion():
    mf = load_motion(lab_motion_path())
    assert mf.start == STARTING_POSE
    assert mf.steps == LAB_MOTION


def test_the_shipped_lab_file_runs_bit_identical_to_the_lab_helpers():
    m = load_model()
    mf = load_motion(lab_motion_path())
    sim = Simulation(m, initial_pose=mf.start)
    from_file = run_motion(m, sim.data, mf.steps)

    d = mujoco.MjData(m)
    lab.set_initial_pose(d, STARTING_POSE)
    helpers = [
        lab.move_to_pose(m, d, None, ZERO_POSE, 2.0),
        lab.hold_position(m, d, None, 2.0),
        lab.move_to_pose(m, d, None, STARTING_POSE, 2.0),
    ]
    assert len(from_file.segments) == len(helpers)
    for a, b in zip(from_file.segments, helpers, strict=True):
        np.testing.assert_array_equal(a.times, b.times)
        np.testing.assert_array_equal(a.commanded, b.commanded)
        np.testing.assert_array_equal(a.measured, b.measured)
    np.testing.assert_array_equal(sim.data.qpos, d.qpos)
    np.testing.assert_array_equal(sim.data.qvel, d.qvel)


def test_cli_run_without_a_file_runs_the_lab_motion(capsys):
    assert cli.main(["run", "--headless"]) == 0
    out = capsys.readouterr().out
    assert [line.split(" ")[0] for line in out.splitlines() if "[" in line] == [
        "to_zero",
        "hold",
        "return",
    ]


def test_cli_run_runs_a_motion_file(tmp_path, capsys):
    path = tmp_path / "m.toml"
    path.write_text("[[steps]]\nname = 'open'\ngripper = 50\nduration = 0.2\n")
    assert cli.main(["run", "--headless", str(path)]) == 0
    out = capsys.readouterr().out
    assert "open [move, 0.000-0.200 s, 100 steps]" in out


def test_cli_run_reports_a_bad_file_with_its_line(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text("[[steps]]\nhold = 0\n")
    assert cli.main(["run", "--headless", str(path)]) == 2
    assert f"{path}:2:" in capsys.readouterr().err


def test_cli_run_strict_refuses_a_too_short_limited_move(tmp_path, capsys):
    path = tmp_path / "fast.toml"
    path.write_text("[[steps]]\nmove = 'zero'\nduration = 0.1\nshape = 'limited'\n")
    assert cli.main(["run", "--headless", "--strict", str(path)]) == 2
    assert "at least" in capsys.readouterr().err
    assert cli.main(["run", "--headless", str(path)]) == 0  # stretched instead


def test_steps_are_motion_step_objects():
    mf = _parse("[[steps]]\nhold = 1\n[[steps]]\nmove = 'zero'\nduration = 2\n")
    assert isinstance(mf.steps[0], Hold) and isinstance(mf.steps[1], Move)
    assert set(mf.steps[1].target) == set(JOINT_NAMES)


# ---------------------------------------------------------------------------- huge or odd inputs
DEEP_ARRAY = "x = " + "[" * 600 + "]" * 600 + "\n"
DEEP_TABLE = "x = " + "{ a = " * 600 + "1" + " }" * 600 + "\n"
DEEP_KEY = "[[steps]]\nduration = 1\nmove.elbow_flex." + ".".join(["a"] * 3000) + " = 1\n"


@pytest.mark.parametrize(
    ("text", "line", "reason"),
    [
        # durations are bounded before they size anything: a move at most an hour, a hold a day
        ("[[steps]]\nhold = 1e9\n", 2, "at most 86400 s"),
        ("[[steps]]\nhold = 1e308\n", 2, "at most 86400 s"),
        ("[[steps]]\nhold = 1\n[[steps]]\nmove = 'zero'\nduration = 7200\n", 5, "at most 3600 s"),
        ("[[steps]]\nmove = 'zero'\nduration = 1e9\nshape = 'limited'\n", 3, "at most 3600 s"),
        ("[[steps]]\ngripper = 50\nduration = 3600.5\n", 3, "at most 3600 s"),
        ("[[steps]]\nhold = 0x" + "f" * 300 + "\n", 2, "302 characters long"),
        ("[[steps]]\nhold = 1" + "0" * 99 + "\n", 2, "at most 86400 s"),  # 100 characters
        # integers Python will not convert (over 4300 digits), hex or decimal
        ("[[steps]]\nhold = " + "9" * 5000 + "\n", 2, "5000 characters long"),
        ("[[steps]]\nhold = 1\n\nmove = 0x" + "f" * 5000 + "\n", 4, "characters long"),
        # nesting bounded before tomllib recurses (it raised RecursionError from 330 levels)
        (DEEP_ARRAY, 1, "nests 33 levels deep"),
        (DEEP_TABLE, 1, "at most 32"),
        ("[[steps]]\nhold = 1\n\n" + DEEP_ARRAY, 4, "nests"),
        (DEEP_KEY, 3, "nests"),  # a dotted key (a RecursionError quoting its value)
        ("[" + ".".join(["t"] * 40) + "]\n", 1, "nests"),
    ],
)
def test_huge_or_deep_values_are_motion_file_errors(text, line, reason):
    err = _error(text)
    assert err.line == line, str(err)
    assert reason in err.reason


def test_the_longest_durations_are_accepted():
    mf = _parse("[[steps]]\nhold = 86400\n[[steps]]\nmove = 'zero'\nduration = 3600\n")
    assert [s.duration for s in mf.steps] == [86400.0, 3600.0]


def test_data_up_to_the_nesting_bound_reaches_the_loader():
    err = _error("x = " + "[" * 31 + "]" * 31 + "\n[[steps]]\nhold = 1\n")  # 32 levels with x
    assert "unknown key 'x'" in err.reason


def test_values_quoted_in_errors_are_cut_short():
    err = _error('steps = ["' + "y" * 100_000 + '"]\n')
    assert "must be a table" in err.reason and len(str(err)) < 300
    err = _error("[[steps]]\nhold = 1\nname = [" + "1, " * 10_000 + "]\n")
    assert err.line == 3 and len(str(err)) < 300


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="no /dev/zero here")
def test_a_device_is_refused_without_reading_it():
    # It was read until memory ran out.
    with pytest.raises(MotionFileError, match="not a regular file") as exc:
        load_motion("/dev/zero")
    assert exc.value.line == 0


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_a_pipe_is_refused_without_waiting_for_a_writer(tmp_path):
    fifo = tmp_path / "motion.toml"
    os.mkfifo(fifo)
    with pytest.raises(MotionFileError, match="not a regular file"):
        load_motion(fifo)


def test_files_past_a_mebibyte_are_refused(tmp_path):
    step = "[[steps]]\nhold = 1\n"
    at_bound = tmp_path / "big.toml"
    at_bound.write_bytes(step.encode() + b"#" * (MAX_FILE_BYTES - len(step) - 1) + b"\n")
    assert at_bound.stat().st_size == MAX_FILE_BYTES
    assert len(load_motion(at_bound).steps) == 1
    with open(at_bound, "ab") as f:
        f.write(b"\n")
    with pytest.raises(MotionFileError, match=f"larger than {MAX_FILE_BYTES} bytes"):
        load_motion(at_bound)
    with pytest.raises(MotionFileError, match="at most 1 MiB"):
        parse_motion(step + "#" * MAX_FILE_BYTES)


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"\x7fELF\x02\x01\x01\x00\xd0\xff", "not UTF-8"),  # a program, say /bin/ls
        (b"[[steps]]\nhold = 1\n\xff\n", "not UTF-8"),
        (b"\x00\x00\x00\x18ftypmp42", "NUL bytes"),  # valid UTF-8, but binary (a video)
    ],
)
def test_files_that_are_not_text_are_refused(tmp_path, content, match):
    path = tmp_path / "m.toml"
    path.write_bytes(content)
    with pytest.raises(MotionFileError, match=match) as exc:
        load_motion(path)
    assert "not a motion file" in str(exc.value) and "--" not in str(exc.value)  # no CLI hint


def test_paths_that_cannot_name_a_file_are_refused(tmp_path):
    with pytest.raises(MotionFileError, match="not a regular file"):
        load_motion(tmp_path)
    with pytest.raises(MotionFileError, match="null"):
        load_motion("motion\0.toml")


# ---------------------------------------------------------------------------- line numbers
@pytest.mark.parametrize(
    ("text", "line"),
    [
        # U+2028, U+2029, U+0085 and the like do not end a line in TOML
        ('description = "a\u2028b\u2029c\u0085d"\n[[steps]]\nhold = -1\n', 3),
        ("# a\u2028b\u2029\u0085\n[[steps]]\nhold = 1\n[[steps]]\nhold = 0\n", 5),
        ("[[steps]]\r\nhold = 1\r\n[[steps]]\r\nhold = 0\r\n", 4),
        # a [[steps]] inside a multi-line string or a comment is not a table
        ("description = '''\n[[steps]]\nhold = 1\n'''\n# [[steps]]\n[[steps]]\nhold = 0\n", 7),
        ('description = """\n[[steps]]\\\n"""\n[[steps]]\nhold = 1\n[[steps]]\nhold = 0\n', 7),
        # steps as one multi-line array of inline tables
        ("steps = [\n  { hold = 1 },\n  { move = 'zero', duration = -1 },\n]\n", 3),
        ("steps = [\n  { hold = 1 },  # first\n\n  { hold = 'x' },\n]\n", 4),
        # a sub-table of the last [[steps]], and a key of a nested inline table
        ("[[steps]]\nhold = 1\n[[steps]]\nduration = 1\n[steps.move]\nelbow_flex = 500\n", 6),
        ("steps = [{ hold = 1 },\n  { duration = 1, move = { wrist_flex = 500 } }]\n", 2),
        # quoted keys with escapes are the keys tomllib reads
        ('[poses.a]\n"elbow_fle\\u0078" = 1\n"wrist_flex\\u002Epos" = 500\n', 3),
        # the end of a file that ends inside an array: its last line
        ('description = "a\u2028b"\nsteps = [\n', 2),
    ],
)
def test_lines_are_counted_as_toml_counts_them(text, line):
    err = _error(text)
    assert err.line == line, str(err)


def test_long_lines_are_located_in_linear_time():
    # An inline string of 20k characters took 3.4 s to locate (quadratic: 200k did not finish
    # in a minute); now a megabyte takes a fraction of a second. The alarm is only a guard
    # against hanging the suite, some 100 times what the scan needs on a busy machine.
    n = MAX_FILE_BYTES - 100
    text = '[poses]\nup = { elbow_flex = 0, s = "' + "a" * n + '" }\n[[steps]]\nhold = 1\n'
    with _alarm(60):
        err = _error(text)
        assert err.line == 2 and "unknown joint 's'" in err.reason
        loc = KeyLines("x = { " + "a" * n + " }\n" + "y = 1\n")
        assert loc.line(("y",)) == 2


@contextmanager
def _alarm(seconds: int):
    """Fail instead of hanging (where SIGALRM exists)."""
    if not hasattr(signal, "SIGALRM"):
        yield
        return

    def fail(*_):
        raise AssertionError(f"still scanning after {seconds} s")

    old = signal.signal(signal.SIGALRM, fail)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


# ---------------------------------------------------------------------------- tip moves
TIP = """\
shape = "minimum_jerk"

[[steps]]
move = { tip = [0.20, 0.0, 0.05], pitch = -90 }
duration = 1

[[steps]]
gripper = 50
duration = 0.5

[[steps]]
name = "forward"
move = { tip = [0.25, 0.0, 0.05], pitch = -90, roll = 10, path = "joint" }
duration = 1
shape = "limited"
"""


def test_a_tip_move_loads_as_a_tip_move_and_the_next_steps_continue_from_its_end():
    mf = _parse(TIP)
    first, grip, forward = mf.steps
    assert first == Move.to_tip((0.2, 0.0, 0.05), 1.0, pitch=-90.0, shape="minimum_jerk",
                                phase="to_tip")  # fmt: skip
    assert first.path == "line" and first.roll is None
    assert forward == Move.to_tip((0.25, 0.0, 0.05), 1.0, pitch=-90.0, roll=10.0, path="joint",
                                  shape="limited", phase="forward")  # fmt: skip
    assert mf.lines == (3, 7, 11)
    # the gripper step keeps the pose the line really ends on, as the run will command it
    sim = Simulation(initial_pose=mf.start)
    _, targets = sim.plan_tip_move(first.tip, 1.0, pitch=-90, shape="minimum_jerk")
    end = sim.units.array_to_pose(targets[-1])
    assert grip.target == {**end, "gripper": 50.0}


def test_a_tip_motion_file_runs_and_ends_with_the_tip_there():
    mf = _parse(TIP)
    sim = Simulation(initial_pose=mf.start, arm="official")  # the plan, on ideal servos
    result = run_motion(sim.model, sim.data, mf.steps)
    assert result.completed and result.end_time == pytest.approx(2.5)
    sim.hold(0.5)  # settle
    tip = sim.tip()
    assert np.linalg.norm(tip.position - (0.25, 0.0, 0.05)) < 2e-3
    assert tip.pitch == pytest.approx(-90, abs=1) and tip.roll == pytest.approx(10, abs=1)


MOVE = "[[steps]]\nduration = 1\nmove = "


@pytest.mark.parametrize(
    ("move", "line", "reason"),
    [
        ("{ tip = 0.2 }", 5, "tip = 0.2 is not three numbers"),
        ("{ tip = [0.2, 0.0] }", 5, "a list of 2 is not three numbers"),
        ("{ tip = [0.2, 'x', 0.05] }", 5, "tip y = 'x' is not a number"),
        ("{ tip = [0.2, 0.0, nan] }", 5, "tip z = nan m is not finite"),
        ("{ tip = [2.5, 0.0, 0.05] }", 5, "each within ±2 m"),
        ("{ tip = [0.2, 0.0, -1e400] }", 5, "not finite"),
        ("{ tip = [0.2, 0.0, 0.05], pitch = 'down' }", 5, "pitch = 'down' is not a number"),
        ("{ tip = [0.2, 0.0, 0.05], roll = 200 }", 5, "roll = 200.0° is invalid"),
        ("{ tip = [0.2, 0.0, 0.05], pitch = true }", 5, "not a number"),
        ("{ tip = [0.2, 0.0, 0.05], path = 'curve' }", 5, "unknown path 'curve'"),
        ("{ tip = [0.2, 0.0, 0.05], elbow_flex = 3 }", 5, "both a tip and a pose"),
        ("{ tip = [0.2, 0.0, 0.05], duration = 3 }", 5, "keys of the step"),
        ("{ tip = [0.2, 0.0, 0.05], speed = 3 }", 5, "unknown key 'speed' in a tip move"),
        ("{ tip = [0.6, 0.0, 0.05] }", 5, "the tip cannot get there"),
        ("{ tip = [0.2, 0.0, 0.3], pitch = -90, path = 'joint' }", 5, "out of reach"),
    ],
)
def test_every_tip_move_error_names_file_line_and_reason(move, line, reason):
    err = _error("[[steps]]\nhold = 1\n" + MOVE + move + "\n")
    assert err.line == line, str(err)
    assert reason in err.reason, err.reason
    assert str(err).startswith(f"m.toml:{line}: ")
    assert "closest=True" not in err.reason  # the API's advice, meaningless in a file


def test_tip_move_errors_point_at_the_key_in_a_multi_line_table():
    table = "[[steps]]\nduration = 1\n[steps.move]\ntip = [0.2, 0.0, 0.05]\n"
    err = _error(table + "pitch = -900\n")
    assert err.line == 5 and "pitch = -900.0° is invalid" in err.reason
    err = _error(table + "shoulder_pan = 0\n")
    assert err.line == 5 and "both a tip and a pose" in err.reason
    err = _error(table.replace("0.05]", "0.05, 0.1]"))
    assert err.line == 4 and "a list of 4" in err.reason


def test_a_line_through_no_reach_or_with_the_limited_profile_is_refused_at_load():
    # the end is reachable, but not the straight line from rest to it (it passes too high)
    err = _error(f"{MOVE}{{ tip = [0.05, 0.0, 0.20], pitch = -90 }}\n")
    assert err.line == 3 and "the tip cannot get there" in err.reason
    err = _error(f"{MOVE}{{ tip = [0.2, 0.0, 0.05] }}\nshape = 'limited'\n")
    assert err.line == 4 and "cannot drive a straight-line tip move" in err.reason
    # the same point in joint space with the limited profile is fine
    mf = _parse(f"{MOVE}{{ tip = [0.2, 0.0, 0.05], path = 'joint' }}\nshape = 'limited'\n")
    assert mf.steps[0].path == "joint"


def test_the_tip_square_example_is_checked_and_stays_on_its_lines():
    from pathlib import Path

    from so101sim.preflight import check_motion_file

    path = Path(__file__).resolve().parents[2] / "examples" / "tip_square.toml"
    mf = load_motion(path)
    sides = [s for s in mf.steps if isinstance(s, Move) and s.tip is not None and s.path == "line"]
    assert len(sides) == 4
    report = check_motion_file(path)
    assert report.passed, report.failures
    deviations = [s.line_deviation_mm for s in report.steps if s.line_deviation_mm is not None]
    assert len(deviations) == 4
    # the commanded tip is on the lines; the default arm (sts3215, P = 16) sags under the
    # arm's weight, so its tip runs 12-15 mm off them (as a real arm at P = 16 would)
    assert all(commanded <= 2.0 and 5.0 < measured <= 20.0 for commanded, measured in deviations)
    ideal = check_motion_file(path, arm="official")
    assert all(
        m <= 2.0 for _, m in (s.line_deviation_mm for s in ideal.steps[:4] if s.line_deviation_mm)
    )


TIP_VALUES = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True)
    .map(repr)
    .map(lambda r: {"inf": "inf", "-inf": "-inf", "nan": "nan"}.get(r, r)),
    st.integers(-(10**30), 10**30).map(str),
    st.sampled_from(["'line'", "'joint'", "'x'", "true", "[]", "[0.2, 0, 0.05]", "[1, 2, 3, 4]"]),
)


@settings(max_examples=100, deadline=None, database=None)
@given(
    st.dictionaries(st.sampled_from(["pitch", "roll", "path", "elbow_flex", "name"]), TIP_VALUES),
    st.lists(TIP_VALUES, max_size=4),
    st.sampled_from(["linear", "limited"]),
)
def test_any_tip_table_loads_or_raises_motion_file_error(keys, tip, shape):
    body = ", ".join([f"tip = [{', '.join(tip)}]", *(f"{k} = {v}" for k, v in keys.items())])
    text = f"[[steps]]\nduration = 0.1\nshape = '{shape}'\nmove = {{ {body} }}\n"
    try:
        mf = parse_motion(text, path="f.toml")
    except MotionFileError as exc:
        assert 1 <= exc.line <= 4 and len(str(exc)) < 1000
    else:
        assert mf.steps[0].tip is not None
