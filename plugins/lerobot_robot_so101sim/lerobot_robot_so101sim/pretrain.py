"""``so101sim pretrain-backbone DATASET -o DIR``: an image ACT whose ResNet-18 has first learnt
to find the cube, for ``lerobot-train --policy.path=DIR`` to go on from.

Without pretrained weights (none can be downloaded on a machine without the internet) LeRobot's
ACT starts its ResNet-18 from random weights, and how well the policy comes to read its
cameras then depends on the training seed (docs/learning.md). Here the backbone is trained
first on the dataset's own images, with labels only a simulator has: from the ``front``
image, where the cube is on the table (its position and its yaw, modulo 90°); from the
``wrist`` image and the joint states, where the cube is relative to the gripper's tip frame
(the forward kinematics of :mod:`so101sim.kinematics`). The labels come from the dataset's
``observation.environment_state`` (``so101sim dataset ... --environment-state``) and are used
for this step only: the policy written is an ACT whose inputs are the joint states and the
cameras (``observation.state`` and ``observation.images.*``), nothing a real arm cannot
sense. Two small heads (a 1×1 convolution to 32 channels, flattened, an MLP) read the
backbone's last feature map, the one ACT's transformer reads; they are dropped when done.

The output folder is what ``lerobot-train`` saves as a checkpoint's ``pretrained_model``:
``config.json``, ``model.safetensors`` (the pretrained backbone, the rest of ACT as
initialised with ``seed``) and the processors with the dataset's statistics, and
``pretrain.json`` with the settings, the held-out errors over the run (mm) and the wall time.
"""

from __future__ import annotations

import json
import logging
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from so101sim.errors import OutputPathError, SettingError
from so101sim.validation import check_count, check_range

log = logging.getLogger(__name__)

MAX_STEPS = 1_000_000
MAX_BATCH = 1024
MAX_FRAMES = 40_000
"""Frames held in memory at most (a larger dataset is subsampled evenly): 40 000 frames of two
160×120 cameras are 4.6 GB of bytes."""
ENV_STATE = "observation.environment_state"
FRONT, WRIST = "observation.images.front", "observation.images.wrist"
VALIDATION_EVERY = 20
"""One episode in this many is held out to measure the errors."""


@dataclass(frozen=True)
class PretrainSettings:
    """What to pretrain (checked by :meth:`checked`); the ACT's sizes are those the image
    recipe trains (docs/learning.md), and ``lerobot-train --policy.path`` keeps them."""

    dataset: str
    output: str
    repo_id: str = "local/so101sim"
    steps: int = 500
    batch_size: int = 32
    lr: float = 3e-4
    seed: int = 1
    shift: int = 4
    """Random shifts of the images by up to this many pixels (edges repeated)."""
    dim_model: int = 256
    dim_feedforward: int = 1024
    n_encoder_layers: int = 2
    chunk_size: int = 30
    max_frames: int = MAX_FRAMES

    def checked(self) -> PretrainSettings:
        check_count(self.steps, "steps", minimum=1, maximum=MAX_STEPS)
        check_count(self.batch_size, "batch_size", minimum=1, maximum=MAX_BATCH)
        check_range(self.lr, "lr", low=0.0, high=1.0, low_open=True)
        check_count(self.seed, "seed", maximum=2**32 - 1)
        check_count(self.shift, "shift", maximum=64, unit=" pixels")
        check_count(self.dim_model, "dim_model", minimum=8, maximum=4096)
        check_count(self.dim_feedforward, "dim_feedforward", minimum=8, maximum=16384)
        check_count(self.n_encoder_layers, "n_encoder_layers", minimum=1, maximum=64)
        check_count(self.chunk_size, "chunk_size", minimum=1, maximum=1000)
        check_count(self.max_frames, "max_frames", minimum=2, maximum=10 * MAX_FRAMES)
        if self.dim_model % 8:
            raise SettingError(
                f"dim_model = {self.dim_model} is not a multiple of 8; expected one "
                "(ACT's 8 attention heads split it)"
            )
        info = Path(self.dataset, "meta", "info.json")
        if not info.is_file():
            raise SettingError(
                f"{self.dataset!r} holds no meta/info.json; expected a LeRobotDataset folder "
                "(so101sim dataset ... -o DIR)"
            )
        features = json.loads(info.read_text()).get("features", {})
        missing = [k for k in (FRONT, WRIST, ENV_STATE, "observation.state") if k not in features]
        if missing:
            raise SettingError(
                f"the dataset {self.dataset!r} lacks {', '.join(missing)}; expected one made "
                "with --cameras front,wrist --environment-state (the cube's pose is the "
                "backbone's label)"
            )
        out = Path(self.output)
        if out.exists() and (not out.is_dir() or any(out.iterdir())):
            raise OutputPathError(
                f"{self.output!r} exists and is not an empty folder; expected a new folder "
                "for -o (or remove that one)"
            )
        return self


