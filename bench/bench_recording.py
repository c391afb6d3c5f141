"""Benchmark: offscreen render speed of the quality presets, and recording the lab motion.

Prints, in one run on this machine:
  0. the visual-mesh triangles each preset draws per frame (meshes counted once per geom that
     uses them, so the servo mesh counts six times) and the distinct meshes' own totals;
  1. frames/s of ``full`` and ``draft`` at 640×480 (rendering only, the arm sweeping between its
     rest pose and all zeros; draft and full interleaved in rounds so both see the same load);
  2. the wall-clock time to record the lab's 6 s motion to an MP4 (640×480, 30 fps, caption,
     draft) — physics, rendering and H.264 encoding — as a multiple of real time.

    PYTHONPATH=src python bench/bench_recording.py [--rounds 3] [--full-video]

``--full-video`` also records the lab motion with ``full`` (about a minute on a 2-core CPU).
Figures depend on the machine and on what else runs on it: the load average is printed too.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import mujoco

from so101sim import LAB_MOTION, Simulation, gl, run_motion
from so101sim.recording import FrameRenderer, Recorder, VideoSettings, render_model
from so101sim.units import STARTING_POSE, ZERO_POSE


def visual_triangles(model: mujoco.MjModel) -> tuple[int, int, int]:
    """(triangles drawn per frame, triangles of the distinct meshes drawn, distinct meshes) of
    the mesh geoms a default scene draws (groups 0-2; collision geoms are group 3)."""
    geoms = [
        g
        for g in range(model.ngeom)
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH and model.geom_group[g] < 3
    ]
    meshes = {int(model.geom_dataid[g]) for g in geoms}
    drawn = sum(int(model.mesh_facenum[model.geom_dataid[g]]) for g in geoms)
    return drawn, sum(int(model.mesh_facenum[i]) for i in meshes), len(meshes)


def frames_per_second(sim: Simulation, quality: str, frames: int) -> float:
    fr = FrameRenderer(sim.model, VideoSettings(width=640, height=480, quality=quality))
    rest = sim.units.to_radians(sim.units.pose_to_array(STARTING_POSE))
    zero = sim.units.to_radians(sim.units.pose_to_array(ZERO_POSE))
    d = sim.data
    try:
        fr.render(d, "warm-up")  # first frame uploads meshes and textures
        start = time.perf_counter()
        for i in range(frames):
            s = i / max(1, frames - 1)
            d.qpos[sim.index.qpos] = (1 - s) * rest + s * zero
            fr.render(d, f"t = {i / 30:6.2f} s   bench")
        return frames / (time.perf_counter() - start)
    finally:
        fr.close()
        sim.set_pose(STARTING_POSE)


def record_lab(quality: str, folder: Path) -> tuple[float, int]:
    sim = Simulation()
    start = time.perf_counter()
    settings = VideoSettings(width=640, height=480, fps=30, quality=quality)
    with Recorder(sim, video=folder / f"lab_{quality}.mp4", settings=settings, force=True) as rec:
        run_motion(sim.model, sim.data, LAB_MOTION, observers=rec.observers)
    return time.perf_counter() - start, rec.video.frames


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=3, help="interleaved rounds (median reported)")
    p.add_argument("--draft-frames", type=int, default=90)
    p.add_argument("--full-frames", type=int, default=8)
    p.add_argument("--full-video", action="store_true", help="also record the lab in full")
    args = p.parse_args()

    backend = gl.prepare_for_rendering()  # what the first renderer would choose
    print(f"OpenGL: MUJOCO_GL={backend} ({gl.selection}), renderer {gl.renderer_string()!r}")
    print(f"CPU cores: {os.cpu_count()}, load average before: {os.getloadavg()[0]:.2f}")
    sim = Simulation()
    print("\nvisual meshes (what each preset draws of the shipped model)")
    for quality in ("full", "draft"):
        drawn, distinct, n = visual_triangles(render_model(sim.model, quality, 640, 480))
        print(
            f"  {quality:5s} {drawn:7d} triangles drawn per frame "
            f"({n} distinct meshes, {distinct} triangles)"
        )
    t0 = time.perf_counter()
    FrameRenderer(sim.model, VideoSettings(quality="draft")).close()
    print(
        f"first draft renderer (draft model compile + GL context): {time.perf_counter() - t0:.2f} s"
    )

    fps: dict[str, list[float]] = {"full": [], "draft": []}
    for _ in range(args.rounds):
        fps["full"].append(frames_per_second(sim, "full", args.full_frames))
        fps["draft"].append(frames_per_second(sim, "draft", args.draft_frames))
    full, draft = statistics.median(fps["full"]), statistics.median(fps["draft"])
    print("\n640x480 rendering, frames/s (median of rounds; each round's value in brackets)")
    for name, value in (("full", full), ("draft", draft)):
        rounds = ", ".join(f"{v:.1f}" for v in fps[name])
        print(f"  {name:5s} {value:7.1f} frames/s  [{rounds}]")
    print(f"  draft / full: {draft / full:.1f}x")

    with tempfile.TemporaryDirectory() as tmp:
        print("\nrecording the lab motion (6.0 s simulated, 640x480, 30 fps, caption) to MP4")
        qualities = ["draft", "full"] if args.full_video else ["draft"]
        for quality in qualities:
            wall, frames = record_lab(quality, Path(tmp))
            print(
                f"  {quality:5s} {frames} frames in {wall:6.2f} s wall = "
                f"{6.0 / wall:.2f}x real time ({frames / wall:.1f} frames/s end to end)"
            )
    print(f"\nload average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
