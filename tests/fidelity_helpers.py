"""Making recordings of a hidden "true" arm for the fidelity tests: commands, the measured
poses the true arm gives, written as LeRobot datasets (v2.1 and v3.0 layouts, with pyarrow,
without lerobot) or so101sim CSV logs."""

from __future__ import annotations

import copy
import json
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

from so101sim.fidelity.compare import replay_episode
from so101sim.fidelity.logs import Episode
from so101sim.model.arm import ArmProfile, load_profile
from so101sim.model.load import load_model
from so101sim.sim import Simulation
from so101sim.units import JOINT_NAMES

FPS = 30.0
CENTRES = np.array([0.0, -40.0, 40.0, 20.0, 0.0, 30.0])
AMPLITUDES = np.array([30.0, 40.0, 40.0, 30.0, 40.0, 30.0])


def true_arm() -> ArmProfile:
    """The hidden arm: the sts3215 profile with a stiffer, less damped shoulder, a softer elbow
    and a longer delay (47 ms)."""
    start = load_profile("sts3215")
    joints = {k: dict(v) for k, v in start.joints.items()}
    joints["shoulder_lift"] = {"kp_per_p": 1.4, "damping": 0.8}
    joints["elbow_flex"] = {"kp_per_p": 0.8}
    return replace(start, name="true", servo=replace(start.servo, delay_s=0.047), joints=joints)


def commands(seed: int, seconds: float = 3.0, fps: float = FPS) -> tuple[np.ndarray, np.ndarray]:
    """Smooth random commands (arm units) at ``fps``: a sine per joint."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(seconds * fps)) / fps
    f = rng.uniform(0.3, 0.8, 6)
    ph = rng.uniform(0.0, 6.0, 6)
    cmd = CENTRES + AMPLITUDES * np.sin(2 * np.pi * f * t[:, None] + ph)
    return t, cmd


def record(
    arm: ArmProfile,
    seeds: list[int],
    seconds: float = 3.0,
    load_friction: float = 0.0,
    every_step: bool = True,
) -> list[Episode]:
    """Episodes of ``arm`` following :func:`commands` for each seed, from the first command.
    ``load_friction`` k: a gearbox whose Coulomb friction grows with the load (Rhoban's BAM
    M3-M6), each joint's friction ``frictionloss + k * |servo torque|`` at every step (a
    profile's ``load_friction`` sets it every 10 ms: the hidden arm is not one the fit can be
    exactly); ``every_step=False``: the profile's ``load_friction`` (an arm the fit can be)."""
    if load_friction and not every_step:
        arm = replace(arm, servo=replace(arm.servo, load_friction=load_friction))
        load_friction = 0.0
    if not load_friction:
        sim = Simulation(arm=arm)
        replay = replay_episode
    else:
        sim = Simulation(copy.copy(load_model(arm=arm)))
        replay = partial(_replay_loaded, k=load_friction, base=sim.model.dof_frictionloss.copy())
    out = []
    for i, seed in enumerate(seeds):
        t, cmd = commands(seed, seconds)
        meas = replay(sim, Episode(i, t, cmd, np.tile(cmd[0], (len(t), 1))))
        out.append(Episode(i, t, cmd, meas))
    return out


def _replay_loaded(sim: Simulation, episode: Episode, k: float, base: np.ndarray) -> np.ndarray:
    """:func:`replay_episode` one physics step at a time, the friction set from the load."""
    idx, m, d = sim.index, sim.model, sim.data
    step = sim.step

    def one_at_a_time(n: int, trace: bool = False) -> None:
        for _ in range(n):  # the coming step's friction from the servos' last torque
            m.dof_frictionloss[idx.dof] = base[idx.dof] + k * np.abs(d.actuator_force[idx.actuator])
            step(1, trace=trace)

    sim.step = one_at_a_time
    try:
        return replay_episode(sim, episode)
    finally:
        del sim.step


