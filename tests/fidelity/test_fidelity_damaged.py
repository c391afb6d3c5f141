"""Damaged logs are never trusted (issue 32, point 5): each case is one error line on standard
error, exit 2, nothing on standard output, and no hang (a FIFO is never opened)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

pytest.importorskip("pyarrow")

import pyarrow as pa
import pyarrow.parquet as pq
from fidelity_helpers import commands, write_lerobot

from so101sim.cli import main
from so101sim.fidelity.logs import Episode
from so101sim.units import JOINT_NAMES

FILE = ("data", "chunk-000", "file-000.parquet")


def _episodes(n: int = 2) -> list[Episode]:
    out = []
    for i in range(n):
        t, cmd = commands(20 + i, seconds=1.0)
        out.append(Episode(i, t, cmd, cmd + 0.5))
    return out


@pytest.fixture
def ds(tmp_path):
    return write_lerobot(tmp_path / "ds", _episodes())


def _one_error(capsys, argv) -> str:
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert out == ""
    lines = err.strip().splitlines()
    assert err.startswith("so101sim: error: ") and len(lines) == 1, err
    assert len(err) < 600, err  # no schema dump, no traceback
    return err


def _both(capsys, root, tmp_path) -> list[str]:
    """The error of compare and of fit (which writes nothing)."""
    out = tmp_path / "fitted.toml"
    errs = [
        _one_error(capsys, ["compare", str(root), "--units", "degrees"]),
        _one_error(capsys, ["fit", str(root), "-o", str(out), "--units", "degrees"]),
    ]
    assert not out.exists()
    return errs


def _rewrite(root, change) -> None:
    """Replace the dataset's parquet file by ``change(table)``."""
    path = root.joinpath(*FILE)
    table = pq.read_table(path)
    pq.write_table(change(table), path)


def _set(table, name, values):
    return table.set_column(table.schema.get_field_index(name), name, values)


def test_a_fifo_under_data_is_refused_without_opening_it(ds, tmp_path, capsys):
    os.mkfifo(ds / "data" / "chunk-000" / "file-001.parquet")
    for err in _both(capsys, ds, tmp_path):
        assert "not a regular file" in err


