"""Where a frame lies between two music beats, as an input a recurrent decoder can time its moves by.

Dancers reach their key poses on the beat and move fastest between beats. A decoder that sees only its own
previous pose cannot know when the next beat comes, so its moves drift off the beat; the beat phase tells it.
Shapes: beat flags ``[B, T]`` (bool, one row per pose frame); phases ``[B, T]`` in ``[0, 1)``, 0 on a beat
frame, rising linearly to the next beat; features ``[B, T, 2]``.
"""

from __future__ import annotations

import math

import torch

from dancesynth.core.errors import DancesynthError


def beat_phase(beats: torch.Tensor, fallback_period: float = 8.0) -> torch.Tensor:
    """Phase ``[B, T]`` of every frame within its interval between two beat frames of ``beats`` ``[B, T]``.

    Before the first and after the last beat the nearest interval's length continues the count; a row with
    fewer than two beats counts in ``fallback_period`` frames from its beat (or from frame 0).
    """
    frames = torch.arange(beats.shape[1], dtype=torch.float32, device=beats.device)
    rows = []
    for flags in beats:
        at = torch.nonzero(flags).flatten().float()
        if len(at) < 2:
            start = at[0] if len(at) else frames.new_zeros(())
            rows.append(torch.remainder((frames - start) / fallback_period, 1.0))
            continue
        # Index of the interval each frame falls in, clamped so the first and last intervals extend outwards.
        k = (torch.searchsorted(at, frames, right=True) - 1).clamp(0, len(at) - 2)
        start, period = at[k], at[k + 1] - at[k]
        rows.append(torch.remainder((frames - start) / period, 1.0))
    return torch.stack(rows) if rows else frames.new_zeros(0, beats.shape[1])


def with_beat_phase(x: torch.Tensor, beats: torch.Tensor | None) -> torch.Tensor:
    """``[B, T, C]`` per-frame inputs -> ``[B, T, C + 2]``: each frame's beat phase features appended, from ``[B, T]``
    beat flags (a model built to read them cannot run without)."""
    if beats is None:
        raise DancesynthError("This model times its moves by the beats; pass the song's beat flags.")
    return torch.cat([x, phase_features(beat_phase(beats.to(x.device))).to(x)], dim=-1)


def phase_features(phase: torch.Tensor) -> torch.Tensor:
    """``[B, T]`` phases -> ``[B, T, 2]`` (sin, cos) of ``2π·phase``: continuous across the beat, where the
    phase itself jumps from nearly 1 back to 0."""
    angle = 2 * math.pi * phase
    return torch.stack([torch.sin(angle), torch.cos(angle)], dim=-1)
