"""Local (banded) multi-head self-attention in O(n·k) memory, as Dance Revolution's music encoder needs it.

Query i attends to the keys j with ``|i - j| <= window // 2`` (the paper's k-nearest neighbours including
itself, Eq. 1-2). Instead of an n x n score matrix with a band mask, the sequence is cut into blocks of
``b = max(window // 2, 1)`` frames; the queries of a block only meet the keys of that block and its two
neighbours (3b keys), which covers the whole band. Scores therefore take ``n · 3b`` entries: linear in n.

Shapes: ``q``, ``k`` ``[..., n, d_k]``, ``v`` ``[..., n, d_v]`` (leading dims = batch, heads), n in frames.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn


def band_mask(n: int, window: int, device: torch.device | None = None) -> torch.Tensor:
    """``[n, n]`` bool, True where ``|i - j| <= window // 2`` (the reference full-attention mask)."""
    idx = torch.arange(n, device=device)
    return (idx[:, None] - idx[None, :]).abs() <= window // 2


def masked_full_attention(q: torch.Tensor, k: torch.Tensor, v: torch.Tensor, mask: torch.Tensor,
                          dropout: float = 0.0, training: bool = False) -> torch.Tensor:
    """Plain softmax attention over all n keys with a ``[n, n]`` bool mask (True = may attend); O(n²) memory.

    With ``mask = band_mask(n, window)`` this is what the authors' public code computes and the reference
    that :func:`local_attention` must equal.
    """
    scores = q @ k.transpose(-1, -2) / math.sqrt(q.shape[-1])
    scores = scores.masked_fill(~mask, torch.finfo(scores.dtype).min)
    weights = torch.softmax(scores, dim=-1)
    if dropout > 0 and training:
        weights = F.dropout(weights, dropout)
    return weights @ v


def local_attention(q: torch.Tensor, k: torch.Tensor, v: torch.Tensor, window: int,
                    dropout: float = 0.0, training: bool = False) -> torch.Tensor:
    """Attention of every position to its neighbours within ``window // 2`` frames, blockwise, O(n·window).

    ``dropout`` (on attention weights) applies only when ``training``. Returns ``[..., n, d_v]``.
    """
    n = q.shape[-2]
    half = window // 2
    b = max(half, 1)
    blocks = -(-n // b)
    pad = blocks * b - n
    lead = q.shape[:-2]
    # Queries: [..., blocks, b, d]. Keys/values get one block of padding on each side, then every block
    # sees the 3b keys around it through an overlapping (stride b) view, which copies nothing.
    qb = F.pad(q, (0, 0, 0, pad)).reshape(*lead, blocks, b, q.shape[-1])
    kp = F.pad(k, (0, 0, b, pad + b))
    vp = F.pad(v, (0, 0, b, pad + b))
    kb = kp.unfold(-2, 3 * b, b)  # [..., blocks, d_k, 3b]
    vb = vp.unfold(-2, 3 * b, b).transpose(-1, -2)  # [..., blocks, 3b, d_v]

    scores = qb @ kb / math.sqrt(q.shape[-1])  # [..., blocks, b, 3b]
    query_pos = torch.arange(blocks * b, device=q.device).reshape(blocks, b, 1)
    key_pos = (torch.arange(blocks, device=q.device)[:, None, None] * b - b
               + torch.arange(3 * b, device=q.device)[None, None, :])
    allowed = ((query_pos - key_pos).abs() <= half) & (key_pos >= 0) & (key_pos < n)
    # A finite fill keeps the padded query rows (all keys masked) finite, so no NaN reaches the gradients.
    scores = scores.masked_fill(~allowed, torch.finfo(scores.dtype).min)
    weights = torch.softmax(scores, dim=-1)
    if dropout > 0 and training:
        weights = F.dropout(weights, dropout)
    out = weights @ vb  # [..., blocks, b, d_v]
    return out.reshape(*lead, blocks * b, v.shape[-1])[..., :n, :]


class LocalSelfAttention(nn.Module):
    """Multi-head local self-attention (Dance Revolution Eq. 1-2).

    ``[B, n, d_model]`` -> ``[B, n, d_model]``: per head, Q, K (``d_k``) and V (``d_v``) projections, banded
    attention of width ``window`` frames, heads concatenated and projected back to ``d_model``.
    ``full=True`` uses the masked n x n reference instead (same result, quadratic memory; for comparison).
    """

    def __init__(self, d_model: int, heads: int, d_k: int, d_v: int, window: int, dropout: float = 0.0,
                 full: bool = False) -> None:
        super().__init__()
        self.heads, self.d_k, self.d_v, self.window, self.dropout, self.full = heads, d_k, d_v, window, dropout, full
        self.w_q = nn.Linear(d_model, heads * d_k)
        self.w_k = nn.Linear(d_model, heads * d_k)
        self.w_v = nn.Linear(d_model, heads * d_v)
        self.w_o = nn.Linear(heads * d_v, d_model)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        batch, n, _ = x.shape

        def split(t: torch.Tensor, d: int) -> torch.Tensor:
            return t.reshape(batch, n, self.heads, d).transpose(1, 2)

        q, k, v = split(self.w_q(x), self.d_k), split(self.w_k(x), self.d_k), split(self.w_v(x), self.d_v)
        if self.full:
            out = masked_full_attention(q, k, v, band_mask(n, self.window, x.device), self.dropout, self.training)
        else:
            out = local_attention(q, k, v, self.window, self.dropout, self.training)
        return self.w_o(out.transpose(1, 2).reshape(batch, n, self.heads * self.d_v))
