"""ST-GCN (Yan et al. 2018) over the BODY_25 skeleton graph, used as the feature network of Ren et al.'s
pose perceptual loss.

Input: ``[B, T, 25, 2]`` model coordinates (:func:`dancesynth.core.skeleton.normalize`); T frames, any length
>= 1. Output of :meth:`STGCN.forward`: ``[B, num_classes]`` logits (the dataset's style labels);
:meth:`STGCN.features` returns every block's activation, the layers Eq. 1 of Ren et al. compares.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace

import numpy as np
import torch
from torch import nn

from dancesynth.core.skeleton import BODY25_LIMBS, NECK, NUM_JOINTS, ROOT

NUM_PARTITIONS = 3  # spatial partitioning: root (same distance to centre), centripetal, centrifugal


@dataclass(frozen=True)
class STGCNConfig:
    """Architecture and training settings of the perceptual ST-GCN.

    ``channels[i]`` / ``strides[i]`` are the output channels and temporal stride of block i;
    ``temporal_kernel`` is in frames. ``window_frames`` is the training window length in pose frames,
    ``lr`` the Adam learning rate, ``epochs`` full passes over the training windows.
    """

    channels: tuple[int, ...] = (64, 64, 64, 64, 128, 128, 128, 256, 256, 256)
    strides: tuple[int, ...] = (1, 1, 1, 1, 2, 1, 1, 2, 1, 1)
    temporal_kernel: int = 9
    dropout: float = 0.5
    num_classes: int = 3
    window_frames: int = 75
    batch_size: int = 32
    lr: float = 2e-3
    epochs: int = 60

    def __post_init__(self) -> None:
        if len(self.channels) != len(self.strides) or not self.channels:
            raise ValueError("channels and strides must be non-empty and of equal length")
        if self.temporal_kernel % 2 != 1:
            raise ValueError("temporal_kernel must be odd so the temporal convolution keeps frame alignment")

    @classmethod
    def preset(cls, name: str) -> "STGCNConfig":
        """``paper``: the 10-block ST-GCN with Ren et al.'s lr 0.002; ``small``: 4 narrow blocks for CPU."""
        if name not in STGCN_PRESETS:
            raise KeyError(name)
        return STGCN_PRESETS[name]

    def with_classes(self, num_classes: int) -> "STGCNConfig":
        return replace(self, num_classes=num_classes)


STGCN_PRESETS: dict[str, STGCNConfig] = {
    "paper": STGCNConfig(),
    "small": STGCNConfig(channels=(16, 16, 32, 32), strides=(1, 1, 2, 1), temporal_kernel=5, dropout=0.1,
                         window_frames=45, batch_size=16, lr=2e-3, epochs=15),
}


def spatial_adjacency() -> np.ndarray:
    """``[3, 25, 25]`` float32 adjacency of BODY_25 with ST-GCN's spatial partitioning.

    Entry ``[k, i, j]`` is the weight with which joint j feeds joint i in partition k: k = 0 holds i itself
    and neighbours as far from the centre (Neck) as i, k = 1 neighbours closer to the centre, k = 2
    neighbours farther away. Each row is divided by i's neighbourhood size (self included), so every joint
    averages its neighbours.
    """
    neighbours: list[set[int]] = [{j} for j in range(NUM_JOINTS)]
    for a, b in BODY25_LIMBS:
        neighbours[a].add(b)
        neighbours[b].add(a)
    depth = np.full(NUM_JOINTS, -1)
    depth[NECK] = 0
    queue = deque([NECK])
    while queue:
        i = queue.popleft()
        for j in neighbours[i]:
            if depth[j] < 0:
                depth[j] = depth[i] + 1
                queue.append(j)
    adj = np.zeros((NUM_PARTITIONS, NUM_JOINTS, NUM_JOINTS), np.float32)
    for i in range(NUM_JOINTS):
        for j in neighbours[i]:
            k = 0 if depth[j] == depth[i] else (1 if depth[j] < depth[i] else 2)
            adj[k, i, j] = 1.0 / len(neighbours[i])
    return adj