def test_a_parquet_with_flipped_bytes_is_refused(tmp_path, capsys):
    root = write_lerobot(tmp_path / "ds", _episodes())
    path = root.joinpath(*FILE)
    table = pq.read_table(path)
    pq.write_table(table, path, write_page_checksum=True, compression="none")
    raw = bytearray(path.read_bytes())
    body = pq.ParquetFile(path).metadata.row_group(0).column(0)  # the action column's pages
    at = body.data_page_offset + (body.total_compressed_size // 2)
    raw[at : at + 4] = bytes(b ^ 0x5A for b in raw[at : at + 4])
    path.write_bytes(bytes(raw))
    assert "damaged" in _both(capsys, root, tmp_path)[0]


def test_a_row_count_unlike_info_json_is_refused(ds, tmp_path, capsys):
    info = json.loads((ds / "meta" / "info.json").read_text())
    info["total_frames"] = 61  # the files hold 60
    (ds / "meta" / "info.json").write_text(json.dumps(info))
    assert "total_frames = 61" in _both(capsys, ds, tmp_path)[0]


def test_a_parquet_with_no_rows_is_refused(ds, tmp_path, capsys):
    _rewrite(ds, lambda t: t.slice(0, 0))
    assert "no frames" in _both(capsys, ds, tmp_path)[0]


def test_three_element_action_vectors_are_refused(ds, tmp_path, capsys):
    def short(t):
        rows = [v[:3] for v in t.column("action").to_pylist()]
        return _set(t, "action", pa.array(rows, type=pa.list_(pa.float32())))

    _rewrite(ds, short)
    assert "3 values per frame" in _both(capsys, ds, tmp_path)[0]


@pytest.mark.parametrize("frames", ["duplicated", "negative"])
def test_duplicated_or_negative_frame_indices_are_refused(ds, tmp_path, capsys, frames):
    def damage(t):
        fr = np.array(t.column("frame_index").to_pylist())
        if frames == "duplicated":
            fr[5] = fr[4]
        else:
            fr[0] = -3
        return _set(t, "frame_index", pa.array(fr, type=pa.int64()))

    _rewrite(ds, damage)
    assert "damaged" in _both(capsys, ds, tmp_path)[0]


def test_a_string_action_column_is_refused(ds, tmp_path, capsys):
    def strings(t):
        rows = [[str(x) for x in v] for v in t.column("action").to_pylist()]
        return _set(t, "action", pa.array(rows, type=pa.list_(pa.string())))

    _rewrite(ds, strings)
    assert "expected numbers" in _both(capsys, ds, tmp_path)[0]


def test_a_dataset_with_no_action_column_names_it_without_the_schema(ds, tmp_path, capsys):
    _rewrite(ds, lambda t: t.drop(["action"]))
    err = _both(capsys, ds, tmp_path)[0]
    assert "no column 'action'" in err and "list<" not in err


def test_values_beyond_any_joint_reading_are_refused(ds, tmp_path, capsys):
    def huge(t):
        rows = t.column("observation.state").to_pylist()
        rows[7][2] = 3.0e7  # a flipped exponent bit
        return _set(t, "observation.state", pa.array(rows, type=pa.list_(pa.float32())))

    _rewrite(ds, huge)
    assert "beyond any joint reading" in _both(capsys, ds, tmp_path)[0]


def test_a_huge_info_json_is_refused_without_reading_it_whole(ds, tmp_path, capsys):
    info = ds / "meta" / "info.json"
    with open(info, "r+b") as fh:
        fh.truncate(300 * 1024 * 1024)  # sparse: 300 MB that take no disk
    assert "larger than" in _both(capsys, ds, tmp_path)[0]


def test_a_csv_log_with_an_overlong_line_is_refused(tmp_path, capsys):
    header = "time,phase," + ",".join(
        f"{n}_{k}" for n in JOINT_NAMES for k in ("commanded", "measured")
    )
    row = "0.0,hold," + ",".join(["0.0"] * 12)
    path = tmp_path / "log.csv"
    path.write_text("\n".join([header, row, "0.1,hold," + "1" * 1_000_000, row]) + "\n")
    err = _one_error(capsys, ["compare", str(path)])
    assert "line 3 is longer than" in err


def test_data_changed_since_lerobot_wrote_its_stats_are_refused(ds, tmp_path, capsys):
    table = pq.read_table(ds.joinpath(*FILE))
    state = np.array(table.column("observation.state").to_pylist())
    stats = {"observation.state": {"min": state.min(0).tolist(), "max": state.max(0).tolist(),
             "mean": state.mean(0).tolist(), "std": state.std(0).tolist(),
             "count": [len(state)]}}  # fmt: skip
    (ds / "meta" / "stats.json").write_text(json.dumps(stats))
    assert main(["compare", str(ds), "--units", "degrees", "--json"]) == 0  # as recorded
    capsys.readouterr()

    def moved(t):
        rows = t.column("observation.state").to_pylist()
        rows[20][1] += 4.0  # a flipped bit in one float32: a plausible value, moved
        return _set(t, "observation.state", pa.array(rows, type=pa.list_(pa.float32())))

    _rewrite(ds, moved)
    assert "disagrees with meta/stats.json" in _both(capsys, ds, tmp_path)[0]


def test_a_dataset_so101sim_wrote_is_read_in_degrees_without_a_guess(tmp_path):
    """``so101sim dataset`` writes degrees (its meta/so101sim.json says who wrote it): --units
    auto takes them as degrees, not as LeRobot's range mode mapped onto the model's ranges."""
    from so101sim.fidelity.logs import read_log
    from so101sim.model import default_units

    root = write_lerobot(tmp_path / "ds", _episodes())
    units = default_units()
    guessed = read_log(root, units)
    assert guessed.range_guess and guessed.warnings  # a stranger's dataset within ±100
    (root / "meta" / "so101sim.json").write_text(json.dumps({"generator": "so101sim dataset"}))
    ours = read_log(root, units)
    assert not ours.range_guess and not ours.warnings
    degrees = read_log(root, units, units="degrees")
    np.testing.assert_array_equal(ours.episodes[0].measured, degrees.episodes[0].measured)
