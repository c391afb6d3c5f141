"""Fuzzing what users type: motion files and the command line's options (Hypothesis).

Each property says "nothing crashes, nothing is lost":

* the motion-file loader returns a :class:`MotionFile` or raises :class:`MotionFileError` with
  a line inside the file, for texts built from the real keys (poses, steps, durations,
  shapes, huge numbers, NaN, strings of any Unicode) and mangled at random, and for any
  text or bytes at all; for valid files, every step's line is the line it was written on;
* the leader's calibration loader returns a calibration or raises :class:`CalibrationError`
  for any bytes, JSON or deeply nested brackets;
* ``so101sim.cli.main`` returns 0, 1 or 2 (or argparse exits with 2) and prints no
  traceback, whatever values ``hold``, ``run``, ``check`` and ``teleop`` are given.

Runs are kept short (durations of at most 0.2 s, small frames) and the number of examples
bounded, so the file takes well under a minute (about 10 to 30 s on the busy 2-core
development machine, the command line's property most of it); the example database is off, so
each run draws new examples. A bug found here in code outside the input layer (the recording
settings: frame sizes with no upper bound) has its own case at the end.
"""

from __future__ import annotations

import itertools
import json
import math
import string
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from so101sim import cli
from so101sim.errors import CalibrationError, MotionFileError
from so101sim.motion.file import MotionFile, load_motion, parse_motion
from so101sim.motion.lines import count_lines
from so101sim.robot.teleop import load_calibration
from so101sim.sim.profiles import MAX_MOVE_DURATION_S
from so101sim.units import JOINT_NAMES
from so101sim.validation import MAX_DURATION_S

