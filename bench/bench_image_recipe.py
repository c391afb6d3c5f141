"""docs/learning.md's image recipe, end to end, timed: demonstrations, training, evaluation.

    # in the LeRobot venv (Python 3.12, lerobot 0.6.1, so101sim and both plugins installed)
    python bench/bench_image_recipe.py --work runs/recipe [--seed 1] [--threads 1]
        [--inputs joints+cameras|cameras] [--episodes 100] [--steps 3500]
        [--eval-episodes 100] [--checkpoints 2000,3000] [--workers 2] [--skip-light] [--json FILE]
        [--pretrain-steps 500]

Runs the recipe's three commands as a user runs them (``so101sim dataset``, ``lerobot-train``,
``so101sim eval``, the executables beside this Python), each timed on the wall clock, and
prints one table: each stage's wall time, the recipe's total against the issue's two-hour
budget, and the success rates with their 95 % intervals, clean (seeds 2000+) and under
``--randomize light`` (seeds 3000+), at the last checkpoint and at each of ``--checkpoints`` (a
learning curve, clean only, ``--eval-episodes`` each; docs/learning.md's curve used 50). The
load average (1 min) before and after each stage is printed beside it: on a shared machine the
times depend on it. A dataset, training or evaluation already in ``--work`` with the same
settings is reused (its time then reads "reused"; one with other settings is refused), so a run
cut short goes on where it stopped; runs of several training seeds (``--seed``) share one
dataset. Nothing is asserted: the figures go in docs/learning.md with
the date and the machine.

The small sizes (``--episodes 3 --steps 4 --save-freq 2 --checkpoints 2 --eval-episodes 2``)
check that the pipeline runs in a few minutes; only the defaults are the recipe.

``--pretrain-steps N`` runs docs/learning.md's pretrained-backbone variant: the dataset is made
with ``--environment-state`` (the cube's pose, the pretraining's label only), ``so101sim
pretrain-backbone`` trains the backbone for N steps with the training seed, and ``lerobot-train
--policy.path`` trains on from it; the stage is timed and counted in the recipe's total. Its
dataset, backbone and runs live beside the recipe's own in ``--work`` (``data_env``,
``backbone_sN``, ``train_pre_sN``), so both can be run on one ``--work``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

RANDOMIZE = "light,textures=0.5,distractors=2"
CAMERAS = ("front", "wrist")
# What the policy reads (``--inputs``): the two cameras alone, or the joint states beside them
# (LeRobot's default, every feature of the dataset but the action).
INPUTS = {
    "cameras": [f"observation.images.{c}" for c in CAMERAS],
    "joints+cameras": [f"observation.images.{c}" for c in CAMERAS] + ["observation.state"],
}
BUDGET_S = 2 * 3600.0
LIMITS = {
    "episodes": (1, 1000),
    "steps": (1, 100_000),
    "save_freq": (1, 100_000),
    "eval_episodes": (1, 1000),
    "seed": (0, 2**31 - 1),
    "threads": (1, 256),
    "workers": (1, 64),
    "pretrain_steps": (0, 100_000),
}


def same(what: Path, got: dict, want: dict) -> None:
    """Refuse to reuse ``what`` when it was made with other settings than these."""
    differ = [f"{k} {got.get(k)!r} (asked: {v!r})" for k, v in want.items() if got.get(k) != v]
    if differ:
        raise SystemExit(
            f"{what} was made with other settings: {'; '.join(differ)}; expected the same "
            "settings to reuse it: remove it, or give another --work"
        )


def tool(name: str) -> str:
    """The console script ``name`` of this Python's environment (the venv LeRobot is in)."""
    path = Path(sys.executable).with_name(name)
    if not path.exists():
        raise SystemExit(
            f"{name} is not installed beside {sys.executable}; expected this script to run "
            "with the Python of the venv that has lerobot and so101sim's plugins"
        )
    return str(path)


def timed(cmd: list[str], log: Path, env: dict[str, str] | None = None) -> dict:
    """Run ``cmd`` with its output in ``log``; its wall time and the load around it."""
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    with log.open("w") as out:
        done = subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT, env=env, check=False)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"{cmd[0]} exited {done.returncode}; see {log}")
    return {"wall_s": round(wall, 1), "load_before": round(load0, 1),
            "load_after": round(os.getloadavg()[0], 1)}  # fmt: skip


