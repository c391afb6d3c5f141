"""Hostile inputs to compare and fit (found by a new user's pass): one error line each, exit 2,
no traceback, nothing allocated from an unbounded number."""

from __future__ import annotations

import json

import pytest

from so101sim.cli import main
from so101sim.units import JOINT_NAMES

REST = "0.0,-98.0,88.0,60.0,0.0,0.0"
HEADER = "time,phase," + ",".join(
    [f"{n}_commanded" for n in JOINT_NAMES] + [f"{n}_measured" for n in JOINT_NAMES]
)


def _csv(tmp_path, rows: list[str]):
    path = tmp_path / "log.csv"
    path.write_text("\n".join([HEADER, *rows]) + "\n")
    return path


def _rest_rows(n: int = 10) -> list[str]:
    return [f"{k / 30:.4f},hold,{REST},{REST}" for k in range(n)]


def _one_error(capsys, argv) -> str:
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith("so101sim: error: ") and len(err.strip().splitlines()) == 1, err
    return err


@pytest.mark.parametrize(
    "rows, words",
    [
        ([*_rest_rows(3), "0.2,hold,1,2"], "fewer fields"),
        ([*_rest_rows(3), f"1e400,hold,{REST},{REST}"], "finite"),
        ([f"0.0,hold,nan,{REST[4:]},{REST}", *_rest_rows(5)[1:]], "finite"),
    ],
)
def test_a_damaged_csv_log_is_one_error_line(tmp_path, capsys, rows, words):
    log = _csv(tmp_path, rows)
    for argv in (["compare", str(log)], ["fit", str(log), "-o", str(tmp_path / "a.toml")]):
        assert words in _one_error(capsys, argv)
    assert not (tmp_path / "a.toml").exists()


@pytest.mark.parametrize("info", [[], {"fps": 30, "features": {"action": [], "x": 1}}])
def test_an_info_json_of_the_wrong_shape_is_one_error_line(tmp_path, capsys, info):
    (tmp_path / "ds" / "meta").mkdir(parents=True)
    (tmp_path / "ds" / "meta" / "info.json").write_text(json.dumps(info))
    assert "features" in _one_error(capsys, ["compare", str(tmp_path / "ds")])


@pytest.mark.parametrize("threads", ["0", "-5", "99999999999"])
def test_fit_threads_are_bounded_before_anything_is_allocated(tmp_path, capsys, threads):
    log = _csv(tmp_path, _rest_rows())
    argv = ["fit", str(log), "-o", str(tmp_path / "a.toml"), "--threads", threads]
    assert "threads" in _one_error(capsys, argv)


def test_empty_and_missing_logs_and_episodes_are_refused(tmp_path, capsys):
    assert "empty" in _one_error(capsys, ["compare", ""])
    assert "does not exist" in _one_error(capsys, ["compare", str(tmp_path / "nope.csv")])
    log = _csv(tmp_path, _rest_rows())
    assert "empty" in _one_error(capsys, ["compare", str(log), "--episodes", ""])
