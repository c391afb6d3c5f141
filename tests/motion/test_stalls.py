"""Nothing stalls (issue 23): reaching a Ray cluster is bounded in time, and planning a
straight tip line costs what its length and turn ask for, not what its duration does (a
3600 s line is 1.8 million targets: it used to be 1.8 million IK solves, and a line over
~2000 s failed with "steps of shape (1800000,) are invalid")."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from so101sim import Simulation
from so101sim.cli import main
from so101sim.errors import SettingError
from so101sim.kinematics import ik, paths
from so101sim.motion.file import load_motion

TARGET = (0.26, -0.03, 0.05)
START = (0.20, -0.03, 0.05)


# ---------------------------------------------------------------------------- Ray
def test_an_address_that_does_not_resolve_fails_at_once() -> None:
    from so101sim.preflight.distributed import probe_address

    with pytest.raises(SettingError, match=r"no Ray cluster reached at nonsense:1 within 10 s"):
        probe_address("nonsense:1")
    with pytest.raises(SettingError, match="within 10 s"):
        probe_address("127.0.0.1:1")  # nothing listens: refused
    with pytest.raises(SettingError, match="is not an address"):
        probe_address("nonsense")
    probe_address("auto")  # left to Ray, which answers at once


def test_an_address_that_does_not_answer_gives_up_in_the_time_stated(monkeypatch) -> None:
    import socket

    from so101sim.preflight.distributed import probe_address

    asked = []

    def silent(address, timeout):
        asked.append(timeout)
        raise TimeoutError("timed out")

    monkeypatch.setattr(socket, "create_connection", silent)
    with pytest.raises(SettingError, match=r"within 0\.5 s \(no answer\)"):
        probe_address("10.255.255.1:6379", timeout=0.5)
    assert asked == [0.5]


def test_check_variants_on_a_nonsense_ray_address_is_one_error_line(capsys) -> None:
    pytest.importorskip("ray")
    t0 = time.monotonic()
    assert main(["check", "--variants", "2", "--ray", "nonsense:1"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "within 10 s" in err
    assert time.monotonic() - t0 < 60  # it hung for minutes (a loose bound: a busy machine)


# ---------------------------------------------------------------------------- tip lines
@pytest.fixture
def solves(monkeypatch) -> list[int]:
    """Counts the IK descents run (the planning work)."""
    count = [0]
    run = ik.Descent.run

    def counted(self, *args, **kwargs):
        count[0] += 1
        return run(self, *args, **kwargs)

    monkeypatch.setattr(ik.Descent, "run", counted)
    return count


def _plan(duration: float) -> np.ndarray:
    sim = Simulation()
    sim.command_array(sim.plan_tip_move(START, 2.0, pitch=-90, path="joint")[1][-1], check=False)
    return sim.plan_tip_move(TARGET, duration, pitch=-90)[1]


def test_a_long_line_costs_what_its_geometry_asks_not_its_duration(solves) -> None:
    _plan(20.0)
    short = solves[0]
    solves[0] = 0
    targets = _plan(3600.0)
    assert len(targets) == 1_800_000  # one target per 2 ms step
    assert solves[0] == short  # the same 6 cm line: the same solves
    assert short <= 2 * paths.MIN_KNOTS  # not one per target


def test_a_line_of_an_hour_is_planned_on_the_line(solves) -> None:
    from so101sim.kinematics import line_deviation

    targets = _plan(3600.0)
    every = targets[:: len(targets) // 2000]  # 2000 rows spread over the hour
    deviation = line_deviation(every, START, TARGET)
    assert deviation.max_mm < 0.5
    np.testing.assert_allclose(np.diff(targets[:, 0]).max(), 0.0, atol=1e-3)  # smooth


@pytest.mark.parametrize("duration", [1999.0, 2001.0, 2500.0, 3600.0])
def test_lines_over_2000_s_plan_without_an_internal_error(duration: float) -> None:
    assert len(_plan(duration)) == round(duration / 0.002)


def test_a_motion_file_with_an_hour_long_line_loads(tmp_path: Path, solves) -> None:
    f = tmp_path / "long.toml"
    f.write_text(
        'start = "rest"\n'
        "[[steps]]\n"
        f'move = {{ tip = {list(START)}, pitch = -90, path = "joint" }}\n'
        "duration = 2.0\n"
        "[[steps]]\n"
        f"move = {{ tip = {list(TARGET)}, pitch = -90 }}\n"
        "duration = 3600.0\n"
    )
    motion = load_motion(f)
    assert motion.steps[-1].duration == 3600.0
    assert solves[0] < 5 * paths.MIN_KNOTS


def test_thirty_lines_of_a_minute_cost_thirty_short_lines(tmp_path: Path, solves) -> None:
    lines = ['start = "rest"', "[[steps]]", f"move = {{ tip = {list(START)}, pitch = -90, "
             'path = "joint" }', "duration = 2.0"]  # fmt: skip
    for i in range(30):
        tip = TARGET if i % 2 == 0 else START
        lines += ["[[steps]]", f"move = {{ tip = {list(tip)}, pitch = -90 }}", "duration = 60.0"]
    f = tmp_path / "many.toml"
    f.write_text("\n".join(lines) + "\n")
    load_motion(f)
    assert solves[0] < 30 * 2 * paths.MIN_KNOTS  # it was 30 x 30000 (one per target)


def test_a_line_needing_too_many_solves_is_refused_at_once_saying_why(monkeypatch) -> None:
    monkeypatch.setattr(paths, "MAX_LINE_SOLVES", 100)
    with pytest.raises(SettingError, match=r"needs \d+ IK solves; expected a line that needs at"):
        _plan(3600.0)


def test_more_steps_than_a_line_may_have_is_said_in_seconds(monkeypatch) -> None:
    monkeypatch.setattr(paths, "MAX_LINE_STEPS", 1000)
    with pytest.raises(SettingError, match=r"a straight tip line of 3600 s is 1800000 physics"):
        _plan(3600.0)