def dataset(args: argparse.Namespace, root: Path) -> dict:
    env_state = args.pretrain_steps > 0  # the pretraining's label, recorded beside the images
    if (root / "meta" / "info.json").exists():
        made = json.loads((root / "meta" / "so101sim.json").read_text())["settings"]
        want = {"task": "pick_cube", "episodes": args.episodes, "cameras": ["front", "wrist"],
                "image_size": [120, 160], "randomize": RANDOMIZE,
                "environment_state": env_state}  # fmt: skip
        made.setdefault("environment_state", False)
        same(root, made, want)
        info = json.loads((root / "meta" / "info.json").read_text())
        return {"wall_s": None} | made_of(info)
    cmd = [tool("so101sim"), "dataset", "pick_cube", "--episodes", str(args.episodes),
           "-o", str(root), "--cameras", "front,wrist", "--image-size", "160x120",
           "--randomize", RANDOMIZE, "--no-progress"]  # fmt: skip
    if env_state:
        cmd.append("--environment-state")
    result = timed(cmd, root.parent / f"{root.name}.log")
    return result | made_of(json.loads((root / "meta" / "info.json").read_text()))


def made_of(info: dict) -> dict:
    """A dataset's episodes, frames and video codec, from its ``meta/info.json``."""
    front = info["features"]["observation.images.front"].get("info") or {}
    return {"episodes": info["total_episodes"], "frames": info["total_frames"],
            "vcodec": front.get("video.codec")}  # fmt: skip


def pretrain(args: argparse.Namespace, root: Path, out: Path) -> dict:
    """``so101sim pretrain-backbone`` for ``--pretrain-steps``, seeded with the training seed."""
    report = out / "pretrain.json"
    if report.exists():
        made = json.loads(report.read_text())["settings"]
        made["dataset"] = str(Path(made["dataset"]).resolve())  # however it was named
        want = {"steps": args.pretrain_steps, "seed": args.seed, "dataset": str(root)}
        same(out, made, want)
        return {"wall_s": None} | json.loads(report.read_text())["report"]
    if out.exists():
        raise SystemExit(f"{out} holds a pretraining that did not finish: remove it")
    cmd = [tool("so101sim"), "pretrain-backbone", str(root), "-o", str(out), "--steps",
           str(args.pretrain_steps), "--seed", str(args.seed), "--no-progress"]  # fmt: skip
    env = {**os.environ, "OMP_NUM_THREADS": str(args.threads)}
    result = timed(cmd, out.parent / f"{out.name}.log", env)
    return result | json.loads(report.read_text())["report"]


def train(args: argparse.Namespace, root: Path, out: Path, backbone: Path | None) -> dict:
    last = out / "checkpoints" / f"{args.steps:06d}" / "pretrained_model"
    if (last / "model.safetensors").exists() and (last / "train_config.json").exists():
        made = json.loads((last / "train_config.json").read_text())
        made |= {"root": str(Path(made["dataset"]["root"]).resolve()),  # however it was named
                 "inputs": sorted(made["policy"]["input_features"])}  # fmt: skip
        want = {"seed": args.seed, "steps": args.steps, "root": str(root),
                "inputs": sorted(INPUTS[args.inputs])}  # fmt: skip
        same(last, made, want)
        return {"wall_s": None}
    if out.exists():
        raise SystemExit(
            f"{out} holds a training without a finished checkpoint at step {args.steps} (cut "
            "short, or run with other --steps): remove it, or resume it with lerobot-train "
            f"--config_path={out}/checkpoints/last/pretrained_model/train_config.json "
            "--resume=true and run this again"
        )
    # from scratch, or on from the pretrained ACT (its config holds the same policy options)
    start = "--policy.type=act" if backbone is None else f"--policy.path={backbone}"
    cmd = [tool("lerobot-train"), "--dataset.repo_id=local/so101sim", f"--dataset.root={root}",
           start, "--policy.device=cpu", "--policy.push_to_hub=false",
           "--policy.pretrained_backbone_weights=null", "--policy.optimizer_lr_backbone=1e-4",
           "--policy.dim_model=256", "--policy.dim_feedforward=1024",
           "--policy.n_encoder_layers=2", "--policy.use_vae=false", "--policy.chunk_size=30",
           "--policy.n_action_steps=30", "--use_policy_training_preset=false",
           "--optimizer.type=adamw", "--optimizer.lr=1e-4", "--optimizer.weight_decay=1e-4",
           "--scheduler.type=cosine_annealing_with_warmup", "--scheduler.num_warmup_steps=100",
           f"--steps={args.steps}", "--batch_size=8", "--num_workers=0",
           f"--seed={args.seed}", f"--save_freq={args.save_freq}", f"--output_dir={out}",
           "--wandb.enable=false"]  # fmt: skip
    if args.inputs == "cameras":
        visual = {"type": "VISUAL", "shape": [3, 120, 160]}
        features = {key: visual for key in INPUTS["cameras"]}
        cmd.append(f"--policy.input_features={json.dumps(features)}")
    env = {**os.environ, "OMP_NUM_THREADS": str(args.threads)}
    return timed(cmd, out.parent / f"{out.name}.log", env)


