"""Reading a LeRobot dataset (v2.1 or v3.0 layout) into episodes, trusting nothing in it.

``meta/info.json`` (``fps``, ``features`` with the joint ``names``, ``total_frames``) is read
with a bound; every parquet file under ``data/`` must be a regular file (a FIFO would block),
is read with pyarrow (page checksums verified where the writer stored them), and its rows must
agree with its own footer and, all files together, with ``total_frames``. ``action`` and
``observation.state`` must be vectors of numbers, one value per named joint, finite and within
a turn; each episode's ``frame_index`` must be 0, 1, 2, ... and its timestamps must increase.
A dataset that breaks any of this is damaged: :class:`LogError`, never a guess.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..units import JOINT_NAMES, LEROBOT_SUFFIX
from .calibration import to_arm_units
from .deps import need
from .logdata import (
    MAX_FRAMES,
    ArmLog,
    Episode,
    LogError,
    choose_episodes,
    read_small,
    regular_file,
)

__all__ = ["read_lerobot"]

COLUMNS = ("action", "observation.state", "episode_index", "frame_index")
MAX_READING = 360.0
"""The largest magnitude a joint reads in any of LeRobot's units (degrees stay within half a
turn, range mode within ±100): beyond it a value is damaged."""


def _joint_order(names: object, what: str) -> list[int]:
    """Column of each of :data:`JOINT_NAMES` in a feature whose ``names`` are given."""
    if isinstance(names, dict):  # older datasets: {"motors": [...]}
        names = next(iter(names.values()), None)
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        return list(range(len(JOINT_NAMES)))
    clean = [n.removesuffix(LEROBOT_SUFFIX) for n in names]
    missing = [j for j in JOINT_NAMES if j not in clean]
    if missing:
        raise LogError(
            f"{what} has no joint {', '.join(missing)}; expected the SO-101's joints "
            f"{', '.join(n + LEROBOT_SUFFIX for n in JOINT_NAMES)} (it has "
            f"{', '.join(names[:12])}{' ...' if len(names) > 12 else ''})"
        )
    return [clean.index(j) for j in JOINT_NAMES]


def _written_by_so101sim(root: Path) -> bool:
    """Whether ``so101sim dataset`` wrote the dataset (its ``meta/so101sim.json`` says so)."""
    path = root / "meta" / "so101sim.json"
    if not path.is_file():
        return False
    try:
        meta = json.loads(read_small(path, "meta/so101sim.json"))
    except (ValueError, LogError):
        return False
    return isinstance(meta, dict) and meta.get("generator") == "so101sim dataset"


def _info(root: Path) -> dict:
    path = root / "meta" / "info.json"
    if not path.exists():
        raise LogError(f"{str(root)!r} has no meta/info.json; expected a LeRobot dataset folder")
    try:
        info = json.loads(read_small(path, "meta/info.json"))
    except ValueError as exc:
        raise LogError(f"{str(path)!r} cannot be read: {exc}") from exc
    feats = info.get("features", {}) if isinstance(info, dict) else None
    if not isinstance(feats, dict) or not all(
        isinstance(feats.get(k, {}), dict) for k in ("action", "observation.state")
    ):
        raise LogError(
            f"{str(path)!r} is not a LeRobot info.json: expected an object whose "
            "'features' map names ('action', 'observation.state') to objects"
        )
    fps = info.get("fps")
    if not isinstance(fps, int | float) or isinstance(fps, bool) or not 0 < fps <= 10_000:
        raise LogError(f"{str(path)!r}: fps = {fps!r}; expected a rate in Hz (0 < fps)")
    for key in ("action", "observation.state"):
        if key not in feats:
            raise LogError(
                f"{str(root)!r} has no {key!r} feature; expected a LeRobot SO-101 recording "
                "(action = command, observation.state = measured)"
            )
    return info


def _read_file(pq, f: Path) -> dict[str, np.ndarray]:
    """The columns of one parquet file, checked: present, of numbers, as many rows as its
    footer says."""
    regular_file(f, "parquet file")
    try:
        pf = pq.ParquetFile(f, page_checksum_verification=True)
        names = pf.schema_arrow.names
    except Exception as exc:  # pyarrow raises its own kinds
        raise LogError(f"{str(f)!r} is not a readable parquet file: {_short(exc)}") from exc
    missing = [c for c in COLUMNS if c not in names]
    if missing:
        shown = ", ".join(names[:8]) + (" ..." if len(names) > 8 else "")
        raise LogError(
            f"{str(f)!r} has no column {', '.join(repr(c) for c in missing)}; expected "
            f"{', '.join(COLUMNS)} (it has {len(names)} columns: {shown})"
        )
    cols = [*COLUMNS, *(["timestamp"] if "timestamp" in names else [])]
    try:
        table = pf.read(columns=cols)
    except Exception as exc:  # a damaged page: checksum, decompression or decoding
        raise LogError(f"{str(f)!r} is damaged: {_short(exc)}") from exc
    if table.num_rows != pf.metadata.num_rows:
        raise LogError(
            f"{str(f)!r} is damaged: {table.num_rows} rows read, its footer says "
            f"{pf.metadata.num_rows}"
        )
    return {c: _column(table.column(c), c, f) for c in cols}


def _short(exc: Exception) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= 200 else text[:200] + " ..."


def _column(col, name: str, path: Path) -> np.ndarray:
    """A parquet column as floats: ``(rows,)``, or ``(rows, n)`` for a list column."""
    # pyarrow (an optional extra) only when a LeRobot dataset is read
    import pyarrow as pa

    col = col.combine_chunks() if isinstance(col, pa.ChunkedArray) else col
    t = col.type
    listy = pa.types.is_list(t) or pa.types.is_fixed_size_list(t) or pa.types.is_large_list(t)
    inner = t.value_type if listy else t
    if not (pa.types.is_integer(inner) or pa.types.is_floating(inner)):
        raise LogError(
            f"{str(path)!r}: {name} holds {inner}; expected numbers"
            + (" (a vector per frame)" if name in COLUMNS[:2] else "")
        )
    if col.null_count:
        raise LogError(f"{str(path)!r}: {name} has empty (null) values; expected a value per row")
    if not listy:
        if name in COLUMNS[:2]:
            raise LogError(f"{str(path)!r}: {name} is one number per frame; expected a vector")
        return col.to_numpy(zero_copy_only=False).astype(float)
    n = len(col)
    flat = col.flatten().to_numpy(zero_copy_only=False).astype(float)
    if n and flat.size % n:
        raise LogError(f"{str(path)!r}: {name} has vectors of different lengths")
    return flat.reshape(n, -1 if n else 0)


def read_lerobot(root: Path, episodes: list[int] | None, calibration, mode: str) -> ArmLog:
    """The LeRobot dataset at ``root`` in arm units (module docstring).

    Raises:
        LogError: the dataset is incomplete, damaged or not an SO-101 recording.
    """
    info = _info(root)
    feats, fps = info["features"], float(info["fps"])
    order_a = _joint_order(feats["action"].get("names"), "action")
    order_s = _joint_order(feats["observation.state"].get("names"), "observation.state")
    data = root / "data"
    files = sorted(data.rglob("*.parquet")) if data.is_dir() else []
    if not files:
        raise LogError(f"{str(root)!r} has no parquet files under data/")
    pq = need("pyarrow.parquet", "pyarrow")
    parts: dict[str, list[np.ndarray]] = {}
    total = 0
    for f in files:
        for c, v in _read_file(pq, f).items():
            parts.setdefault(c, []).append(v)
        total += len(parts["episode_index"][-1])
        if total > MAX_FRAMES:
            raise LogError(f"{str(root)!r} holds more than {MAX_FRAMES} frames; too many")
    if total == 0:
        raise LogError(f"{str(root)!r}: its parquet files hold no frames; expected a recording")
    declared = info.get("total_frames")
    if isinstance(declared, int) and not isinstance(declared, bool) and declared != total:
        raise LogError(
            f"{str(root)!r} is damaged or incomplete: its parquet files hold {total} frames, "
            f"meta/info.json says total_frames = {declared}"
        )
    act, obs = (  # the shapes first (a short vector is named as such), then the stats
        _vectors(parts, "action", order_a, root),
        _vectors(parts, "observation.state", order_s, root),
    )
    _check_stats(root, parts, total)
    ep = np.concatenate(parts["episode_index"])
    fr = np.concatenate(parts["frame_index"])
    ts = np.concatenate(parts["timestamp"]) if "timestamp" in parts else fr / fps
    if not np.isfinite(ts).all():
        raise LogError(f"{str(root)!r}: a timestamp is not a finite number; expected seconds")
    for name, v in (("episode_index", ep), ("frame_index", fr)):
        if not np.isfinite(v).all() or (v != np.round(v)).any():
            raise LogError(f"{str(root)!r}: {name} holds a value that is not a whole number")
    if ep.min() < 0 or fr.min() < 0:
        raise LogError(f"{str(root)!r}: a negative episode or frame index; the dataset is damaged")
    ep, fr = ep.astype(np.int64), fr.astype(np.int64)
    warnings: list[str] = []
    if mode == "auto" and calibration is None and _written_by_so101sim(root):
        mode = "degrees"  # `so101sim dataset` writes the body joints in degrees
    act, obs, guessed, stops = to_arm_units(act, obs, mode, calibration, warnings)
    order = np.lexsort((fr, ep))  # by episode, then frame: each episode one slice
    found, first = np.unique(ep[order], return_index=True)
    bounds = dict(zip(found.tolist(), zip(first, [*first[1:], len(order)], strict=True),
                      strict=True))  # fmt: skip
    chosen = choose_episodes(found.tolist(), episodes, str(root))
    out = []
    for e in chosen:
        sel = order[bounds[e][0] : bounds[e][1]]
        if not np.array_equal(fr[sel], np.arange(len(sel))):
            raise LogError(
                f"{str(root)!r}: episode {e}'s frame_index is not 0, 1, 2, ... (a frame "
                "duplicated or missing); the dataset is damaged"
            )
        if len(sel) < 2:
            warnings.append(f"episode {e} has {len(sel)} frame; skipped")
            continue
        t = ts[sel] - ts[sel[0]]
        if (np.diff(t) <= 0).any():
            raise LogError(
                f"{str(root)!r}: episode {e}'s timestamps do not increase; the dataset is damaged"
            )
        out.append(Episode(e, t, act[sel], obs[sel]))
    if not out:
        raise LogError(f"{str(root)!r}: no episode with two frames or more among {chosen}")
    kind = "lerobot-v2.1" if str(info.get("codebase_version", "v3.0")).startswith("v2") else (
        "lerobot-v3.0")  # fmt: skip
    return ArmLog(fps, out, str(root), kind, warnings, range_guess=guessed, stops=stops)


def _check_stats(root: Path, parts: dict, total: int) -> None:
    """The data against ``meta/stats.json`` (LeRobot's per-feature count, min, max and mean,
    computed when it was recorded), where the stats cover the same frames: a flipped byte that
    moves a value shows there (LeRobot's files carry no page checksums)."""
    path = root / "meta" / "stats.json"
    if not path.exists():
        return
    try:
        stats = json.loads(read_small(path, "meta/stats.json"))
    except ValueError as exc:
        raise LogError(f"{str(path)!r} cannot be read: {exc}") from exc
    if not isinstance(stats, dict):
        raise LogError(f"{str(path)!r} is not a LeRobot stats.json (an object per feature)")
    for name in (*COLUMNS, "timestamp"):
        st = stats.get(name)
        if name not in parts or not isinstance(st, dict):
            continue
        try:
            count = float(np.ravel(st["count"])[0])
            want = {k: np.asarray(st[k], dtype=float).ravel() for k in ("min", "max", "mean")}
            spread = np.asarray(st.get("std", 0.0), dtype=float).ravel()
        except (KeyError, TypeError, ValueError, IndexError):
            continue  # not the stats this check reads: nothing to hold the data against
        v = np.concatenate(parts[name]).reshape(total, -1)
        if count != total or any(w.shape != (v.shape[1],) for w in want.values()):
            continue  # the stats describe other frames (an edited dataset): no comparison
        got = {"min": v.min(axis=0), "max": v.max(axis=0), "mean": v.mean(axis=0)}
        for k, w in want.items():
            tol = 1e-5 * (np.abs(w) + np.resize(spread, w.shape) + 1.0)
            bad = np.abs(got[k] - w) > tol
            if bad.any():
                i = int(np.argmax(bad))
                raise LogError(
                    f"{str(root)!r} is damaged: its {name} disagrees with meta/stats.json "
                    f"({k} {got[k][i]:.6g} against {w[i]:.6g}): changed since it was recorded"
                )


def _vectors(parts: dict, name: str, order: list[int], root: Path) -> np.ndarray:
    widths = {p.shape[1] for p in parts[name] if p.ndim == 2}
    if len(widths) > 1:
        raise LogError(f"{str(root)!r}: {name} has vectors of different lengths across files")
    width = widths.pop() if widths else 0
    if width < len(JOINT_NAMES) or width <= max(order):
        raise LogError(
            f"{str(root)!r}: {name} has {width} values per frame; expected one per joint "
            f"({len(JOINT_NAMES)}: {', '.join(JOINT_NAMES)})"
        )
    v = np.concatenate(parts[name])[:, order]
    if not np.isfinite(v).all():
        raise LogError(
            f"{str(root)!r}: {name} holds values that are not finite numbers (NaN or "
            "infinity); expected joint positions"
        )
    if np.abs(v).max() > MAX_READING:
        raise LogError(
            f"{str(root)!r}: {name} holds {np.abs(v).max():.4g}, beyond any joint reading "
            f"(±{MAX_READING:g}); the dataset is damaged"
        )
    return v
