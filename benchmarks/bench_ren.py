"""Time one Ren et al. training step and a 60-s generation per ablation preset on random tensors.

Timing only: the ST-GCN of the perceptual loss has random weights here (its cost does not depend on them).
Usage: python benchmarks/bench_ren.py [--size small|paper] [--device cpu|cuda|auto] [--steps N]
"""

from __future__ import annotations

import argparse
import time

import torch

from dancesynth.core.device import resolve_device
from stage1_pose.models.base import Batch
from stage1_pose.models.ren.model import ABLATIONS, RenConfig, RenMethod
from stage1_pose.models.ren.perceptual import PosePerceptualLoss
from stage1_pose.models.ren.stgcn import STGCN, STGCNConfig

FPS = 15


def _sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", choices=("small", "paper"), default="small")
    parser.add_argument("--device", default="auto")
    parser.add_argument("--steps", type=int, default=5)
    args = parser.parse_args()
    device = resolve_device(args.device)
    print(f"device {device}, {torch.get_num_threads()} threads")
    print(f"{'preset':<16}{'params (M)':>12}{'batch':>7}{'window':>8}{'step (s)':>10}{'60-s gen (s)':>14}")
    for row in ABLATIONS:
        name = args.size if row == "full" else f"{row}-{args.size}"
        cfg = RenConfig.preset(name)
        method = RenMethod(cfg).to(device)
        if cfg.uses_perceptual:
            stgcn = STGCN(STGCNConfig.preset(args.size))
            method.perceptual = PosePerceptualLoss(stgcn.to(device), cfg.perceptual_layer_weights)
        method._optimizers = method.configure_optimizers()
        b, t = cfg.batch_size, cfg.window_frames
        batch = Batch(torch.randn(b, t, cfg.samples_per_frame), torch.zeros(b, t, dtype=torch.bool),
                      torch.randn(b, t, 25, 2), torch.zeros(b, dtype=torch.long)).to(device)
        method.training_step(batch, 0)
        _sync(device)
        start = time.perf_counter()
        for _ in range(args.steps):
            method.training_step(batch, 0)
        _sync(device)
        step = (time.perf_counter() - start) / args.steps
        method.eval()
        song = torch.randn(1, 60 * FPS, cfg.samples_per_frame, device=device)
        start = time.perf_counter()
        method.generate(song, torch.zeros(song.shape[:2], dtype=torch.bool, device=device),
                        torch.Generator(device=device).manual_seed(0))
        _sync(device)
        gen = time.perf_counter() - start
        params = sum(p.numel() for p in method.parameters()) / 1e6
        print(f"{name:<16}{params:>12.2f}{b:>7}{t:>8}{step:>10.3f}{gen:>14.3f}")


if __name__ == "__main__":
    main()
