"""Ren et al.'s pose perceptual loss (Eq. 1) and the ST-GCN it compares features in.

The authors pre-trained their ST-GCN on the Let's Dance dataset; no weights can be downloaded here, so this
project trains its own on the dataset's style labels (:func:`train_stgcn`, command ``dancesynth train-stgcn``)
and loads it frozen (:func:`load_stgcn`) while the Ren generator trains.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F
from torch.utils.data import DataLoader

from dancesynth.core.checkpoint import POINTER, checkpoint_files, load_checkpoint, run_file_contents
from dancesynth.core.config import config_from_dict, config_to_dict
from dancesynth.core.device import resolve_device
from dancesynth.core.errors import DancesynthError
from dancesynth.core.runs import RunFolder, epoch_order
from dancesynth.core.skeleton import ROOT
from stage1_pose.data.dataset import WindowDataset, collate
from stage1_pose.models.ren.stgcn import STGCN, STGCN_PRESETS, STGCNConfig

CHECKPOINT_KIND = "stgcn"
# The classifier reads poses only; raw waveform pieces are the audio feature that costs nothing to prepare.
FEATURE_KIND = "waveform"


class PosePerceptualLoss:
    """L_P = sum_l lambda_l * mean|Phi_l(real) - Phi_l(fake)| over the ST-GCN's blocks (Eq. 1).

    ``layer_weights`` are lambda_l for the first blocks, in order (the official 20, 5, 1, ...); the network
    must not have more blocks than weights. Deliberately not an ``nn.Module``: the frozen network's weights
    belong to its own run folder, not to the model being trained.
    """

    def __init__(self, net: STGCN, layer_weights: Sequence[float]) -> None:
        n = len(net.blocks)
        if len(layer_weights) < n:
            raise DancesynthError(f"The ST-GCN has {n} blocks but only {len(layer_weights)} perceptual layer "
                                  "weights are configured; give one weight per block.")
        self.net = net.eval().requires_grad_(False)
        self.weights = tuple(float(w) for w in layer_weights[:n])

    @classmethod
    def from_run(cls, run_dir: str | os.PathLike, layer_weights: Sequence[float],
                 device: torch.device | str = "cpu") -> "PosePerceptualLoss":
        """The loss over the ST-GCN saved in ``run_dir`` by :func:`train_stgcn`."""
        return cls(load_stgcn(run_dir, device), layer_weights)

    def __call__(self, real: torch.Tensor, fake: torch.Tensor) -> torch.Tensor:
        """``[B, T, 25, 2]`` model coordinates each -> scalar loss (0 iff every compared feature agrees)."""
        self.net.to(real.device)
        with torch.no_grad():
            target = self.net.features(real)
        return sum(w * F.l1_loss(f, t) for w, f, t in zip(self.weights, self.net.features(fake), target))


def load_stgcn(run_dir: str | os.PathLike, device: torch.device | str = "cpu") -> STGCN:
    """The ST-GCN saved by :func:`train_stgcn` in ``run_dir``, in eval mode with gradients off."""
    if not str(run_dir):
        raise DancesynthError(
            "The pose perceptual loss needs a trained ST-GCN: run `dancesynth train-stgcn --data DIR --out RUN` "
            "and give RUN as the ren method's stgcn_run, or train an ablation preset without it (e.g. local_d-small).")
    state, meta = load_checkpoint(run_dir, expected_kind=CHECKPOINT_KIND)
    with run_file_contents(Path(run_dir) / POINTER):
        net = STGCN(config_from_dict(STGCNConfig, meta["config"]))
        net.load_state_dict(state)
    return net.to(device).eval().requires_grad_(False)


def _augment(poses: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """Random uniform scale (0.8-1.2) and root shift (+-0.5 torso lengths) per sequence, so style is
    learned from the shape of the movement rather than where on the canvas or how large the dancer is."""
    b = poses.shape[0]
    scale = 0.8 + 0.4 * torch.rand(b, 1, 1, 1, generator=generator)
    shift = torch.rand(b, 1, 1, 2, generator=generator) - 0.5
    out = poses * scale.to(poses)
    out[:, :, ROOT:ROOT + 1] += shift.to(poses)
    return out


@torch.no_grad()
def _accuracy(net: STGCN, loader: DataLoader, device: torch.device) -> float:
    net.eval()
    right = total = 0
    for batch in loader:
        pred = net(batch.poses.to(device)).argmax(dim=1).cpu()
        right += int((pred == batch.style).sum())
        total += len(batch.style)
    return right / total if total else float("nan")


@dataclass
class _Position:
    """How far an ST-GCN training got: ``epoch``, ``batch`` of it, optimiser ``step`` in all, and the loss summed
    over the epoch's batches so far (its ``metrics.csv`` row is their mean)."""

    epoch: int = 0
    batch: int = 0
    step: int = 0
    loss_sum: float = 0.0


