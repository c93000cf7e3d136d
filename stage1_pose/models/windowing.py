"""Generation in windows of the training length, for methods whose recurrent encoders were trained on short
windows but must dance whole songs."""

from __future__ import annotations

from collections.abc import Callable

import torch


def windowed(encode: Callable[..., torch.Tensor], inputs: tuple[torch.Tensor, ...], window: int) -> torch.Tensor:
    """``encode`` (``[B, t, ...]`` inputs -> ``[B, t, C]``) over windows of ``window`` frames, consecutive windows
    sharing an eighth of a window where their codes cross-fade linearly: every frame's code comes from windows of
    the training length (a recurrent encoder run over a whole song drifts into states it never saw, and the dance
    slows down after the first window). A short overlap, because a blend of two windows' codes is a calmer code,
    and none would leave a jump. Inputs of at most one window are encoded at once."""
    frames = inputs[0].shape[1]
    if frames <= window:
        return encode(*inputs)
    overlap = window // 8
    hop = window - overlap
    starts = [*range(0, frames - window, hop), frames - window]
    ramp = torch.ones(window, device=inputs[0].device)
    if overlap:
        rise = (torch.arange(overlap, device=ramp.device) + 0.5) / overlap
        ramp[:overlap], ramp[-overlap:] = rise, rise.flip(0)
    total, mass = None, inputs[0].new_zeros(frames)
    for start in starts:
        # The song's first and last frames have no neighbouring window to fade into.
        weight = ramp.clone()
        if start == 0:
            weight[:overlap] = 1.0
        if start == frames - window:
            weight[window - overlap:] = 1.0
        code = encode(*(x[:, start:start + window] for x in inputs)) * weight[:, None]
        if total is None:
            total = code.new_zeros(code.shape[0], frames, code.shape[2])
        total[:, start:start + window] += code
        mass[start:start + window] += weight
    return total / mass[:, None]
