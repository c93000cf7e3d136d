"""A temporal convolutional network over log-mel frames giving beat and downbeat activations (after Davies &
Böck 2019, "Temporal convolutional networks for musical audio beat tracking", and Böck & Davies 2020,
"Deconstruct, analyse, reconstruct: how to improve tempo, beat, and downbeat estimation").

Input ``[B, T, 2 * n_mels]`` (:func:`stage1_pose.beat_tracking.spectrogram.network_input`), output ``[B, T, 3]``
logits per frame for the classes no beat, beat (not the bar's first) and downbeat; ``T`` is any length, frames at
``features.FPS``.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import torch
from torch import nn

CLASSES = ("none", "beat", "downbeat")


@dataclass(frozen=True)
class BeatTCNConfig:
    """Network size. ``layers`` residual blocks with dilations 1, 2, 4, ... 2**(layers - 1) frames and kernel
    ``kernel``: the receptive field is ``1 + 2 * (kernel - 1) * (2**layers - 1)`` frames (``small``: 163 s)."""

    n_mels: int = 64
    channels: int = 32
    kernel: int = 5
    layers: int = 11
    dropout: float = 0.1


PRESETS: dict[str, BeatTCNConfig] = {
    # The papers' TCN has 16-20 filters and 11 layers over a 3-layer 2-D conv front-end; a 1-D front-end with
    # twice the filters costs less on a CPU for the same width.
    "small": BeatTCNConfig(),
    # For tests: trains in seconds.
    "tiny": BeatTCNConfig(channels=8, layers=4),
}


class _Block(nn.Module):
    """Residual block: two parallel dilated convolutions (dilation d and 2d, as Böck & Davies 2020), ELU, dropout,
    then a 1x1 convolution added to the input. ``[B, C, T] -> [B, C, T]``."""

    def __init__(self, channels: int, kernel: int, dilation: int, dropout: float) -> None:
        super().__init__()
        self.convs = nn.ModuleList(nn.Conv1d(channels, channels, kernel, dilation=d, padding=d * (kernel - 1) // 2)
                                   for d in (dilation, 2 * dilation))
        self.act = nn.ELU()
        self.drop = nn.Dropout1d(dropout)
        self.mix = nn.Conv1d(2 * channels, channels, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.mix(self.drop(self.act(torch.cat([c(x) for c in self.convs], dim=1))))


class BeatTCN(nn.Module):
    """Frames ``[B, T, 2 * n_mels]`` -> logits ``[B, T, 3]`` (:data:`CLASSES`)."""

    def __init__(self, config: BeatTCNConfig) -> None:
        super().__init__()
        self.config = config
        c = config.channels
        self.front = nn.Sequential(nn.Conv1d(2 * config.n_mels, c, 3, padding=1), nn.ELU(),
                                   nn.Dropout1d(config.dropout), nn.Conv1d(c, c, 3, padding=1), nn.ELU())
        self.blocks = nn.Sequential(*(_Block(c, config.kernel, 2 ** i, config.dropout) for i in range(config.layers)))
        self.out = nn.Conv1d(c, len(CLASSES), 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.out(self.blocks(self.front(x.transpose(1, 2)))).transpose(1, 2)


def save_model(model: BeatTCN, folder: Path, info: dict) -> None:
    """Write ``folder/model.safetensors`` (weights only) and ``folder/config.json`` (the config, the frame rate and
    ``info``), each replaced atomically."""
    from safetensors.torch import save_file

    from stage1_pose.beat_tracking.spectrogram import FPS

    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / ".model.part.safetensors"
    save_file({k: v.detach().cpu().contiguous() for k, v in model.state_dict().items()}, str(tmp))
    tmp.replace(folder / "model.safetensors")
    tmp = folder / ".config.part.json"
    tmp.write_text(json.dumps({"model": asdict(model.config), "fps": FPS, **info}, indent=1) + "\n")
    tmp.replace(folder / "config.json")


def load_model(folder: Path) -> BeatTCN:
    """The network saved by :func:`save_model` in ``folder``, in eval mode on the CPU."""
    from safetensors.torch import load_file

    config = json.loads((folder / "config.json").read_text())["model"]
    model = BeatTCN(BeatTCNConfig(**config))
    model.load_state_dict(load_file(str(folder / "model.safetensors")))
    return model.eval()
