"""Time-axis helpers of the recurrent methods: generation in windows of the training length, for encoders trained
on short windows that must dance whole songs, and smoothing along time."""

from __future__ import annotations

import math
from collections.abc import Callable

import torch
import torch.nn.functional as F


def windowed(encode: Callable[..., torch.Tensor], inputs: tuple[torch.Tensor, ...], window: int) -> torch.Tensor:
    """``encode`` (``[B, t, ...]`` inputs -> ``[B, t, C]``) over windows of ``window`` frames; consecutive windows'
    codes cross-fade linearly over an eighth of a window: every frame's code comes from windows of the training
    length (a recurrent encoder run over a whole song drifts into states it never saw, and the dance slows down
    after the first window). A short fade, because a blend of two windows' codes is a calmer code, and none would
    leave a jump. Inputs of at most one window, and every input when ``window`` <= 0, are encoded at once."""
    frames = inputs[0].shape[1]
    if window <= 0 or frames <= window:
        return encode(*inputs)
    overlap = window // 8
    hop = window - overlap
    starts = [*range(0, frames - window, hop), frames - window]
    rise = (torch.arange(overlap, device=inputs[0].device) + 0.5) / max(overlap, 1)
    total, mass = None, inputs[0].new_zeros(frames)
    for i, start in enumerate(starts):
        weight = torch.ones(window, device=rise.device)
        if i > 0:
            # Fade in where the previous window fades out; the last window, which ends on the song's last frame,
            # starts closer than a hop after it and reads the frames before that fade as context only.
            fade = starts[i - 1] + hop - start
            weight[:fade] = 0.0
            weight[fade:fade + overlap] = rise
        if i < len(starts) - 1:
            weight[window - overlap:] = rise.flip(0)
        code = encode(*(x[:, start:start + window] for x in inputs)) * weight[:, None]
        if total is None:
            total = code.new_zeros(code.shape[0], frames, code.shape[2])
        total[:, start:start + window] += code
        mass[start:start + window] += weight
    return total / mass[:, None]


def smooth_in_time(x: torch.Tensor, sigma: float) -> torch.Tensor:
    """``[B, T, C]`` smoothed along T by a Gaussian of ``sigma`` frames (edges repeated); ``sigma`` 0: ``x``."""
    if sigma <= 0:
        return x
    radius = int(math.ceil(3 * sigma))
    taps = torch.exp(-0.5 * (torch.arange(-radius, radius + 1, dtype=x.dtype, device=x.device) / sigma) ** 2)
    kernel = (taps / taps.sum()).expand(x.shape[2], 1, -1)
    padded = F.pad(x.transpose(1, 2), (radius, radius), mode="replicate")
    return F.conv1d(padded, kernel, groups=x.shape[2]).transpose(1, 2)