@dataclass(frozen=True)
class PretrainReport:
    """The result of :func:`pretrain_backbone`; errors are mean distances in mm on the held-out
    episodes (``*_baseline_mm``: those of always guessing the mean)."""

    output: str
    steps: int
    frames: int
    held_out_episodes: int
    front_error_mm: float
    wrist_error_mm: float
    front_baseline_mm: float
    wrist_baseline_mm: float
    wall_seconds: float
    history: tuple[dict[str, float], ...]


def tip_frame_positions(states: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``points`` (world, metres) in the gripper's tip frame for each row of ``states``
    (arm units), in the pick_cube scene."""
    # the scene's modules only when labels are made (importing the plugin stays light)
    from so101sim.kinematics import Kinematics
    from so101sim.scenes import SCENE_PRESETS, build_scene

    kin = Kinematics(build_scene(SCENE_PRESETS["pick_cube"]))
    out = np.zeros((len(states), 3), np.float32)
    for i, (s, c) in enumerate(zip(states, points, strict=True)):
        kin.frame_at(np.radians(s[:5]))
        p = kin.data.site_xpos[kin.tip_site]
        r = kin.data.site_xmat[kin.tip_site].reshape(3, 3)
        out[i] = r.T @ (c - p)
    return out


def _labels(env: np.ndarray, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Front labels (x, y, z, sin 4·yaw, cos 4·yaw) and wrist labels (tip frame x, y, z)."""
    cube = env[:, :3].astype(np.float64)
    from so101sim.kinematics import quat_yaw

    yaw = quat_yaw(env[:, 3:7])
    front = np.column_stack([cube, np.sin(4 * yaw), np.cos(4 * yaw)])
    return front, tip_frame_positions(states, cube).astype(np.float64)


def pretrain_backbone(
    settings: PretrainSettings, progress: Callable[[int], None] | None = None
) -> PretrainReport:
    """Pretrain the backbone (see the module's text); ``progress(step)`` after each step.

    Raises:
        SettingError, OutputPathError: see :meth:`PretrainSettings.checked`.
    """
    # torch and LeRobot only when a backbone is trained (the CLI's start-up stays light)
    import torch
    import torch.nn.functional as F
    from lerobot.configs import FeatureType, PolicyFeature
    from lerobot.datasets import LeRobotDataset
    from lerobot.policies import make_pre_post_processors
    from lerobot.policies.act.configuration_act import ACTConfig
    from lerobot.policies.act.modeling_act import ACTPolicy
    from torch import nn

    s = settings.checked()
    start = time.monotonic()
    torch.manual_seed(s.seed)
    rng = np.random.default_rng(s.seed)
    ds = LeRobotDataset(s.repo_id, root=s.dataset)
    n_all = ds.num_frames
    keep = np.unique(np.linspace(0, n_all - 1, min(n_all, s.max_frames)).round().astype(int))
    subset = torch.utils.data.Subset(ds, keep.tolist())
    workers = min(2, len(os.sched_getaffinity(0)))
    loader = torch.utils.data.DataLoader(subset, batch_size=64, num_workers=workers)
    parts: dict[str, list[Any]] = {FRONT: [], WRIST: [], "state": [], "env": [], "ep": []}
    for b in loader:
        for cam in (FRONT, WRIST):
            parts[cam].append((b[cam] * 255).round().to(torch.uint8))
        parts["state"].append(b["observation.state"].numpy())
        parts["env"].append(b[ENV_STATE].numpy())
        parts["ep"].append(b["episode_index"].numpy())
    images = {cam: torch.cat(parts[cam]) for cam in (FRONT, WRIST)}
    states = np.concatenate(parts["state"])
    episode = np.concatenate(parts["ep"])
    y_front, y_wrist = _labels(np.concatenate(parts["env"]), states)
    log.info("%d frames decoded in %.1f s", len(states), time.monotonic() - start)

    def standard(y: np.ndarray) -> tuple[Any, np.ndarray, np.ndarray]:
        mean, std = y.mean(0), y.std(0) + 1e-6
        return torch.tensor((y - mean) / std, dtype=torch.float32), mean, std

    yf, yf_mean, yf_std = standard(y_front)
    yw, yw_mean, yw_std = standard(y_wrist)
    st, _, _ = standard(states.astype(np.float64))
    held = set(np.unique(episode)[::VALIDATION_EVERY].tolist())
    val_mask = np.isin(episode, list(held))
    train_idx, val_idx = np.nonzero(~val_mask)[0], np.nonzero(val_mask)[0]
    if len(train_idx) < s.batch_size or len(val_idx) == 0:
        raise SettingError(
            f"the dataset has {len(train_idx)} training frames beside {len(val_idx)} held out "
            f"(one episode in {VALIDATION_EVERY}); expected more than batch_size = "
            f"{s.batch_size} and at least one held out"
        )
    stats = ds.meta.stats
    norm = {
        cam: tuple(
            torch.tensor(np.asarray(stats[cam][k]), dtype=torch.float32).reshape(1, 3, 1, 1)
            for k in ("mean", "std")
        )
        for cam in (FRONT, WRIST)
    }
    h, w = images[FRONT].shape[2:]
    visual = {cam: PolicyFeature(type=FeatureType.VISUAL, shape=(3, h, w)) for cam in images}
    cfg = ACTConfig(
        input_features={
            "observation.state": PolicyFeature(type=FeatureType.STATE, shape=(states.shape[1],)),
            **visual,
        },
        output_features={"action": PolicyFeature(type=FeatureType.ACTION, shape=(6,))},
        device="cpu",
        pretrained_backbone_weights=None,
        dim_model=s.dim_model,
        dim_feedforward=s.dim_feedforward,
        n_encoder_layers=s.n_encoder_layers,
        use_vae=False,
        chunk_size=s.chunk_size,
        n_action_steps=s.chunk_size,
        push_to_hub=False,
    )
    policy = ACTPolicy(cfg)
    backbone = policy.model.backbone
    with torch.no_grad():
        cells = int(np.prod(backbone(torch.zeros(1, 3, h, w))["feature_map"].shape[2:]))

    def head(extra: int, out: int) -> nn.Module:
        return nn.Sequential(nn.Linear(32 * cells + extra, 256), nn.ReLU(), nn.Linear(256, out))

    reduce = nn.ModuleDict({"f": nn.Conv2d(512, 32, 1), "w": nn.Conv2d(512, 32, 1)})
    heads = nn.ModuleDict({"f": head(0, yf.shape[1]), "w": head(st.shape[1], yw.shape[1])})
    params = [*backbone.parameters(), *reduce.parameters(), *heads.parameters()]
    opt = torch.optim.AdamW(params, lr=s.lr, weight_decay=1e-4)
    warmup = min(50, max(1, s.steps // 10))
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda k: min(1.0, (k + 1) / warmup) * 0.5 * (1 + math.cos(math.pi * k / s.steps))
    )

    def batch(cam: str, idx: np.ndarray, train: bool) -> Any:
        x = images[cam][idx].float() / 255.0
        if train and s.shift:
            pad = s.shift
            xp = F.pad(x, (pad, pad, pad, pad), mode="replicate")
            dx, dy = rng.integers(0, 2 * pad + 1, (2, len(idx)))
            x = torch.stack(
                [xp[i, :, dy[i] : dy[i] + h, dx[i] : dx[i] + w] for i in range(len(idx))]
            )
        mean, std = norm[cam]
        return (x - mean) / std

    def predict(idx: np.ndarray, train: bool) -> tuple[Any, Any]:
        ff = F.relu(reduce["f"](backbone(batch(FRONT, idx, train))["feature_map"])).flatten(1)
        fw = F.relu(reduce["w"](backbone(batch(WRIST, idx, train))["feature_map"])).flatten(1)
        return heads["f"](ff), heads["w"](torch.cat([fw, st[idx]], 1))

    def errors() -> tuple[float, float]:
        for m in (backbone, reduce, heads):
            m.eval()
        ef, ew = [], []
        with torch.no_grad():
            for i in range(0, len(val_idx), 64):
                idx = val_idx[i : i + 64]
                a, b = predict(idx, False)
                ef.append((a[:, :3] - yf[idx, :3]).numpy() * yf_std[:3])
                ew.append((b - yw[idx]).numpy() * yw_std)
        for m in (backbone, reduce, heads):
            m.train()
        return tuple(  # type: ignore[return-value]
            float(np.linalg.norm(np.concatenate(e), axis=1).mean() * 1000) for e in (ef, ew)
        )

    history = []
    for step in range(1, s.steps + 1):
        idx = rng.choice(train_idx, s.batch_size, replace=False)
        a, b = predict(idx, True)
        loss = F.mse_loss(a, yf[idx]) + F.mse_loss(b, yw[idx])
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        if step % 250 == 0 or step == s.steps:
            front_mm, wrist_mm = errors()
            history.append({"step": step, "loss": loss.item(), "front_mm": front_mm,
                            "wrist_mm": wrist_mm})  # fmt: skip
            log.info(
                "step %d: held-out error front %.1f mm, wrist %.1f mm", step, front_mm, wrist_mm
            )
        if progress is not None:
            progress(step)
    report = PretrainReport(
        output=s.output,
        steps=s.steps,
        frames=len(states),
        held_out_episodes=len(held),
        front_error_mm=history[-1]["front_mm"],
        wrist_error_mm=history[-1]["wrist_mm"],
        front_baseline_mm=float(
            np.linalg.norm(y_front[val_idx, :3] - yf_mean[:3], axis=1).mean() * 1000
        ),
        wrist_baseline_mm=float(np.linalg.norm(y_wrist[val_idx] - yw_mean, axis=1).mean() * 1000),
        wall_seconds=time.monotonic() - start,
        history=tuple(history),
    )
    _write(policy, cfg, ds.meta.stats, report, s, make_pre_post_processors)
    return report


def _write(policy: Any, cfg: Any, stats: Any, report: PretrainReport, s: PretrainSettings,
           make_processors: Callable[..., Any]) -> None:  # fmt: skip
    """The policy folder, written beside ``output`` and moved there when complete."""
    out = Path(s.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        policy.save_pretrained(tmp)
        pre, post = make_processors(policy_cfg=cfg, dataset_stats=stats)
        pre.save_pretrained(tmp)
        post.save_pretrained(tmp)
        info = {"settings": asdict(s), "report": asdict(report)}
        (tmp / "pretrain.json").write_text(json.dumps(info, indent=1) + "\n")
        if out.exists():
            out.rmdir()  # an empty folder only (checked() refused any other)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
