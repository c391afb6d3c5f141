"""Reading a real arm's recording: a LeRobot dataset (v2.1 or v3.0 layout) or a so101sim CSV log.

LeRobot datasets keep ``meta/info.json`` (``fps``, ``features`` with the joint ``names``) and
parquet files under ``data/`` (v2.1: ``data/chunk-XXX/episode_XXXXXX.parquet``, one file per
episode; v3.0: ``data/chunk-XXX/file-XXX.parquet``, many episodes per file). Every parquet
file under ``data/`` is read (pyarrow) and its rows grouped by ``episode_index`` and ordered by
``frame_index``: both layouts read the same way. ``action`` is the command (the leader's
pose), ``observation.state`` what the follower measured.

Units (``units``). A follower run with ``use_degrees=True`` (so101sim's simulated follower, and
LeRobot's when asked) records body joints in degrees and the gripper on 0–100: so101sim's own
units, read as they are (``"degrees"``; a calibration JSON is refused there). LeRobot's default
(range mode, ``"range"``) records body joints on −100..100 of the calibrated range: with
LeRobot's calibration JSON (``range_min``, ``range_max`` per motor) they become degrees from the
pose the arm was placed in when calibrated, the model's zero
(:func:`~so101sim.fidelity.calibration.calibration_of`); without it they are read as a typical
arm's (:data:`~so101sim.fidelity.calibration.RANGE_GUESS`), with a warning (an approximation:
each arm's calibrated range is its own).
``"auto"`` (the default): range mode when a calibration is given (a body joint beyond ±100 is
then an error); degrees when a body joint reads beyond ±100; otherwise range mode (LeRobot's
default), with a warning saying so.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import SettingError
from ..units import ArmUnits
from .calibration import lerobot_calibration_path
from .csvlog import read_csv_log
from .lerobotlog import read_lerobot
from .logdata import MAX_EPISODES, MAX_FRAMES, ArmLog, Episode, LogError

__all__ = ["MAX_FRAMES", "ArmLog", "Episode", "LogError", "parse_episodes", "read_log"]


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
    robot_id: str | None = None,
) -> ArmLog:
    """The recording at ``path`` (a LeRobot dataset folder, or a so101sim CSV log) in the arm's
    units, its ``episodes`` (all by default). ``arm_units`` are the model's (for range-mode
    data without a calibration); ``units``: ``"auto"``, ``"degrees"`` or ``"range"`` (above).
    ``robot_id``: the follower's LeRobot id, whose calibration JSON is read from LeRobot's
    folder (:func:`~so101sim.fidelity.calibration.lerobot_calibration_path`) when
    ``calibration`` is not given.

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
    if robot_id is not None:
        if calibration is not None:
            raise LogError("give --calibration or --robot-id, not both")
        if units != "degrees" and p.is_dir():  # a CSV log is in degrees already
            calibration = lerobot_calibration_path(robot_id)
    if units == "degrees" and calibration is not None:
        raise LogError("--calibration converts range-mode data; degrees need none")
    if p.is_dir():
        return read_lerobot(p, episodes, calibration, units)
    if p.is_file() and p.suffix.lower() == ".csv":
        if calibration is not None:
            raise LogError("--calibration applies to LeRobot datasets; a CSV log is in arm units")
        if units == "range":
            raise LogError("a so101sim CSV log is in degrees; units = range does not apply")
        return read_csv_log(p, episodes)
    raise LogError(
        f"log {str(p)!r} is neither a LeRobot dataset folder (meta/info.json and data/*.parquet) "
        "nor a so101sim CSV log (.csv)"
    )
