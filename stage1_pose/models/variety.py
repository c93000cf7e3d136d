"""The variety loss of Social GAN (Gupta et al. 2018): an L1 loss on the best of K noise draws.

An L1 (or L2) loss against the one real dance of a song is smallest for the median dance, so a generator
trained with it learns to ignore its noise (two seeds give the same dance). Charging only the draw closest to
the real dance leaves the other draws free to cover other plausible dances, so the noise comes to choose
between them.

Shapes: ``preds [K, B, ...]`` (K draws for each of B examples), ``target [B, ...]``.
"""

from __future__ import annotations

import torch


def best_of(preds: torch.Tensor, target: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The draw with the smallest mean absolute error per example, and that error averaged over the batch.

    Returns ``(best [B, ...], l1)``; ``l1`` equals ``F.l1_loss(best, target)`` and its gradient reaches only
    the chosen draws. With K = 1 this is the plain L1 loss.
    """
    if preds.shape[1:] != target.shape:
        raise ValueError(f"preds {tuple(preds.shape)} must be [K, *{tuple(target.shape)}]")
    errors = (preds - target).abs().flatten(2).mean(-1)
    index = errors.argmin(0)
    best = preds[index, torch.arange(target.shape[0], device=target.device)]
    return best, errors.gather(0, index[None]).mean()
