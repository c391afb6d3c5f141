"""Build a tiny, untrained ACT policy for a so101sim environment and save it where
``lerobot-eval --policy.path=DIR`` loads it from (the policy and its processors, as
``lerobot-train`` saves a checkpoint's ``pretrained_model``).

Its inputs and output are the environment config's features (``observation.state``,
``observation.images.<camera>``, ``action``); the normalisation statistics are set by hand
(joint angles around 0 with a spread of 60, images around 0.5), since nothing is trained:
the policy only has to run.

    python build_tiny_act.py --env-type so101sim_pick_cube --height 48 --width 64 --out DIR
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import lerobot_env_so101sim  # noqa: F401  (registers the env types)
import numpy as np
import torch
from lerobot.configs import FeatureType
from lerobot.envs.configs import EnvConfig
from lerobot.envs.utils import env_to_policy_features
from lerobot.policies import make_policy, make_pre_post_processors
from lerobot.policies.act.configuration_act import ACTConfig


def synthetic_stats(features: dict) -> dict[str, dict[str, np.ndarray]]:
    """Mean/std/min/max per feature: joints 0 ± 60, images 0.5 ± 0.25 per channel."""
    stats = {}
    for key, ft in features.items():
        if ft.type is FeatureType.VISUAL:
            shape, mean, std = (ft.shape[0], 1, 1), 0.5, 0.25
        else:
            shape, mean, std = ft.shape, 0.0, 60.0
        stats[key] = {
            "mean": np.full(shape, mean, dtype=np.float32),
            "std": np.full(shape, std, dtype=np.float32),
            "min": np.full(shape, mean - 3 * std, dtype=np.float32),
            "max": np.full(shape, mean + 3 * std, dtype=np.float32),
        }
    return stats


def build(env_cfg: EnvConfig, out: str | Path) -> tuple[Any, Any, Any]:
    """Make the policy for ``env_cfg``, save it (with its processors) in ``out``, and return
    (policy, preprocessor, postprocessor)."""
    torch.manual_seed(0)
    features = env_to_policy_features(env_cfg)
    cfg = ACTConfig(
        device="cpu",
        push_to_hub=False,
        pretrained_backbone_weights=None,  # nothing downloaded
        dim_model=32,
        n_heads=2,
        dim_feedforward=64,
        n_encoder_layers=1,
        n_decoder_layers=1,
        n_vae_encoder_layers=1,
        use_vae=False,
        chunk_size=10,
        n_action_steps=10,
    )
    cfg.output_features = {k: f for k, f in features.items() if f.type is FeatureType.ACTION}
    cfg.input_features = {k: f for k, f in features.items() if k not in cfg.output_features}
    policy = make_policy(cfg, env_cfg=env_cfg)
    pre, post = make_pre_post_processors(cfg, dataset_stats=synthetic_stats(features))
    out = Path(out)
    policy.save_pretrained(out)
    pre.save_pretrained(out)
    post.save_pretrained(out)
    return policy, pre, post


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env-type", default="so101sim_pick_cube")
    p.add_argument("--height", type=int, default=48)
    p.add_argument("--width", type=int, default=64)
    p.add_argument("--out", required=True)
    args = p.parse_args()
    env_cfg = EnvConfig.get_choice_class(args.env_type)(
        observation_height=args.height, observation_width=args.width
    )
    build(env_cfg, args.out)
    print(f"saved to {args.out}")


if __name__ == "__main__":
    main()
