"""Reading a real arm's recording: a LeRobot dataset (v2.1 or v3.0 layout) or a so101sim CSV log.

LeRobot datasets keep ``meta/info.json`` (``fps``, ``features`` with the joint ``names``) and
parquet files under ``data/`` (v2.1: ``data/chunk-XXX/episode_XXXXXX.parquet``, one file per
episode; v3.0: ``data/chunk-XXX/file-XXX.parquet``, many episodes per file). Every parquet
file under ``data/`` is read (pyarrow) and its rows grouped by ``episode_index`` and ordered by
``frame_index``: both layouts read the same way. ``action`` is the command (the leader's
pose), ``observation.state`` what the follower measured.

Units (``units``). A follower run with ``use_degrees=True`` (so101sim's simulated follower, and
LeRobot's when asked) records body joints in degrees (0 in the middle of the calibrated range)
and the gripper on 0–100: so101sim's own units, read as they are (``"degrees"``). LeRobot's
default (range mode, ``"range"``) records body joints on −100..100 of the calibrated range:
with LeRobot's calibration JSON (``range_min``, ``range_max`` per motor) they become degrees
exactly as LeRobot computes them; without it they are mapped linearly onto the model's joint
ranges, with a warning (an approximation: the real calibrated range is not the model's).
``"auto"`` (the default): range mode when a calibration is given; degrees when a body joint
reads beyond ±100; otherwise range mode (LeRobot's default), with a warning saying so.
"""

from __future__ import annotations

import csv
import json
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import CalibrationError, SettingError
from ..units import JOINT_NAMES, LEROBOT_SUFFIX, ArmUnits
from .deps import need

log = logging.getLogger(__name__)

__all__ = ["ArmLog", "Episode", "LogError", "parse_episodes", "read_log"]

MAX_FRAMES = 5_000_000
MAX_EPISODES = 100_000
TICKS_PER_TURN = 4096
DEGREE_TICKS = 4095  # LeRobot's degrees: (ticks - middle) * 360 / 4095


class LogError(SettingError):
    """A recording that cannot be read: missing files, columns or joints, bad units."""


@dataclass(frozen=True)
class Episode:
    """One episode: ``times`` (s, from 0), ``command`` and ``measured`` (``(n, 6)``, arm units:
    degrees, gripper 0–100)."""

    index: int
    times: np.ndarray
    command: np.ndarray
    measured: np.ndarray


@dataclass(frozen=True)
class ArmLog:
    """A recording: its rate, its episodes, where it came from and what was assumed
    (``warnings``: the caller shows them; the CLI prints them on standard error)."""

    fps: float
    episodes: list[Episode]
    source: str
    kind: str  # "lerobot-v2.1" | "lerobot-v3.0" | "csv"
    warnings: list[str] = field(default_factory=list)

    @property
    def frames(self) -> int:
        return sum(len(e.times) for e in self.episodes)


def parse_episodes(text: str, *, limit: int = MAX_EPISODES) -> list[int]:
    """``"0-1,3"`` -> ``[0, 1, 3]`` (sorted, unique).

    Raises:
        SettingError: not a list of whole numbers and ranges.
    """
    if not str(text).strip():
        raise SettingError("--episodes is empty; expected episodes such as 0-1,3 (or leave it out)")
    out: set[int] = set()
    for part in str(text).split(","):
        part = part.strip()
        try:
            if "-" in part:
                a, b = (int(x) for x in part.split("-", 1))
            else:
                a = b = int(part)
        except ValueError:
            raise SettingError(
                f"--episodes {text!r}: {part!r} is not a whole number or a range; expected "
                "e.g. 0-1,3"
            ) from None
        if a < 0 or b < a or b >= limit:
            raise SettingError(
                f"--episodes {text!r}: {part!r} is not a range of episodes >= 0 (first <= last, "
                f"< {limit}); expected e.g. 0-1,3"
            )
        if len(out) + (b - a + 1) > limit:
            raise SettingError(f"--episodes {text!r} names more than {limit} episodes")
        out.update(range(a, b + 1))
    return sorted(out)


