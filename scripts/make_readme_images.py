"""Render the README's pictures, 640×480 from the viewer's default view of the arm
(``viewer.frame_arm``): the hero picture docs/so101.png (``full`` preset, no caption) and the
side-by-side docs/draft.png and docs/full.png (one pose, each preset, captioned).

PYTHONPATH=src python scripts/make_readme_images.py
"""

from __future__ import annotations

from pathlib import Path

import imageio.v2 as imageio

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
HERO_POSE = {
    "shoulder_pan": -35.0,
    "shoulder_lift": -10.0,
    "elbow_flex": 20.0,
    "wrist_flex": 60.0,
    "wrist_roll": 0.0,
    "gripper": 50.0,
}
DOCS = Path(__file__).resolve().parents[1] / "docs"


def hero() -> None:
    sim = Simulation(initial_pose=HERO_POSE)
    settings = VideoSettings(width=640, height=480, quality="full", caption=False)
    fr = FrameRenderer(sim.model, settings)
    try:
        imageio.imwrite(DOCS / "so101.png", fr.render(sim.data))
    finally:
        fr.close()
    print(f"wrote {DOCS / 'so101.png'}")


def main() -> None:
    hero()
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