FAST = settings(max_examples=150, deadline=None, database=None)
CLI = settings(
    max_examples=25,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


# ---------------------------------------------------------------------------- TOML pieces
def toml_string(s: str) -> str:
    """``s`` as a TOML basic string (every character TOML forbids raw, escaped)."""
    out = []
    for ch in s:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        elif 0xD800 <= ord(ch) <= 0xDFFF:
            out.append("?")  # a lone surrogate cannot be written in a file
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def toml_number(x: float | int) -> str:
    if isinstance(x, float) and math.isnan(x):
        return "nan"
    if isinstance(x, float) and math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return repr(x)


ODD_TEXT = st.text(
    alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",))
    | st.sampled_from(["\u2028", "\u2029", "\u0085", "\r", "\n", "\t", "\x00", "#", '"', "'"]),
    max_size=12,
)
NUMBERS = st.one_of(
    st.integers(min_value=-(10**30), max_value=10**30),
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(min_value=-200, max_value=200),
    st.sampled_from(
        [0, 1, -1, 0.5, 1e9, 1e308, -1e308, 3600, 3600.5, 86400, 86401, 1e-300, 5e-324, 2**64]
    ),
).map(toml_number)
BIG_INT = st.integers(min_value=300, max_value=5000).map(lambda n: "9" * n)
SCALARS = st.one_of(
    NUMBERS,
    NUMBERS,
    ODD_TEXT.map(toml_string),
    st.sampled_from(["true", "false", "1979-05-27", "07:32:00", "1979-05-27T07:32:00Z"]),
    st.sampled_from(["'rest'", "'zero'", "'up'", "'linear'", "'limited'", "'minimum_jerk'"]),
)


ODD_PARTS = (
    "description", "units", "shape", "start", "pose name", "joint", "joint value",
    "pose", "kind", "move", "duration", "gripper", "step shape", "step name", "steps",
    "layout", "text",
)  # fmt: skip
"""The parts of a motion file :func:`motion_texts` may make odd, one per file."""


class Parts:
    """Draws each part of a motion file: the plausible strategy, or for the one part chosen to
    be odd (none in some files) the odd one. So most files get far into the loader, and each
    part is odd in some."""

    def __init__(self, draw: st.DrawFn) -> None:
        self.draw = draw
        self.odd = draw(st.sampled_from((None, None, None, *ODD_PARTS)))

    def __call__(self, part: str, good: st.SearchStrategy[Any], odd: st.SearchStrategy[Any]):
        return self.draw(odd if part == self.odd else good)


def pairs(
    keys: st.SearchStrategy[str], values: st.SearchStrategy[str]
) -> st.SearchStrategy[list[tuple[str, str]]]:
    return st.lists(st.tuples(keys, values), max_size=4, unique_by=lambda kv: kv[0])


def inline(kvs: list[tuple[str, str]]) -> str:
    return "{ " + ", ".join(f"{k} = {v}" for k, v in kvs) + " }"


KEYS = st.one_of(
    st.sampled_from(["x", "move", "hold", "elbow", "shoulder_pan.pos", "a b"]).map(toml_string),
    st.text(string.ascii_letters + "_-", min_size=1, max_size=8),
)
VALUES = st.recursive(
    st.one_of(SCALARS, BIG_INT),
    lambda children: (
        st.lists(children, max_size=4).map(lambda v: "[" + ", ".join(v) + "]")
        | pairs(KEYS, children).map(inline)
    ),
    max_leaves=8,
)
JOINTS = st.sampled_from([*JOINT_NAMES, *(toml_string(f"{n}.pos") for n in JOINT_NAMES)])
SHORT = st.floats(min_value=0.001, max_value=0.2).map(repr)  # runs stay short
ODD_DURATIONS = st.one_of(NUMBERS, VALUES, BIG_INT, st.just(""))  # "": none given


def pose(parts: Parts) -> list[tuple[str, str]]:
    joints = parts("joint", JOINTS, KEYS)
    good = pairs(JOINTS, st.floats(-60, 60).map(repr))
    odd = st.tuples(st.just(joints), st.one_of(NUMBERS, VALUES)).map(lambda kv: [kv])
    return parts("joint value", good, odd) + parts("joint", st.just([]), st.just([(joints, "1")]))


def step(parts: Parts) -> dict[str, str]:
    """One step's keys and values (TOML text)."""
    kind = parts("kind", st.sampled_from(["move", "hold", "gripper"]), st.just("none, both"))
    out: dict[str, str] = {}
    if kind in ("move", "none, both"):
        names = st.sampled_from(["'rest'", "'zero'", "'up'", "'left'", "'down'"])
        out["move"] = parts("move", names, VALUES | names.map(lambda n: n + "x"))
        if parts.draw(st.booleans()):
            out["move"] = inline(pose(parts))
    if kind in ("hold", "none, both"):
        out["hold"] = parts("duration", SHORT, ODD_DURATIONS)
    if kind == "gripper":
        out["gripper"] = parts("gripper", st.floats(0, 100).map(repr), NUMBERS)
    if kind in ("move", "gripper"):
        out["duration"] = parts("duration", SHORT, ODD_DURATIONS)
    if parts.draw(st.booleans()):
        out["shape"] = parts("step shape", st.just("'minimum_jerk'"), VALUES)
    if parts.draw(st.booleans()):
        out["name"] = parts("step name", ODD_TEXT.map(toml_string), VALUES)
    return {k: v for k, v in out.items() if v}


@st.composite
def motion_texts(draw: st.DrawFn) -> str:
    """A motion file built from the real keys, in one of TOML's layouts, one part of it odd
    (or none), maybe mangled."""
    parts = Parts(draw)
    lines: list[str] = []
    for key, good in (
        ("description", ODD_TEXT.map(toml_string)),
        ("units", st.sampled_from(["'deg'", "'rad'"])),
        ("shape", st.sampled_from(["'linear'", "'minimum_jerk'", "'limited'"])),
        ("start", st.sampled_from(["'rest'", "'zero'", "'up'"])),
    ):
        if draw(st.booleans()) or parts.odd == key:
            lines.append(f"{key} = {parts(key, good, VALUES)}")
    names = st.sampled_from(["up", "left", "'down'", '"a b"'])
    poses = {parts("pose name", names, KEYS): pose(parts) for _ in range(draw(st.integers(0, 3)))}
    if parts("layout", st.booleans(), st.just(False)) and poses:
        lines.append("[poses]")
        lines += [
            f"{name} = {parts('pose', st.just(inline(p)), VALUES)}" for name, p in poses.items()
        ]
    else:
        for name, p in poses.items():
            lines += [f"[poses.{name}]", *(f"{k} = {v}" for k, v in p)]
    all_steps = [step(parts) for _ in range(parts("steps", st.integers(1, 4), st.just(0)))]
    if draw(st.booleans()):
        for s in all_steps:
            lines += ["[[steps]]", *(f"{k} = {v}" for k, v in s.items())]
    elif all_steps:
        lines += ["steps = [", *(f"  {inline(list(s.items()))}," for s in all_steps), "]"]
    text = "\n".join(lines) + "\n"
    return parts("text", st.just(text), mangled(text))


@st.composite
def mangled(draw: st.DrawFn, text: str) -> str:
    """``text`` with a piece cut out, odd characters put in, other line ends, or deep data."""
    how = draw(st.sampled_from(["insert", "cut", "crlf", "nest"]))
    at = draw(st.integers(0, len(text)))
    if how == "insert":
        return text[:at] + draw(ODD_TEXT) + text[at:]
    if how == "cut":
        return text[:at] + text[at + draw(st.integers(1, 20)) :]
    if how == "crlf":
        return text.replace("\n", "\r\n")
    depth = draw(st.integers(1, 400))  # "nest"
    return text + "deep = " + "[" * depth + "]" * depth + "\n"


# ---------------------------------------------------------------------------- the loader
def _load(text: str) -> MotionFile | None:
    """Load ``text``; on MotionFileError check the error is well-formed and return None."""
    try:
        motion = parse_motion(text, path="fuzz.toml")
    except MotionFileError as exc:
        assert 0 <= exc.line <= count_lines(text), (exc.line, text)
        assert str(exc).startswith("fuzz.toml") and exc.reason
        assert len(str(exc)) < 1000  # values are quoted short
        return None
    assert isinstance(motion, MotionFile)
    assert len(motion.steps) == len(motion.lines) >= 1
    for step in motion.steps:
        most = MAX_MOVE_DURATION_S if hasattr(step, "target") else MAX_DURATION_S
        assert 0 < step.duration <= most
    return motion


@pytest.mark.slow
@FAST
@given(motion_texts())
def test_motion_file_texts_load_or_raise_motion_file_error(text):
    _load(text)


@FAST
@given(st.text(max_size=300))
def test_any_text_loads_or_raises_motion_file_error(text):
    _load(text)


@settings(max_examples=60, deadline=None, database=None)
@given(st.binary(max_size=300))
def test_any_file_loads_or_raises_motion_file_error(tmp_path_factory, content):
    path = tmp_path_factory.mktemp("fuzz") / "m.toml"
    path.write_bytes(content)
    try:
        assert isinstance(load_motion(path), MotionFile)
    except MotionFileError as exc:
        assert exc.path == str(path)


JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda children: (
        st.lists(children, max_size=4)
        | st.dictionaries(st.sampled_from([*JOINT_NAMES, "id", "range_min", "x"]), children)
    ),
    max_leaves=20,
)
CALIBRATION_FILES = st.one_of(
    st.binary(max_size=300),
    JSON.map(lambda v: json.dumps(v).encode()),
    st.integers(1, 40_000).map(lambda n: b"[" * n + b"]" * n),
)


