"""Hand-ins for the tests of ``so101sim grade``, made with so101sim itself: a motion file run
headless (the physics-only model) with ``so101sim run --log``, and a stand-in video."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from so101sim.cli import main

# the lab as a motion file, with what a student may get wrong: {first, hold, back} are the
# three steps' TOML (a step left out when None)
LAB = {
    "first": 'move = "zero"\nduration = 2.0',
    "hold": "hold = 2.0",
    "back": 'move = "rest"\nduration = 2.0',
}
HANDINS = {
    "lab": {},
    "slow": {"first": 'move = "zero"\nduration = 4.0'},  # to_zero takes 4 s
    "short": {  # shoulder_lift stops 40° short of zero
        "first": "move = { shoulder_lift = -40, elbow_flex = 0, wrist_flex = 0 }\nduration = 2.0"
    },
    "no_return": {"hold": "hold = 4.0", "back": None},  # holds to the end
    "drift": {"hold": "move = { shoulder_pan = 20 }\nduration = 2.0"},  # the hold wanders
}


def motion_text(kind: str, shape: str = "linear") -> str:
    steps = {**LAB, **HANDINS[kind]}
    text = f'start = "rest"\nshape = "{shape}"\n'
    for name, body in steps.items():
        if body is not None:
            text += f'\n[[steps]]\nname = "{name}"\n{body}\n'
    return text


def make_log(folder: Path, kind: str, *, shape: str = "linear", arm: str | None = None) -> Path:
    """The CSV log of the motion ``kind`` (a key of HANDINS) run by ``so101sim run``."""
    folder.mkdir(parents=True, exist_ok=True)
    motion = folder / f"{kind}-{shape}-{arm}.toml"
    motion.write_text(motion_text(kind, shape))
    log = motion.with_suffix(".csv")
    argv = ["run", "--headless", "--log", str(log), str(motion)]
    assert main([*argv, *(["--arm", arm] if arm else [])]) == 0
    return log


def make_video(path: Path, frames: int, fps: float = 30.0) -> Path:
    """A small video of ``frames`` grey frames (what grade checks: it opens, its length)."""
    import imageio.v2 as imageio

    with imageio.get_writer(path, fps=fps, codec="libx264", macro_block_size=16) as w:
        for k in range(frames):
            w.append_data(np.full((48, 64, 3), k % 256, dtype=np.uint8))
    return path
