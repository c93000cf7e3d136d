"""Noise a generator can use: held noise and the variety loss of Social GAN (Gupta et al. 2018).

An L1 (or L2) loss against the one real dance of a song is smallest for the median dance, so a generator
trained with it learns to ignore its noise (two seeds give the same dance). Charging only the draw closest to
the real dance leaves the other draws free to cover other plausible dances, so the noise comes to choose
between them.

Noise drawn afresh every frame can only make the dance shake; :func:`held_noise` draws it every few frames and
interpolates, so that it can choose a way of dancing.

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


def held_noise(batch: int, frames: int, dim: int, every: int, std: float, device: torch.device,
               generator: torch.Generator | None = None) -> torch.Tensor:
    """``[batch, frames, dim]`` Gaussian noise with standard deviation ``std`` in every frame.

    Independent draws every ``every`` frames (at a random phase), linearly interpolated and rescaled so that
    frames between two draws keep the same spread; ``every = 1`` is a fresh draw per frame. Drawn on
    ``generator``'s device (so a seed gives the same noise anywhere), returned on ``device``.
    """
    draw_on = device if generator is None else generator.device
    if every == 1:
        noise = torch.randn((batch, frames, dim), generator=generator, device=draw_on)
    else:
        knots = torch.randn((batch, frames // every + 3, dim), generator=generator, device=draw_on)
        phase = int(torch.randint(every, (1,), generator=generator, device=draw_on))
        position = (torch.arange(frames, device=draw_on) + phase) / every
        left = position.floor().long()
        w = (position - left)[None, :, None]
        noise = (knots[:, left] * (1 - w) + knots[:, left + 1] * w) / torch.sqrt(w ** 2 + (1 - w) ** 2)
    return (noise * std).to(device)