@settings(max_examples=60, deadline=None, database=None)
@given(CALIBRATION_FILES)
def test_any_calibration_file_loads_or_raises_calibration_error(tmp_path_factory, content):
    path = tmp_path_factory.mktemp("fuzz") / "leader.json"
    path.write_bytes(content)
    try:
        assert set(load_calibration(path)) == set(JOINT_NAMES)
    except CalibrationError as exc:
        assert str(path) in str(exc) or "calibration" in str(exc)


# ---------------------------------------------------------------------------- line numbers
TOP_JUNK = st.sampled_from(
    [
        'description = "[[steps]]\u2028hold = 1\u2029 \u0085"',
        "description = '''\n[[steps]]\nhold = -1\n'''",
        'description = """\nmove = { x = 1 }\\\n"""',
        "units = 'deg'  # [[steps]]",
    ]
)
JUNK = st.lists(
    st.sampled_from(["", "# [[steps]]", "# \u2028 [poses] \u2029", "  # hold = 1"]), max_size=2
)


@st.composite
def valid_motions(draw: st.DrawFn) -> tuple[str, list[int]]:
    """A valid motion file with comments, strings and blank lines between its parts, and the
    line each step was written on."""
    lines: list[str] = draw(JUNK)
    for piece in draw(st.lists(TOP_JUNK, max_size=1)):
        lines += piece.split("\n")
    starts: list[int] = []
    as_array = draw(st.booleans())
    if as_array:
        lines.append("steps = [")
    for _ in range(draw(st.integers(1, 5))):
        joint = draw(st.sampled_from(JOINT_NAMES))
        value = draw(st.floats(-5, 5)) if joint != "gripper" else draw(st.floats(1, 99))
        short = draw(st.floats(0.001, 0.2))
        step = draw(
            st.sampled_from(
                [
                    f"hold = {short!r}",
                    f"move = 'zero', duration = {short!r}",
                    f"move = {{ {joint} = {value!r} }}, duration = {short!r}",
                    f"gripper = {draw(st.floats(1, 99))!r}, duration = {short!r}",
                ]
            )
        )
        lines += draw(JUNK)
        starts.append(len(lines) + 1)
        lines += ["  { " + step + " },"] if as_array else ["[[steps]]", *step.split(", ")]
    if as_array:
        lines.append("]")
    return "\n".join(lines + draw(JUNK)) + "\n", starts


