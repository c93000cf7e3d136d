"""Diagonal Gaussian latents shared by the VAE-style methods: sampling and the KL divergence to N(0, I).

Shapes: ``mean`` and ``logvar`` (log-variance) have the same shape ``[..., dim]``.
"""

from __future__ import annotations

import torch


def reparameterize(mean: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """A sample of N(mean, exp(logvar)) that gradients flow through (Kingma & Welling 2014)."""
    return mean + torch.randn_like(mean) * torch.exp(0.5 * logvar)


def kl_to_standard_normal(mean: torch.Tensor, logvar: torch.Tensor,
                          mean_over: int | tuple[int, ...] | None = None) -> torch.Tensor:
    """``KL(N(mean, exp(logvar)) || N(0, 1))`` of every latent number, in nats, averaged over the dimensions
    ``mean_over`` (None: over all of them, a scalar)."""
    kl = 0.5 * (mean.square() + logvar.exp() - 1.0 - logvar)
    return kl.mean() if mean_over is None else kl.mean(dim=mean_over)