def read_log(
    path: str | Path,
    arm_units: ArmUnits,
    *,
    episodes: list[int] | None = None,
    calibration: str | Path | None = None,
    units: str = "auto",
) -> ArmLog:
    """The recording at ``path`` (a LeRobot dataset folder, or a so101sim CSV log) in the arm's
    units, its ``episodes`` (all by default). ``arm_units`` are the model's (for range-mode
    data without a calibration); ``units``: ``"auto"``, ``"degrees"`` or ``"range"`` (above).

    Raises:
        LogError: the path is neither, or lacks what is needed.
        MissingDependencyError: pyarrow is needed and missing.
    """
    if not str(path).strip():
        raise LogError("the log path is empty; expected a LeRobot dataset folder or a CSV log")
    p = Path(path).expanduser()
    if not p.exists():
        raise LogError(
            f"log {str(p)!r} does not exist; expected a LeRobot dataset folder "
            "(meta/info.json and data/*.parquet) or a so101sim CSV log (.csv)"
        )
    if units not in ("auto", "degrees", "range"):
        raise LogError(f"units = {units!r} is invalid; expected auto, degrees or range")
    if units == "degrees" and calibration is not None:
        raise LogError("--calibration converts range-mode data; degrees need none")
    if p.is_dir():
        return _read_lerobot(p, arm_units, episodes, calibration, units)
    if p.is_file() and p.suffix.lower() == ".csv":
        if calibration is not None:
            raise LogError("--calibration applies to LeRobot datasets; a CSV log is in arm units")
        if units == "range":
            raise LogError("a so101sim CSV log is in degrees; units = range does not apply")
        return _read_csv(p, episodes)
    raise LogError(
        f"log {str(p)!r} is neither a LeRobot dataset folder (meta/info.json and data/*.parquet) "
        "nor a so101sim CSV log (.csv)"
    )


# ---------------------------------------------------------------------------- LeRobot
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
            f"{', '.join(n + LEROBOT_SUFFIX for n in JOINT_NAMES)} (it has {', '.join(names)})"
        )
    return [clean.index(j) for j in JOINT_NAMES]


