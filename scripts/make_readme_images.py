"""Render the README's side-by-side: docs/draft.png and docs/full.png, the same pose at 640×480.

PYTHONPATH=src python scripts/make_readme_images.py
"""

from __future__ import annotations

from pathlib import Path

import imageio.v2 as imageio

import so101sim  # noqa: F401  (chooses the OpenGL backend before mujoco is imported)
from so101sim import Simulation
from so101sim.recording import FrameRenderer, VideoSettings

POSE = {
    "shoulder_pan": 0.0,
    "shoulder_lift": -20.0,
    "elbow_flex": 30.0,
    "wrist_flex": 50.0,
    "wrist_roll": 0.0,
    "gripper": 60.0,
}
DOCS = Path(__file__).resolve().parents[1] / "docs"


def main() -> None:
    sim = Simulation(initial_pose=POSE)
    for quality in ("draft", "full"):
        fr = FrameRenderer(sim.model, VideoSettings(width=640, height=480, quality=quality))
        try:
            frame = fr.render(sim.data, f"{quality}: t = 0.00 s")
            imageio.imwrite(DOCS / f"{quality}.png", frame)
        finally:
            fr.close()
        print(f"wrote {DOCS / f'{quality}.png'}")


if __name__ == "__main__":
    main()