def train_stgcn(data_dir: str | os.PathLike, out_dir: str | os.PathLike, preset: str = "small",
                epochs: int | None = None, device: str = "auto", seed: int = 0,
                progress: bool = True, resume: bool = False, minutes: float | None = None) -> dict[str, float]:
    """Train the ST-GCN to classify the style of pose windows of the dataset in ``data_dir`` into the run folder
    ``out_dir`` (kind ``stgcn``, :class:`~dancesynth.core.runs.RunFolder`: a checkpoint and a ``metrics.csv``
    row after every epoch, ``loss.png``). With ``resume`` the run continues exactly where its last checkpoint
    left it, with its own preset and seed; ``epochs`` is the total (default: the preset's, or the run's),
    ``minutes`` the wall-clock training time in all; Ctrl-C or SIGTERM saves, then raises
    :class:`KeyboardInterrupt` (:meth:`~dancesynth.core.runs.RunFolder.training`). ``progress``: report the
    dataset's preparation.

    Windows are ``window_frames`` pose frames with 50 % overlap. Returns ``epochs`` (completed), ``train_accuracy``
    and ``val_accuracy`` (fractions in [0, 1] of windows whose style is recognised; NaN when the dataset has
    no validation clips), which the final checkpoint's metadata also holds.
    """
    if not resume and preset not in STGCN_PRESETS:
        raise DancesynthError(f"Unknown ST-GCN preset {preset!r}; choose one of {', '.join(STGCN_PRESETS)}.")
    if epochs is not None and epochs < 1:
        raise DancesynthError(f"--epochs must be at least 1, got {epochs}.")
    dev = resolve_device(device)
    run = RunFolder(out_dir, CHECKPOINT_KIND, dev, resume=resume)
    cfg = STGCN_PRESETS[preset] if run.meta is None else config_from_dict(STGCNConfig, run.meta["config"])
    cfg = cfg if epochs is None else replace(cfg, epochs=epochs)
    seed = seed if run.meta is None else int(run.meta["seed"])
    torch.manual_seed(seed)
    stride = max(1, cfg.window_frames // 2)
    train_set, val_set = (WindowDataset(data_dir, split, FEATURE_KIND, cfg.window_frames, stride,
                                        standardize=False, progress=progress) for split in ("train", "val"))
    styles = list(train_set.styles)
    if run.meta is not None and run.meta["styles"] != styles:
        raise DancesynthError(f"{data_dir} has the styles {styles}, but the run in {out_dir} learned "
                              f"{run.meta['styles']}; resume it with its own dataset.")
    cfg = cfg.with_classes(len(styles))
    if len(train_set) == 0:
        raise DancesynthError(f"The dataset {data_dir} has no training window of {cfg.window_frames} frames; "
                              "make longer clips with `dancesynth make-dataset --seconds`.")
    eval_loaders = [DataLoader(d, cfg.batch_size, collate_fn=collate) for d in (train_set, val_set)]

    net = STGCN(cfg).to(dev)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    optimizers = {"adam": opt}
    augment = torch.Generator().manual_seed(seed)
    at = _Position()
    if run.meta is not None:
        meta, extra = run.restore(net, optimizers)
        with run_file_contents(checkpoint_files(run.path, meta)[1]):
            at = _Position(int(meta["epoch"]), int(meta.get("batch", 0)), int(meta["step"]), float(extra["loss_sum"]))
            augment.set_state(extra["augment"])
    base_meta = {"config": config_to_dict(cfg), "styles": styles, "seed": seed, "data": str(data_dir)}

    def save() -> dict[str, Any]:
        return run.save(net, {**base_meta, "epoch": at.epoch, "batch": at.batch, "step": at.step}, optimizers,
                        {"augment": augment.get_state(), "loss_sum": at.loss_sum})

    batches_per_epoch = math.ceil(len(train_set) / cfg.batch_size)
    with run.training(save, minutes, cfg.epochs * batches_per_epoch, at.step, "train-stgcn") as session:
        net.train()
        while at.epoch < cfg.epochs and not session.stopped:
            order = epoch_order(len(train_set), seed, at.epoch)
            batches = [order[i:i + cfg.batch_size] for i in range(0, len(order), cfg.batch_size)]
            for indices in batches[at.batch:]:
                batch = collate([train_set[i] for i in indices])
                loss = F.cross_entropy(net(_augment(batch.poses, augment).to(dev)), batch.style.to(dev))
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                at.batch, at.step, at.loss_sum = at.batch + 1, at.step + 1, at.loss_sum + loss.item()
                if session.step_done(at.step, epoch=at.epoch + 1, loss=f"{loss.item():.3f}"):
                    break
            if at.batch < len(batches):
                break
            run.log("metrics", {"epoch": at.epoch, "step": at.step, "loss": at.loss_sum / len(batches)})
            at = _Position(at.epoch + 1, 0, at.step)
            save()
    if at.batch:
        save()  # the budget ran out inside an epoch
    train_acc, val_acc = (_accuracy(net, loader, dev) for loader in eval_loaders)
    run.update_meta({"train_accuracy": train_acc, "val_accuracy": val_acc})
    run.plot("loss.png")
    run.close()
    return {"epochs": at.epoch, "train_accuracy": train_acc, "val_accuracy": val_acc}