def _read_lerobot(
    root: Path,
    units: ArmUnits,
    episodes: list[int] | None,
    calibration: str | Path | None,
    mode: str,
) -> ArmLog:
    info_path = root / "meta" / "info.json"
    try:
        info = json.loads(info_path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise LogError(
            f"{str(root)!r} has no meta/info.json; expected a LeRobot dataset folder"
        ) from None
    except (OSError, ValueError) as exc:
        raise LogError(f"{str(info_path)!r} cannot be read: {exc}") from exc
    feats = info.get("features", {}) if isinstance(info, dict) else None
    if not isinstance(feats, dict) or not all(
        isinstance(feats.get(k, {}), dict) for k in ("action", "observation.state")
    ):
        raise LogError(
            f"{str(info_path)!r} is not a LeRobot info.json: expected an object whose "
            "'features' map names ('action', 'observation.state') to objects"
        )
    version = str(info.get("codebase_version", "v3.0"))
    fps = info.get("fps")
    if not isinstance(fps, int | float) or not 0 < fps <= 10_000:
        raise LogError(f"{str(info_path)!r}: fps = {fps!r}; expected a rate in Hz (0 < fps)")
    feats = info.get("features", {})
    for key in ("action", "observation.state"):
        if key not in feats:
            raise LogError(
                f"{str(root)!r} has no {key!r} feature; expected a LeRobot SO-101 recording "
                "(action = command, observation.state = measured)"
            )
    order_a = _joint_order(feats["action"].get("names"), "action")
    order_s = _joint_order(feats["observation.state"].get("names"), "observation.state")
    files = sorted((root / "data").rglob("*.parquet"))
    if not files:
        raise LogError(f"{str(root)!r} has no parquet files under data/")
    pq = need("pyarrow.parquet", "pyarrow")
    cols = ["action", "observation.state", "episode_index", "frame_index", "timestamp"]
    parts: dict[str, list[np.ndarray]] = {c: [] for c in cols}
    total = 0
    for f in files:
        try:
            table = pq.read_table(f, columns=[c for c in cols if c != "timestamp"] + (
                ["timestamp"] if "timestamp" in pq.read_schema(f).names else []))  # fmt: skip
        except Exception as exc:  # pyarrow raises its own kinds
            raise LogError(f"{str(f)!r} cannot be read as parquet with {cols[:4]}: {exc}") from exc
        total += table.num_rows
        if total > MAX_FRAMES:
            raise LogError(f"{str(root)!r} holds more than {MAX_FRAMES} frames; too many")
        for c in cols:
            if c in table.column_names:
                parts[c].append(_column(table.column(c), c, f))
    act = np.concatenate(parts["action"])
    obs = np.concatenate(parts["observation.state"])
    if act.ndim != 2 or obs.ndim != 2:
        raise LogError(f"{str(root)!r}: action/observation.state are not vectors per frame")
    act, obs = act[:, order_a], obs[:, order_s]
    if not (np.isfinite(act).all() and np.isfinite(obs).all()):
        raise LogError(
            f"{str(root)!r}: action or observation.state holds values that are not finite "
            "numbers (NaN or infinity); expected joint positions"
        )
    ep = np.concatenate(parts["episode_index"]).astype(int)
    fr = np.concatenate(parts["frame_index"]).astype(int)
    ts = np.concatenate(parts["timestamp"]) if parts["timestamp"] else fr / float(fps)
    if not np.isfinite(ts).all():
        raise LogError(f"{str(root)!r}: a timestamp is not a finite number; expected seconds")
    warnings: list[str] = []
    act, obs = _to_arm_units(act, obs, mode, units, calibration, warnings)
    available = sorted(set(ep.tolist()))
    chosen = _choose(available, episodes, str(root))
    out = []
    for e in chosen:
        sel = np.flatnonzero(ep == e)
        sel = sel[np.argsort(fr[sel], kind="stable")]
        if len(sel) < 2:
            warnings.append(f"episode {e} has {len(sel)} frame; skipped")
            continue
        t = ts[sel] - ts[sel[0]]
        out.append(Episode(e, t, act[sel], obs[sel]))
    if not out:
        raise LogError(f"{str(root)!r}: no episode with two frames or more among {chosen}")
    kind = "lerobot-v2.1" if version.startswith("v2") else "lerobot-v3.0"
    return ArmLog(float(fps), out, str(root), kind, warnings)


def _column(col, name: str, path: Path) -> np.ndarray:
    """A parquet column as floats: ``(rows,)``, or ``(rows, n)`` for a list column."""
    import pyarrow as pa

    col = col.combine_chunks() if isinstance(col, pa.ChunkedArray) else col
    if (
        pa.types.is_list(col.type)
        or pa.types.is_fixed_size_list(col.type)
        or (pa.types.is_large_list(col.type))
    ):
        n = len(col)
        flat = col.flatten().to_numpy(zero_copy_only=False).astype(float)
        if n and flat.size % n:
            raise LogError(f"{str(path)!r}: {name} has vectors of different lengths")
        return flat.reshape(n, -1 if n else 0)
    return col.to_numpy(zero_copy_only=False).astype(float)


def _choose(available: list[int], episodes: list[int] | None, where: str) -> list[int]:
    if episodes is None:
        return available
    missing = [e for e in episodes if e not in available]
    if missing:
        has = f"episode {available[0]}" if len(available) == 1 else f"episodes {_ranges(available)}"
        raise LogError(
            f"{where} has no episode {', '.join(map(str, missing))}; expected one of its {has}"
            if available
            else f"{where} has no episodes at all"
        )
    return list(episodes)


def _ranges(values: list[int]) -> str:
    if not values:
        return "none"
    out, start, prev = [], values[0], values[0]
    for v in [*values[1:], None]:
        if v is not None and v == prev + 1:
            prev = v
            continue
        out.append(f"{start}" if start == prev else f"{start}-{prev}")
        if v is not None:
            start = prev = v
    return ",".join(out)


def _to_arm_units(
    act: np.ndarray,
    obs: np.ndarray,
    mode: str,
    units: ArmUnits,
    calibration: str | Path | None,
    warnings: list[str],
) -> tuple[np.ndarray, np.ndarray]:
    body = np.abs(np.concatenate([act[:, :5], obs[:, :5]]))
    beyond = bool(body.max(initial=0.0) > 100.0 + 1e-6)
    if mode == "range" and beyond:
        raise LogError(
            "units = range, but a body joint reads beyond ±100; expected range-mode data "
            "(-100..100), or units = degrees"
        )
    if mode == "degrees" or (mode == "auto" and calibration is None and beyond):
        return act, obs
    if mode == "auto" and calibration is None:
        msg = (
            "every body joint reads within ±100: taken as LeRobot's range mode (-100..100); "
            "if the follower recorded degrees (use_degrees=True) give --units degrees"
        )
        warnings.append(msg)
    if calibration is not None:
        scale = _calibration_scale(Path(calibration).expanduser())
        act, obs = act.copy(), obs.copy()
        act[:, :5] *= scale
        obs[:, :5] *= scale
        return act, obs
    lo, hi = units.limits
    span = (hi - lo)[:5] / 200.0
    mid = ((hi + lo) / 2)[:5]
    msg = (
        "the body joints look range-normalised (-100..100) and no --calibration was given: "
        "mapped linearly onto the model's joint ranges (approximate; give LeRobot's "
        "calibration JSON for exact degrees)"
    )
    warnings.append(msg)
    act, obs = act.copy(), obs.copy()
    act[:, :5] = mid + act[:, :5] * span
    obs[:, :5] = mid + obs[:, :5] * span
    return act, obs


def _calibration_scale(path: Path) -> np.ndarray:
    """Degrees per range unit of each body joint from LeRobot's calibration JSON: a range value
    v maps to ticks ``min + (v + 100) / 200 · (max − min)``, and degrees are ticks from the
    middle of the range times 360/4095 (LeRobot's ``use_degrees``), so ``v · (max − min) / 200
    · 360 / 4095``."""
    try:
        cal = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CalibrationError(
            f"calibration file {str(path)!r} does not exist; expected LeRobot's calibration "
            "JSON (e.g. ~/.cache/huggingface/lerobot/calibration/robots/so_follower/<id>.json)"
        ) from None
    except (OSError, ValueError) as exc:
        raise CalibrationError(f"calibration file {str(path)!r} cannot be read: {exc}") from exc
    scale = np.empty(5)
    for i, name in enumerate(JOINT_NAMES[:5]):
        m = cal.get(name) if isinstance(cal, dict) else None
        try:
            lo, hi = float(m["range_min"]), float(m["range_max"])  # type: ignore[index]
        except (TypeError, KeyError, ValueError):
            raise CalibrationError(
                f"calibration file {str(path)!r} has no range_min/range_max for {name!r}; "
                "expected LeRobot's calibration JSON with every motor"
            ) from None
        if not (0 <= lo < hi <= TICKS_PER_TURN) or not math.isfinite(hi):
            raise CalibrationError(
                f"calibration file {str(path)!r}: {name} range {lo}..{hi} is invalid; expected "
                f"0 <= range_min < range_max <= {TICKS_PER_TURN}"
            )
        scale[i] = (hi - lo) / 200.0 * 360.0 / DEGREE_TICKS
    return scale


# ---------------------------------------------------------------------------- CSV
def _read_csv(path: Path, episodes: list[int] | None) -> ArmLog:
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            kinds = ("commanded", "measured")
            need_cols = ["time"] + [f"{n}_{k}" for n in JOINT_NAMES for k in kinds]
            missing = [c for c in need_cols if c not in (reader.fieldnames or [])]
            if missing:
                raise LogError(
                    f"CSV log {str(path)!r} lacks the columns {', '.join(missing[:3])}; expected "
                    "a log written by so101sim (--log)"
                )
            rows = []
            for i, row in enumerate(reader):
                if i >= MAX_FRAMES:
                    raise LogError(f"CSV log {str(path)!r} has more than {MAX_FRAMES} rows")
                values = [row.get(c) for c in need_cols]
                if any(v is None for v in values):
                    raise LogError(
                        f"CSV log {str(path)!r}: row {i + 2} has fewer fields than the header; "
                        "expected a log written by so101sim (--log)"
                    )
                rows.append([float(v) for v in values])
    except LogError:
        raise
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise LogError(f"CSV log {str(path)!r} cannot be read: {exc}") from exc
    if len(rows) < 3:
        raise LogError(f"CSV log {str(path)!r} has fewer than three rows")
    a = np.array(rows)
    if not np.isfinite(a).all():
        row = int(np.flatnonzero(~np.isfinite(a).all(axis=1))[0]) + 2
        raise LogError(
            f"CSV log {str(path)!r}: row {row} holds a value that is not a finite number (NaN or "
            "infinity); expected times, commands and measurements"
        )
    _choose([0], episodes, str(path))
    # so101sim's --log writes each row's measurement after that row's command has acted (one
    # physics step later); a recording pairs each command with the state read before it
    # (LeRobot's order, what the replay assumes): frame k is row k's command with row k-1's
    # measurement, so the first row gives only the first measured state.
    t = a[1:, 0] - a[1, 0]
    cmd = a[1:, 1::2][:, : len(JOINT_NAMES)]
    meas = a[:-1, 2::2][:, : len(JOINT_NAMES)]
    dt = np.diff(t)
    if (dt <= 0).any():
        raise LogError(f"CSV log {str(path)!r}: times do not increase")
    fps = 1.0 / float(np.median(dt))
    return ArmLog(fps, [Episode(0, t, cmd, meas)], str(path), "csv", [])
