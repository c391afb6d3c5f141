"""Which randomisation draws an evaluation's failures share: every scalar draw of
``so101sim eval --randomize ...``'s episodes (``eval.json``'s ``per_episode[].randomization``:
the cameras' moves and field of view, the lights, the colours, the cube's size, mass and
friction, the servos) ranked by its correlation with failure, and the success split at
the draw's median.

    # in the LeRobot venv; one or more evaluations of the same seeds (several training runs)
    python bench/eval_draws.py runs/recipe/train_pre_s5/eval_light/eval.json [more eval.json]
        [--top 10] [--split cameras.front.fovy_deg]

With several evaluations of the same episodes (the same ``--seed`` and ``--randomize``) an
episode counts the runs that failed it; an evaluation under other draws (one given after the
first with a draw held fixed, ``--randomize light,camera_fovy_deg=0`` for instance) is left
out of the ranking and only shown by ``--split``, its outcomes beside the others' on either
side of the first evaluation's draw. Each episode's scene is made again (the environment reset
with the first evaluation's settings and the episode's seed: the draws and where the cube
starts depend on these only, not on the policy), so where the objects start (``start.cube.x``,
``.y``, ``.yaw_mod90``) is compared too, and an evaluation written before every episode's draws
were kept (so101sim before 2026-12-08 dropped them for failures past ``--max-videos``) is
complete; the draws eval.json kept are checked against those drawn again. Only numbers are
compared (a texture's name is not). The p-values are from a permutation test and are not
corrected for the number of things compared (over a hundred): read a p below 0.0005 as a
lead, not a cause; the cause needs an evaluation with that draw held fixed.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

PERMUTATIONS = 20_000


def flatten(tree: Any, prefix: str = "") -> dict[str, float]:
    """Every number of a draw, named by its path (``cameras.front.fovy_deg``); lists by
    index (``lighting.scale.3``), a list of things (``distractors``) by its length."""
    out: dict[str, float] = {}
    if isinstance(tree, dict):
        for key, value in tree.items():
            out.update(flatten(value, f"{prefix}{key}."))
    elif isinstance(tree, list) and tree and all(isinstance(v, (int, float)) for v in tree):
        for i, value in enumerate(tree):
            out[f"{prefix}{i}"] = float(value)
    elif isinstance(tree, list) and all(isinstance(v, list) for v in tree) and tree:
        for i, value in enumerate(tree):
            out.update(flatten(value, f"{prefix}{i}."))
    elif isinstance(tree, list):
        out[f"{prefix}count"] = float(len(tree))
    elif isinstance(tree, (int, float)) and not isinstance(tree, bool):
        out[prefix.rstrip(".")] = float(tree)
    return out


def scenes(report: dict[str, Any], policy: str, seeds: list[int]) -> dict[int, dict[str, Any]]:
    """Each seed's draws and where its objects start (x, y in metres, the yaw modulo 90°),
    under ``report``'s settings: its environment, reset with the seed (what the draws and
    the start depend on; the policy's folder gives the cameras and image size)."""
    import lerobot_env_so101sim  # noqa: F401  (registers the env types)
    from lerobot.envs.configs import EnvConfig
    from lerobot.envs.factory import make_env
    from lerobot.policies import make_policy  # noqa: F401  (registers the policy types)

    from so101sim.kinematics import quat_yaw

    kind = f"so101sim_{report['task']}"
    cfg = EnvConfig.get_choice_class(kind)(
        policy_path=policy,
        episode_length=report.get("episode_length", 240),
        fps=report.get("fps", 30),
        randomize=report["randomize"],
        camera_file=report.get("camera_file"),
    )
    vec = make_env(cfg, n_envs=1)[kind][0]
    try:
        out = {}
        for seed in seeds:
            vec.reset(seed=[seed])
            env = vec.envs[0].unwrapped
            start = {}
            for obj in env.scene.objects:
                pose = np.asarray(env.object_pose(obj.name), dtype=float)
                yaw = float(np.degrees(quat_yaw(pose[3:]))) % 90
                start[obj.name] = {"x": pose[0], "y": pose[1], "yaw_mod90": yaw}
            drawn = json.loads(json.dumps(env.randomization, default=float))
            out[seed] = {"start": start, **drawn}
        return out
    finally:
        vec.close()


def ranks(x: np.ndarray) -> np.ndarray:
    """Average ranks (ties share theirs)."""
    order = np.argsort(x, kind="stable")
    r = np.empty(len(x))
    r[order] = np.arange(len(x), dtype=float)
    for value in np.unique(x):
        tied = x == value
        r[tied] = r[tied].mean()
    return r