def to_absolute(poses: torch.Tensor) -> torch.Tensor:
    """Model coordinates (joints relative to MidHip, MidHip relative to the canvas) -> every joint in
    canvas-centred torso units, so that graph neighbours live in one frame of reference. Shape kept."""
    root = poses[..., ROOT:ROOT + 1, :]
    absolute = poses + root
    absolute[..., ROOT:ROOT + 1, :] = root
    return absolute


class STGCNBlock(nn.Module):
    """Spatial graph convolution (one 1x1 conv per partition) -> temporal conv, with a residual path.

    ``[B, C_in, T, 25]`` -> ``[B, C_out, ceil(T / stride), 25]``.
    """

    def __init__(self, c_in: int, c_out: int, stride: int, temporal_kernel: int, dropout: float,
                 residual: bool = True) -> None:
        super().__init__()
        self.c_out = c_out
        self.spatial = nn.Conv2d(c_in, c_out * NUM_PARTITIONS, kernel_size=1)
        # Learned per-edge importance, as in ST-GCN's edge_importance_weighting.
        self.edge_importance = nn.Parameter(torch.ones(NUM_PARTITIONS, NUM_JOINTS, NUM_JOINTS))
        pad = (temporal_kernel - 1) // 2
        self.temporal = nn.Sequential(
            nn.BatchNorm2d(c_out), nn.ReLU(inplace=True),
            nn.Conv2d(c_out, c_out, (temporal_kernel, 1), (stride, 1), (pad, 0)),
            nn.BatchNorm2d(c_out), nn.Dropout(dropout),
        )
        if not residual:
            self.residual = None
        elif c_in == c_out and stride == 1:
            self.residual = nn.Identity()
        else:
            self.residual = nn.Sequential(nn.Conv2d(c_in, c_out, 1, (stride, 1)), nn.BatchNorm2d(c_out))
        self.register_buffer("adjacency", torch.from_numpy(spatial_adjacency()), persistent=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, _, t, v = x.shape
        y = self.spatial(x).view(b, NUM_PARTITIONS, self.c_out, t, v)
        y = torch.einsum("bkctj,kij->bcti", y, self.adjacency * self.edge_importance)
        y = self.temporal(y)
        if self.residual is not None:
            y = y + self.residual(x)
        return torch.relu(y)


class STGCN(nn.Module):
    """Style classifier on BODY_25 pose sequences (see module docstring for shapes)."""

    def __init__(self, config: STGCNConfig) -> None:
        super().__init__()
        self.config = config
        self.data_bn = nn.BatchNorm1d(2 * NUM_JOINTS)
        blocks = []
        c_in = 2
        for i, (c, s) in enumerate(zip(config.channels, config.strides)):
            # ST-GCN's first block has no residual: its input is raw coordinates.
            blocks.append(STGCNBlock(c_in, c, s, config.temporal_kernel, config.dropout, residual=i > 0))
            c_in = c
        self.blocks = nn.ModuleList(blocks)
        self.head = nn.Linear(c_in, config.num_classes)

    def features(self, poses: torch.Tensor) -> list[torch.Tensor]:
        """``[B, T, 25, 2]`` model coordinates -> each block's output ``[B, C_i, T_i, 25]``."""
        x = to_absolute(poses)
        b, t, v, c = x.shape
        x = self.data_bn(x.reshape(b, t, v * c).transpose(1, 2))
        x = x.reshape(b, v, c, t).permute(0, 2, 3, 1)
        out = []
        for block in self.blocks:
            x = block(x)
            out.append(x)
        return out

    def forward(self, poses: torch.Tensor) -> torch.Tensor:
        """``[B, T, 25, 2]`` -> ``[B, num_classes]`` style logits."""
        return self.head(self.features(poses)[-1].mean(dim=(2, 3)))