def evaluate(args: argparse.Namespace, policy: Path, out: Path, seed: int, episodes: int,
             randomize: str | None) -> dict:  # fmt: skip
    report = out / "eval.json"
    if report.exists():
        made = json.loads(report.read_text())
        made |= {"seed": made["per_episode"][0]["seed"] if made["per_episode"] else None}
        want = {"episodes": episodes, "seed": seed, "randomize": randomize or "none"}
        same(report, made, want)
        result: dict = {"wall_s": None}
    else:
        cmd = [tool("so101sim"), "eval", str(policy), "--task", "pick_cube",
               "--episodes", str(episodes), "--seed", str(seed), "--workers", str(args.workers),
               "--no-progress", "-o", str(out)]  # fmt: skip
        if randomize:
            cmd += ["--randomize", randomize]
        result = timed(cmd, out.parent / f"{out.name}.log")
    got = json.loads(report.read_text())
    low, high = got["success_interval_95"]
    return result | {"successes": got["successes"], "episodes": got["episodes"],
                     "interval_95": [round(low, 3), round(high, 3)]}  # fmt: skip


def bounded(name: str, value: int) -> int:
    low, high = LIMITS[name]
    if not low <= value <= high:
        raise SystemExit(f"--{name.replace('_', '-')} {value}: expected {low} to {high}")
    return value


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--work", required=True, help="folder for the dataset, runs and logs")
    p.add_argument("--seed", type=int, default=1, help="the training seed (default 1)")
    p.add_argument(
        "--inputs",
        choices=sorted(INPUTS),
        default="joints+cameras",
        help="what the policy reads: the cameras and the joints (default) or the cameras alone",
    )
    p.add_argument("--threads", type=int, default=1, help="OMP_NUM_THREADS for training (1)")
    p.add_argument("--episodes", type=int, default=100, help="demonstrations (100)")
    p.add_argument("--steps", type=int, default=3500, help="training steps (3500)")
    p.add_argument("--save-freq", type=int, default=500, help="checkpoint every N steps (500)")
    p.add_argument("--eval-episodes", type=int, default=100, help="episodes per evaluation")
    p.add_argument("--checkpoints", default="", help="earlier steps to evaluate, e.g. 2000,3000")
    p.add_argument("--workers", type=int, default=2, help="worker processes (2)")
    p.add_argument("--skip-light", action="store_true", help="no randomised evaluation")
    p.add_argument("--json", help="also write the figures to this file")
    p.add_argument(
        "--pretrain-steps",
        type=int,
        default=0,
        help="pretrain the backbone this many steps first (so101sim pretrain-backbone; 0: none)",
    )
    args = p.parse_args()
    for name in LIMITS:
        bounded(name, getattr(args, name))
    try:
        curve = sorted({int(s) for s in args.checkpoints.split(",") if s.strip()})
    except ValueError:
        raise SystemExit(
            f"--checkpoints {args.checkpoints}: expected steps, e.g. 2000,3000"
        ) from None
    bad = [s for s in curve if s % args.save_freq or not 0 < s < args.steps]
    if bad:
        raise SystemExit(f"--checkpoints {bad}: expected multiples of --save-freq below --steps")

    work = Path(args.work).resolve()  # the commands are given absolute paths
    work.mkdir(parents=True, exist_ok=True)
    only = "" if args.inputs == "joints+cameras" else "_cameras"  # the recipe's own: train_sN
    pre = "_pre" if args.pretrain_steps else ""
    if pre and args.inputs != "joints+cameras":
        raise SystemExit("--pretrain-steps: expected --inputs joints+cameras (the ACT it writes)")
    root = work / ("data_env" if pre else "data")
    run = work / f"train{only}{pre}_s{args.seed}"
    figures: dict = {"date": time.strftime("%Y-%m-%d %H:%M"), "cores": os.cpu_count(),
                     "inputs": args.inputs, "pretrain_steps": args.pretrain_steps}  # fmt: skip
    figures["dataset"] = dataset(args, root)
    backbone = None
    if pre:
        backbone = work / f"backbone_s{args.seed}"
        figures["pretraining"] = pretrain(args, root, backbone)
    figures["training"] = train(args, root, run, backbone)

    def policy(step: int) -> Path:
        return run / "checkpoints" / f"{step:06d}" / "pretrained_model"

    n = args.eval_episodes
    figures["clean"] = evaluate(args, policy(args.steps), run / "eval_clean", 2000, n, None)
    if not args.skip_light:
        light = run / "eval_light"
        figures["light"] = evaluate(args, policy(args.steps), light, 3000, n, "light")
    figures["curve"] = {
        step: evaluate(args, policy(step), run / f"eval_{step:06d}", 2000, n, None)
        for step in curve
    }
    recipe = [
        figures[k]["wall_s"]
        for k in ("dataset", "pretraining", "training", "clean", "light")
        if k in figures
    ]
    figures["recipe_wall_s"] = None if None in recipe else round(sum(recipe), 1)

    def rate(r: dict) -> str:
        low, high = r["interval_95"]
        return (f"{r['successes']}/{r['episodes']} = {100 * r['successes'] / r['episodes']:.0f} %"
                f" (95 % interval {100 * low:.0f}-{100 * high:.0f} %)")  # fmt: skip

    def wall(r: dict) -> str:
        if r["wall_s"] is None:
            return "reused"
        return f"{r['wall_s'] / 60:.1f} min (load {r['load_before']} -> {r['load_after']})"

    d = figures["dataset"]
    print(f"| stage (training seed {args.seed}, inputs {args.inputs}) | wall time | figure |")
    print("| --- | --- | --- |")
    made = f"{d['episodes']} episodes, {d['frames']} frames, {d.get('vcodec')} videos"
    print(f"| dataset | {wall(d)} | {made} |")
    if "pretraining" in figures:
        r = figures["pretraining"]
        print(f"| backbone pretraining, {args.pretrain_steps} steps | {wall(r)} | held-out error: "
              f"table {r['front_error_mm']:.1f} mm (mean {r['front_baseline_mm']:.1f}), "
              f"gripper {r['wrist_error_mm']:.1f} mm ({r['wrist_baseline_mm']:.1f}) |")  # fmt: skip
    print(f"| training, {args.steps} steps | {wall(figures['training'])} | |")
    print(f"| clean, seeds 2000+ | {wall(figures['clean'])} | {rate(figures['clean'])} |")
    if "light" in figures:
        print(f"| light, seeds 3000+ | {wall(figures['light'])} | {rate(figures['light'])} |")
    for step, r in figures["curve"].items():
        print(f"| clean at {step} steps | {wall(r)} | {rate(r)} |")
    if figures["recipe_wall_s"] is not None:
        share = figures["recipe_wall_s"] / BUDGET_S
        print(f"recipe: {figures['recipe_wall_s'] / 60:.1f} min, {share:.0%} of the 2 h budget")
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=1) + "\n")


if __name__ == "__main__":
    main()