def spearman(x: np.ndarray, y: np.ndarray, shuffles: np.ndarray) -> tuple[float, float]:
    """Rank correlation and its two-sided p-value over the orders ``shuffles`` (one per row)."""
    rx, ry = ranks(x), ranks(y)
    rx, ry = rx - rx.mean(), ry - ry.mean()
    scale = np.sqrt((rx**2).sum() * (ry**2).sum())
    if scale == 0:
        return 0.0, 1.0
    rho = float(rx @ ry / scale)
    perm = ry[shuffles] @ rx / scale
    hits = np.sum(np.abs(perm) >= abs(rho) - 1e-12)  # ties that differ in the last bits count
    return rho, float((hits + 1) / (len(shuffles) + 1))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("evals", nargs="+", type=Path, help="eval.json files of the same seeds")
    p.add_argument("--top", type=int, default=10, help="draws to list (10)")
    p.add_argument(
        "--split",
        action="append",
        default=[],
        help="NAME or NAME=VALUE: each run's successes on either side of a draw's median "
        "(or of VALUE), the first evaluation's draws",
    )
    args = p.parse_args()
    if not 1 <= args.top <= 1000:
        p.error(f"--top {args.top}; expected 1 to 1000")
    reports = [json.loads(f.read_text()) for f in args.evals]
    first = reports[0].get("randomize", "none")
    if first == "none":
        p.error(f"{args.evals[0]} was evaluated without --randomize; expected randomised draws")
    outcomes = [{e["seed"]: e for e in r["per_episode"]} for r in reports]
    seeds = sorted(set.intersection(*(set(o) for o in outcomes)))
    if not seeds:
        p.error("the evaluations share no seed; expected evaluations of the same episodes")
    policy = next((r["policy"] for r in reports if "policy" in r), None)
    if policy is None or not Path(policy, "config.json").is_file():
        p.error(f"policy folder {policy!r} not found; expected an eval.json that names one "
                "(to draw the scenes again)")  # fmt: skip
    # ranked: the evaluations under the first one's draws; the others are only --split
    ranked = [o for o, r in zip(outcomes, reports, strict=True) if r["randomize"] == first]
    draws = scenes(reports[0], policy, seeds)
    for s in seeds:  # the draws eval.json kept, where it kept them, are the ones drawn again
        kept = outcomes[0][s].get("randomization")
        if kept and json.dumps(kept, sort_keys=True) != json.dumps(
            {k: v for k, v in draws[s].items() if k != "start"}, sort_keys=True
        ):
            p.error(f"seed {s}: the draws drawn again differ from eval.json's (another version?)")
    failed = np.array([sum(not o[s]["success"] for o in ranked) for s in seeds], dtype=float)
    table = [flatten(draws[s]) for s in seeds]  # text (a texture's name) is left out
    names = sorted(set.intersection(*(set(t) for t in table)))
    rng = np.random.default_rng(0)
    shuffles = np.argsort(rng.random((PERMUTATIONS, len(seeds))), axis=1)
    rows = []
    for name in names:
        x = np.array([t[name] for t in table])
        if np.ptp(x) == 0:
            continue
        rho, pval = spearman(x, failed, shuffles)
        rows.append((pval, -abs(rho), name, rho, x))
    rows.sort(key=lambda r: r[:2])
    runs = len(ranked)
    print(f"{len(seeds)} episodes x {runs} runs under --randomize {first}: "
          f"{int(failed.sum())} failures; {len(rows)} draws compared")  # fmt: skip
    print("| draw | rank corr. with failure | p (permutation) | successes <= median / above |")
    print("| --- | ---: | ---: | --- |")
    for pval, _, name, rho, x in rows[: args.top]:
        low = x <= np.median(x)
        ok = runs - failed
        print(f"| {name} | {rho:+.2f} | {pval:.4f} | {int(ok[low].sum())}/{runs * low.sum()} / "
              f"{int(ok[~low].sum())}/{runs * (~low).sum()} |")  # fmt: skip
    for item in args.split:
        name, _, value = item.partition("=")
        if name not in names:
            p.error(
                f"--split {name}: no such draw; expected one of the names listed, e.g. {names[0]}"
            )
        x = np.array([t[name] for t in table])
        try:
            at = float(value) if value else float(np.median(x))
        except ValueError:
            p.error(f"--split {item}: {value!r} is not a number; expected NAME or NAME=VALUE")
        for label, mask in ((f"<= {at:.4g}", x <= at), (f"> {at:.4g}", x > at)):
            per_run = [
                sum(o[s]["success"] for s, m in zip(seeds, mask, strict=True) if m)
                for o in outcomes
            ]
            print(f"{name} {label}: {mask.sum()} episodes, successes per evaluation {per_run} "
                  f"({', '.join(r['randomize'] for r in reports)})")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
