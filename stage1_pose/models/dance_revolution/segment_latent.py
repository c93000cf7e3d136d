"""A latent code per segment of a dance, learned as in a conditional VAE (Kingma & Welling 2014; Sohn et al. 2015).

A dance to a given song is one of many: which move comes next is the dancer's choice, not the music's. A decoder
trained with an L1 loss against the one real dance therefore learns the median of those choices, a dance near
the mean pose, and ignores any noise it is given. Here the noise is made to carry the choices: during training a
posterior network reads the real dance and summarises each segment as a Gaussian ``q(c | dance)``; the decoder
gets a sample of it and the loss adds ``KL(q || N(0, I))``, so at generation a draw from N(0, I) per segment
chooses the moves.

Segments are given as per-frame segment ids ``[B, T]`` (int64, 0, 1, ... increasing with time): fixed runs of
frames (:func:`fixed_segments`) or the intervals between music beats (:func:`beat_segments`). Shapes: poses
``[B, T, D]``; segment codes ``[B, S, dim]``; per-frame codes ``[B, T, dim]``.
"""

from __future__ import annotations

import torch
from torch import nn

from stage1_pose.models.gaussian import kl_to_standard_normal, reparameterize


def fixed_segments(batch: int, frames: int, every: int, device: torch.device | None = None) -> torch.Tensor:
    """Segment ids ``[batch, frames]``: frames ``s*every .. (s+1)*every - 1`` form segment ``s``."""
    return (torch.arange(frames, device=device) // every).expand(batch, frames)


def beat_segments(beats: torch.Tensor) -> torch.Tensor:
    """Segment ids ``[B, T]`` from beat flags ``[B, T]`` (bool): a new segment starts at every beat frame."""
    starts = beats.clone()
    starts[:, 0] = False
    return starts.long().cumsum(dim=1)


def per_frame(codes: torch.Tensor, ids: torch.Tensor) -> torch.Tensor:
    """``[B, S, dim]`` segment codes -> ``[B, T, dim]``, each code held through its segment."""
    return codes.gather(1, ids[..., None].expand(-1, -1, codes.shape[-1]))


def prior_codes(ids: torch.Tensor, dim: int, generator: torch.Generator | None = None) -> torch.Tensor:
    """``[B, T, dim]`` codes drawn from N(0, I) per segment (on ``generator``'s device), on ``ids``' device."""
    draw_on = ids.device if generator is None else generator.device
    count = int(ids.max()) + 1 if ids.numel() else 0
    codes = torch.randn((ids.shape[0], count, dim), generator=generator, device=draw_on).to(ids.device)
    return per_frame(codes, ids)


def kl_with_free_bits(kl: torch.Tensor, free_bits: float) -> torch.Tensor:
    """``[dim]`` KL of each code number (nats) -> the KL cost (mean over numbers) in which each number's first
    ``free_bits`` nats are free (Kingma et al. 2016). Below that a number is not pushed towards the prior, so the
    posterior is not driven to carry nothing before the decoder has learned to use the code (posterior
    collapse); 0 is the plain KL."""
    return kl.clamp_min(free_bits).mean()


class SegmentPosterior(nn.Module):
    """``q(c | dance)``: a bidirectional GRU over the frames, averaged over each segment, then a linear layer
    giving the mean and log-variance of the segment's code."""

    def __init__(self, input_dim: int, dim: int, hidden: int = 64) -> None:
        super().__init__()
        self.gru = nn.GRU(input_dim, hidden, batch_first=True, bidirectional=True)
        self.out = nn.Linear(2 * hidden, 2 * dim)

    def forward(self, poses: torch.Tensor, ids: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``[B, T, input_dim]`` poses and ``[B, T]`` segment ids -> ``(mean, logvar)`` ``[B, S, dim]`` and
        which of the ``S = ids.max() + 1`` segments each sequence has (``[B, S]`` bool)."""
        feats, _ = self.gru(poses)
        count = int(ids.max()) + 1
        sums = feats.new_zeros(feats.shape[0], count, feats.shape[2]).scatter_add_(
            1, ids[..., None].expand_as(feats), feats)
        sizes = feats.new_zeros(feats.shape[0], count).scatter_add_(1, ids, torch.ones_like(ids, dtype=feats.dtype))
        mean, logvar = self.out(sums / sizes.clamp_min(1)[..., None]).chunk(2, dim=-1)
        return mean, logvar.clamp(-10.0, 10.0), sizes > 0

    def sample(self, poses: torch.Tensor, ids: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Reparameterised per-frame codes ``[B, T, dim]`` and the KL ``[dim]`` of each code number (nats per
        segment, averaged over the segments present)."""
        mean, logvar, present = self(poses, ids)
        kl = kl_to_standard_normal(mean[present], logvar[present], mean_over=0)
        return per_frame(reparameterize(mean, logvar), ids), kl