@FAST
@given(valid_motions())
def test_each_steps_line_is_where_it_was_written(case):
    text, starts = case
    motion = parse_motion(text, path="fuzz.toml")
    assert list(motion.lines) == starts, text


# ---------------------------------------------------------------------------- the command line
EDGE_NUMBERS = st.sampled_from(
    ["0", "-0", "-1", "nan", "inf", "-inf", "1e309", "1e-320", "1e9", "1e308", "0x10", "1_0",
     "", " ", "--", "x", "\u0663", "9" * 400, "1.5", "2", "31", "240", "241", "1e4", "1e5"]
)  # fmt: skip
ODD_NUMBERS = EDGE_NUMBERS | st.text(max_size=6)
ODD_DURATIONS_CLI = ODD_NUMBERS.filter(lambda v: not 0.2 < _float(v) <= MAX_DURATION_S)
"""Odd durations, but none that would run long: invalid ones, or at most 0.2 s."""
ODD_SIZES = ODD_NUMBERS.filter(lambda v: not v.strip().isdigit() or int(v) <= 64)
"""Frame sizes other than huge ones (huge ones render for long before the bound was added:
they have their own case at the end)."""


def _float(value: str) -> float:
    """``value`` as argparse's ``type=float`` reads it (NaN if it cannot)."""
    try:
        return float(value)
    except ValueError:
        return math.nan


def floats(low: float, high: float) -> st.SearchStrategy[str]:
    return st.floats(min_value=low, max_value=high).map(repr)


Option = tuple[st.SearchStrategy[str], st.SearchStrategy[str]]
"""An option's plausible values and its odd ones."""


def _file(out: Path, kind: str) -> str:
    """A file for ``kind`` (a motion file, a bad one, a calibration) written in ``out``, or a
    path that names no such file."""
    files = {
        "ok": "[[steps]]\nmove = { elbow_flex = 5 }\nduration = 0.1\nshape = 'minimum_jerk'\n",
        "long": "[[steps]]\nhold = 1e9\n",
        "bad": "[[steps]]\nmove = { elbow = 5 }\nduration = 0.1\n",
        "calibration": '{"shoulder_pan": {"id": 1}}',
    }
    if kind in files:
        path = out / f"{kind}.txt"
        path.write_text(files[kind])
        return str(path)
    return {"missing": str(out / "missing.toml"), "folder": str(out)}.get(kind, kind)


def options(command: str, out: Path, record: bool) -> dict[str, Option]:
    """The options of ``command`` the fuzzer sets (``""``: the positional motion file)."""
    motion = (
        st.just("ok").map(lambda k: _file(out, k)),
        st.sampled_from(["long", "bad", "missing", "folder", "/dev/zero", "/bin/ls"]).map(
            lambda k: _file(out, k)
        ),
    )
    found: dict[str, Option] = {"--model": (st.nothing(), st.sampled_from([str(out), "/dev/zero"]))}
    if command in ("hold", "run"):
        found["--speed"] = (floats(0.01, 100), ODD_NUMBERS)
    if command == "hold":
        found["--duration"] = (SHORT, ODD_DURATIONS_CLI)
    if command in ("run", "check"):
        found[""] = motion
    if command == "check":
        for flag, high in (
            ("--max-effort", 1.0),
            ("--max-saturation", 1.0),
            ("--max-tracking-error", 50.0),
            ("--limit-margin", 10.0),
        ):
            found[flag] = (floats(0.01, high), ODD_NUMBERS)
    if command == "teleop":  # it stops at the leader's port at the latest: there is no leader
        calibration = st.sampled_from(["/bin/ls", "/dev/zero", "folder", "calibration", "x.json"])
        found["--calibration"] = (st.nothing(), calibration.map(lambda k: _file(out, k)))
        found["--fps"] = (floats(1, 200), ODD_NUMBERS)
        found["--duration"] = (SHORT, ODD_DURATIONS_CLI)
    if record:
        paths = st.sampled_from(["v.gif", "v", "missing/v.mp4", ""])
        found["--record"] = (st.just(str(out / "v.mp4")), paths.map(lambda p: str(out / p)))
        found["--width"] = (st.integers(8, 32).map(lambda n: str(2 * n)), ODD_SIZES)
        found["--height"] = found["--width"]
        found["--fps"] = (floats(1, 60), ODD_NUMBERS)
        found["--camera"] = (st.just("free"), st.sampled_from(["nope", ""]) | st.text(max_size=5))
        found["--quality"] = (st.sampled_from(["auto", "draft", "full"]), st.just("best"))
    if command in ("hold", "run"):
        found["--plot"] = (st.just(str(out / "p.png")), st.just(str(out / "p.txt")))
        found["--log"] = (st.just(str(out / "l.csv")), st.just(str(out / "missing/l.csv")))
    return found


