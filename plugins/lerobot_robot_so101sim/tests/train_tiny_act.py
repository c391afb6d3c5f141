"""Train a tiny ACT policy on a local LeRobot dataset for a few steps, on the CPU, and save it
where ``lerobot-rollout --policy.path=DIR`` loads it from (the policy and its processors, as
``lerobot-train`` saves a checkpoint's ``pretrained_model``).

``lerobot-train`` itself needs ``lerobot[training]`` (accelerate, wandb); this does the same
few steps with LeRobot's own factories, so the test venv needs only ``lerobot[dataset]``.

    python train_tiny_act.py --root DATASET_DIR --repo-id local/name --out POLICY_DIR
"""

from __future__ import annotations

import argparse

import torch
from lerobot.datasets import LeRobotDataset
from lerobot.datasets.factory import resolve_delta_timestamps
from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata
from lerobot.policies import make_policy, make_pre_post_processors
from lerobot.policies.act.configuration_act import ACTConfig


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--root", required=True)
    p.add_argument("--repo-id", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--steps", type=int, default=3)
    args = p.parse_args()

    torch.manual_seed(0)
    meta = LeRobotDatasetMetadata(args.repo_id, root=args.root)
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
    policy = make_policy(cfg, ds_meta=meta)
    images = [k for k in policy.config.input_features if k.startswith("observation.images.")]
    assert images, "the policy has no image inputs"
    pre, post = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    dataset = LeRobotDataset(
        args.repo_id, root=args.root, delta_timestamps=resolve_delta_timestamps(cfg, meta)
    )
    loader = torch.utils.data.DataLoader(dataset, batch_size=4, shuffle=True, num_workers=0)
    optim = torch.optim.AdamW(policy.parameters(), lr=1e-4)
    policy.train()
    batches = iter(loader)
    for step in range(args.steps):
        loss, _ = policy.forward(pre(next(batches)))
        optim.zero_grad()
        loss.backward()
        optim.step()
        print(f"step {step}: loss {loss.item():.4f}")
    policy.save_pretrained(args.out)
    pre.save_pretrained(args.out)
    post.save_pretrained(args.out)
    print(f"image inputs: {', '.join(images)}; saved to {args.out}")


if __name__ == "__main__":
    main()