def write_lerobot(root: Path, episodes: list[Episode], *, version: str = "v3.0",
                  transform=None) -> Path:  # fmt: skip
    """A LeRobot dataset of ``episodes`` at ``root`` (``meta/info.json``, parquet data).
    ``transform(values)`` maps arm units to what is stored (range mode)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    names = [f"{n}.pos" for n in JOINT_NAMES]
    feats = {
        "action": {"dtype": "float32", "shape": [6], "names": names},
        "observation.state": {"dtype": "float32", "shape": [6], "names": names},
        "timestamp": {"dtype": "float32", "shape": [1], "names": None},
        "frame_index": {"dtype": "int64", "shape": [1], "names": None},
        "episode_index": {"dtype": "int64", "shape": [1], "names": None},
        "index": {"dtype": "int64", "shape": [1], "names": None},
        "task_index": {"dtype": "int64", "shape": [1], "names": None},
    }
    (root / "meta").mkdir(parents=True)
    info = {"codebase_version": version, "robot_type": "so_follower", "fps": int(FPS),
            "features": feats}  # fmt: skip
    (root / "meta" / "info.json").write_text(json.dumps(info))
    tf = transform or (lambda v: v)

    def table(eps: list[Episode], start: int) -> pa.Table:
        rows: dict[str, list] = {k: [] for k in feats}
        index = start
        for ep in eps:
            for k in range(len(ep.times)):
                rows["action"].append(np.float32(tf(ep.command[k])).tolist())
                rows["observation.state"].append(np.float32(tf(ep.measured[k])).tolist())
                rows["timestamp"].append(float(np.float32(ep.times[k])))
                rows["frame_index"].append(k)
                rows["episode_index"].append(ep.index)
                rows["index"].append(index)
                rows["task_index"].append(0)
                index += 1
        return pa.table(
            {k: pa.array(v, type=pa.list_(pa.float32()) if k in ("action", "observation.state")
                         else (pa.float32() if k == "timestamp" else pa.int64()))
             for k, v in rows.items()}
        )  # fmt: skip

    data = root / "data" / "chunk-000"
    data.mkdir(parents=True)
    if version.startswith("v3"):
        pq.write_table(table(episodes, 0), data / "file-000.parquet")
    else:
        start = 0
        for ep in episodes:
            pq.write_table(table([ep], start), data / f"episode_{ep.index:06d}.parquet")
            start += len(ep.times)
    return root


def write_csv(path: Path, ep: Episode) -> Path:
    """A so101sim CSV log of one episode, as so101sim's --log writes it: each row's measurement
    is the state after its command acted (the episode's next measured state), after a first
    row holding the starting state; read back, it is the episode less its last frame."""
    cols = ["time", "phase"]
    for n in JOINT_NAMES:
        cols += [f"{n}_commanded", f"{n}_measured"]
    lines = [",".join(cols)]
    dt = float(ep.times[1] - ep.times[0])
    rows = [(float(ep.times[0]) - dt, ep.command[0], ep.measured[0])]
    rows += [
        (float(ep.times[k]), ep.command[k], ep.measured[k + 1]) for k in range(len(ep.times) - 1)
    ]
    for t, cmd, meas in rows:
        vals = [f"{t:.4f}", "replay"]
        for j in range(len(JOINT_NAMES)):
            vals += [f"{cmd[j]:.6f}", f"{meas[j]:.6f}"]
        lines.append(",".join(vals))
    path.write_text("\n".join(lines) + "\n")
    return path


TRUE_CALIBRATION = {
    "shoulder_lift": {"scale": 1.06, "offset": 3.0},
    "elbow_flex": {"scale": 0.94, "offset": -4.0},
    "wrist_flex": {"scale": 1.04, "offset": 2.5},
}
"""The hidden arm's calibration errors: a joint reads ``scale`` × its angle + ``offset``."""


def as_read(episodes: list[Episode], cal: dict, blocked: tuple[float, float] | None = None):
    """``episodes`` as a miscalibrated follower reads them (``cal``), and, over ``blocked``
    (s), a gripper closing on an object: commanded shut (5) but held at 40."""
    from so101sim.fidelity.calibration import to_log

    out = []
    for ep in episodes:
        cmd, meas = to_log(ep.command, cal), to_log(ep.measured, cal)
        if blocked is not None:
            m = (ep.times >= blocked[0]) & (ep.times < blocked[1])
            cmd[m, 5], meas[m, 5] = 5.0, 40.0
        out.append(Episode(ep.index, ep.times, cmd, meas))
    return out


def range_mode():
    """A transform of arm units to LeRobot's range mode as a typical arm reads it (the inverse
    of what ``compare`` and ``fit`` assume without a calibration JSON)."""
    from so101sim.fidelity.calibration import range_guess

    scale, offset = range_guess()

    def tf(values):
        v = np.array(values, dtype=float).copy()
        v[:5] = (v[:5] - offset) / scale
        return v

    return tf