def once_in(n: int) -> st.SearchStrategy[bool]:
    """True about once in ``n`` draws (Hypothesis favours the ends of an integer range)."""
    return st.sampled_from([False] * (n - 1) + [True])


ALWAYS = ("", "--record", "--duration", "--width", "--height")
"""Options always given (small frames: the default 640 x 480 takes seconds to render)."""
RARELY = {"--plot": 8}
"""Options given about once in so many runs, those that take long (matplotlib: a second)."""


@st.composite
def command_lines(draw: st.DrawFn, out: Path) -> list[str]:
    """A command line with plausible values for its options but one odd (or none): runs are
    short (at most 0.2 s simulated, frames of at most 64 pixels) and write into ``out``."""
    command = draw(st.sampled_from(["hold", "hold", "run", "run", "check", "check", "teleop"]))
    record = command in ("hold", "run") and draw(once_in(6))
    found = options(command, out, record)
    odd = draw(st.sampled_from([*[None] * 4, *found]))
    argv = {
        "hold": ["hold", "--headless", "--force"],
        "run": ["run", "--headless", "--force", *draw(st.sampled_from([[], ["--strict"]]))],
        "check": ["check", *draw(st.sampled_from([[], ["--json"], ["--strict"]]))],
        "teleop": ["teleop", "--headless", "--port", str(out / "ttyNONE")],
    }[command]
    for flag, (good, bad) in found.items():
        if flag == odd:
            value = draw(bad)
        elif flag in ALWAYS or (not good.is_empty and draw(once_in(RARELY.get(flag, 2)))):
            value = draw(good)
        else:
            continue
        argv += [value] if not flag else [f"{flag}={value}"]
    if record:
        argv += draw(st.sampled_from([[], ["--caption"], ["--no-caption"]]))
    return argv


_RUNS = itertools.count()


@CLI
@given(data=st.data())
def test_cli_options_never_crash(tmp_path, capsys, data):
    out = tmp_path / str(next(_RUNS))  # a folder of its own for each example
    out.mkdir()
    argv = data.draw(command_lines(out), label="argv")
    try:
        rc = cli.main(argv)
    except SystemExit as exc:  # argparse: a value of the wrong type or an unknown choice
        rc = exc.code
    printed = capsys.readouterr()
    event(f"{argv[0]}{' --record' if any('--record' in a for a in argv) else ''} -> {rc}")
    assert rc in (0, 1, 2), (argv, rc, printed.err[-2000:])
    assert "Traceback" not in printed.out + printed.err, (argv, printed.err[-2000:])
    if rc == 2:
        assert printed.err.strip(), argv  # a refusal says why
    assert not list(out.rglob(".*.partial*")), argv  # nothing half-written left behind


# ----------------------------------------------------------------- found by fuzzing, fixed
def test_huge_frame_sizes_are_refused_as_settings(tmp_path, capsys):
    video = tmp_path / "v.mp4"
    argv = ["hold", "--headless", "--duration", "0.01", "--record", str(video)]
    assert cli.main([*argv, "--width", "100000", "--height", "100000"]) == 2
    err = capsys.readouterr().err
    assert "width" in err and "EGL" not in err
