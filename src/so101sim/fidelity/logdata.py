"""What a recording reads into (:class:`Episode`, :class:`ArmLog`), the error a damaged or
unusable one raises (:class:`LogError`), and reading files that may be hostile: only regular
files are opened (a FIFO or a device under ``data/`` would block the reader for ever), and no
more than a bound is read of a file that should be small (``meta/info.json``, a calibration)."""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SettingError

__all__ = ["ArmLog", "Episode", "LogError", "choose_episodes", "read_small", "regular_file"]

MAX_FRAMES = 5_000_000
MAX_EPISODES = 100_000
MAX_SMALL_BYTES = 4 * 1024 * 1024
"""The most read of a file that should be small (``meta/info.json``, a calibration JSON)."""


class LogError(SettingError):
    """A recording that cannot be read or is damaged: missing files, columns or joints, bad
    units, frames that contradict each other."""


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
    range_guess: bool = False
    """True when range-mode readings were read as a typical arm's (no LeRobot calibration
    JSON): each body joint's true offset and scale are unknown."""
    stops: np.ndarray | None = None
    """Range mode: ``(2, 6)``, each joint's lower and upper reading (arm units) at the ends of
    the follower's calibration sweep, where LeRobot's −100 and 100 lie: its mechanical stops
    (NaN for the gripper). None when the recording does not tell them (degrees, CSV)."""

    @property
    def frames(self) -> int:
        return sum(len(e.times) for e in self.episodes)


def regular_file(path: Path, what: str, error: type[Exception] = LogError) -> Path:
    """``path`` if it is a regular file (after symlinks), else ``error`` naming ``what``: a FIFO,
    a socket or a device is never opened."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise error(f"{what} {str(path)!r} does not exist") from None
    except OSError as exc:
        raise error(f"{what} {str(path)!r} cannot be read: {exc}") from exc
    if not stat.S_ISREG(mode):
        raise error(
            f"{what} {str(path)!r} is not a regular file (a FIFO, device or folder); expected "
            "a file of data"
        )
    return path


def read_small(path: Path, what: str, error: type[Exception] = LogError) -> str:
    """The text of ``path`` (a regular file, UTF-8), refused when it holds more than
    :data:`MAX_SMALL_BYTES` (never read whole)."""
    regular_file(path, what, error)
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_SMALL_BYTES + 1)
    except OSError as exc:
        raise error(f"{what} {str(path)!r} cannot be read: {exc}") from exc
    if len(raw) > MAX_SMALL_BYTES:
        raise error(
            f"{what} {str(path)!r} is larger than {MAX_SMALL_BYTES // (1024 * 1024)} MB; "
            "expected a small JSON file"
        )
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{what} {str(path)!r} is not UTF-8 text: {exc}") from exc


def choose_episodes(available: list[int], episodes: list[int] | None, where: str) -> list[int]:
    """``episodes`` (all of ``available`` when None), each checked to be there."""
    if episodes is None:
        return available
    missing = [e for e in episodes if e not in available]
    if missing:
        has = f"episode {available[0]}" if len(available) == 1 else f"episodes {ranges(available)}"
        raise LogError(
            f"{where} has no episode {', '.join(map(str, missing))}; expected one of its {has}"
            if available
            else f"{where} has no episodes at all"
        )
    return list(episodes)


def ranges(values: list[int]) -> str:
    """``[0, 1, 2, 5]`` -> ``"0-2,5"``."""
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
