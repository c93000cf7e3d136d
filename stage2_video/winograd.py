"""The generator's residual blocks rewritten with Winograd F(4x4, 3x3) convolutions, for CPU rendering.

A 3x3 convolution computed directly costs 144 multiplies per 4 x 4 output tile and (input, output) channel
pair; in the Winograd domain (Lavin & Gray 2016, "Fast Algorithms for Convolutional Neural Networks") it
costs 36: each 6 x 6 input tile ``d`` and each filter ``g`` are transformed (``B^T d B``, ``G g G^T``),
multiplied elementwise, which over channels is 36 independent matrix products, and transformed back
(``A^T m A``). The small generator spends 80 % of its multiplies in nine 256-channel residual blocks at 1/8
of the image size; compiled by OpenVINO, those blocks take about 60 % of the time of its direct convolutions
(53 vs 90 ms for three 256-channel blocks at 32 x 32), with float32 rounding differences of about 1e-5 of the
activations.

Inside a run of residual blocks the activations are kept as ``[H * W, C]`` rows (channels last), so that
cutting the padded image into overlapping tiles and putting the output tiles back in place are both row
gathers with precomputed indices (the reflection padding folded into them), and the only transposes are one
at the start and one at the end of the run. The rewritten network is meant to be traced and compiled by
OpenVINO (:class:`stage2_video.render.OpenVINOGenerator`) for one input size.
"""

from __future__ import annotations

import copy

import numpy as np
import torch
from torch import nn

from stage2_video.models.pix2pixhd import ResnetBlock

# Lavin & Gray's F(4x4, 3x3) matrices, interpolation points 0, +-1, +-2 and infinity.
_BT = torch.tensor([[4, 0, -5, 0, 1, 0], [0, -4, -4, 1, 1, 0], [0, 4, -4, -1, 1, 0],
                    [0, -2, -1, 2, 1, 0], [0, 2, -1, -2, 1, 0], [0, 4, 0, -5, 0, 1]], dtype=torch.float64)
_G = torch.tensor([[1 / 4, 0, 0], [-1 / 6, -1 / 6, -1 / 6], [-1 / 6, 1 / 6, -1 / 6],
                   [1 / 24, 1 / 12, 1 / 6], [1 / 24, -1 / 12, 1 / 6], [0, 0, 1]], dtype=torch.float64)
_AT = torch.tensor([[1, 1, 1, 1, 1, 0], [0, 1, -1, 2, -2, 0], [0, 1, 1, 4, 4, 0], [0, 1, -1, 8, -8, 1]],
                   dtype=torch.float64)
TILE = 4
# Transformed filters are 4x the size of 3x3 ones, and converting the network for OpenVINO briefly holds about
# three more copies. Above this many bytes per run of blocks the blocks stay direct: the small preset's nine
# 256-channel blocks take 170 MB, the paper preset's 1024-channel bottleneck would take 2.7 GB.
MAX_WEIGHT_BYTES = 256 * 2 ** 20
# Narrower blocks stay direct: their 36 matrix products are too thin to beat OpenVINO's direct convolution
# (measured with three blocks: 64 channels at 128 px 99 vs 81 ms, 128 channels at 64 px 50 vs 64 ms).
MIN_CHANNELS = 128


def _reflect(index: np.ndarray, size: int) -> np.ndarray:
    """Indices into a reflection-padded axis (``nn.ReflectionPad2d``) -> indices into the unpadded axis."""
    index = np.abs(index)
    return np.where(index >= size, 2 * (size - 1) - index, index)


class WinogradConv3x3(nn.Module):
    """``ReflectionPad2d(1)`` + 3x3 ``conv`` on ``[height * width, C_in]`` rows -> ``[height * width, C_out]``.

    ``height`` and ``width`` (pixels) must be multiples of 4.
    """

    def __init__(self, conv: nn.Conv2d, height: int, width: int) -> None:
        super().__init__()
        if conv.kernel_size != (3, 3) or conv.stride != (1, 1) or conv.padding != (0, 0) or conv.groups != 1:
            raise ValueError("WinogradConv3x3 needs an unpadded 3x3 convolution with stride 1")
        if height % TILE or width % TILE:
            raise ValueError(f"image size {width}x{height} is not a multiple of {TILE}")
        weight = conv.weight.detach()
        c_out, c_in = weight.shape[:2]
        filters = (_G.float() @ weight @ _G.float().T).permute(2, 3, 1, 0)  # [6, 6, C_in, C_out]
        self.register_buffer("filters", filters.reshape(36, c_in, c_out).contiguous())
        self.register_buffer("input_transform", torch.kron(_BT, _BT).float())  # [36, 36]
        self.register_buffer("output_transform", torch.kron(_AT, _AT).float())  # [16, 36]
        bias = conv.bias.detach() if conv.bias is not None else torch.zeros(c_out)
        self.register_buffer("bias", bias.float().clone())
        tiles_y, tiles_x = height // TILE, width // TILE
        self.tiles = tiles_y * tiles_x
        offsets = np.arange(TILE + 2) - 1  # the padding of 1 folded into the gather
        rows = _reflect(TILE * np.arange(tiles_y)[None, :] + offsets[:, None], height)  # [6, tiles_y]
        cols = _reflect(TILE * np.arange(tiles_x)[None, :] + offsets[:, None], width)  # [6, tiles_x]
        # Gathered rows ordered (tile row i, tile column j, tile y, tile x): [36 * tiles, C_in] is [36, tiles, C_in].
        gather = rows[:, None, :, None] * width + cols[None, :, None, :]
        self.register_buffer("gather", torch.from_numpy(gather.reshape(-1).astype(np.int64)))
        # Output rows come ordered (p, q, tile y, tile x) for pixel (4 * tile y + p, 4 * tile x + q).
        y, x = np.meshgrid(np.arange(height), np.arange(width), indexing="ij")
        scatter = ((y % TILE) * TILE + x % TILE) * self.tiles + (y // TILE) * tiles_x + x // TILE
        self.register_buffer("scatter", torch.from_numpy(scatter.reshape(-1).astype(np.int64)))

    def forward(self, rows: torch.Tensor) -> torch.Tensor:
        c_in = rows.shape[1]
        tiles = rows.index_select(0, self.gather).reshape(36, self.tiles * c_in)
        transformed = (self.input_transform @ tiles).reshape(36, self.tiles, c_in)
        products = torch.bmm(transformed, self.filters)  # [36, tiles, C_out]
        c_out = products.shape[2]
        out = (self.output_transform @ products.reshape(36, self.tiles * c_out)).reshape(16 * self.tiles, c_out)
        return out.index_select(0, self.scatter) + self.bias


def _instance_norm(rows: torch.Tensor, eps: float) -> torch.Tensor:
    """``nn.InstanceNorm2d`` without affine parameters on ``[pixels, C]`` rows."""
    mean = rows.mean(0, keepdim=True)
    centred = rows - mean
    return centred * torch.rsqrt(centred.pow(2).mean(0, keepdim=True) + eps)


class WinogradResnetStack(nn.Module):
    """A run of :class:`ResnetBlock` s at one ``height x width`` (pixels, multiples of 4), same function.

    ``[1, C, height, width]`` -> ``[1, C, height, width]``.
    """

    def __init__(self, blocks: list[ResnetBlock], height: int, width: int) -> None:
        super().__init__()
        self.convs = nn.ModuleList()
        self.eps: list[tuple[float, float]] = []
        for block in blocks:
            convs = [layer for layer in block.block if isinstance(layer, nn.Conv2d)]
            norms = [layer for layer in block.block if isinstance(layer, nn.InstanceNorm2d)]
            if any(norm.affine for norm in norms):
                raise ValueError("WinogradResnetStack expects instance norms without affine parameters")
            self.convs.append(nn.ModuleList(WinogradConv3x3(conv, height, width) for conv in convs))
            self.eps.append((norms[0].eps, norms[1].eps))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        n, c, h, w = x.shape
        rows = x.reshape(c, h * w).t()
        for (first, second), (eps1, eps2) in zip(self.convs, self.eps):
            inner = torch.relu(_instance_norm(first(rows), eps1))
            rows = rows + _instance_norm(second(inner), eps2)
        return rows.t().reshape(n, c, h, w)


def _block_sizes(generator: nn.Module, in_channels: int, width: int, height: int) -> dict[int, tuple[int, int]]:
    """``id(block) -> (height, width)`` of its input, for every residual block, from one forward pass."""
    sizes: dict[int, tuple[int, int]] = {}
    hooks = [block.register_forward_pre_hook(lambda m, args: sizes.__setitem__(id(m), tuple(args[0].shape[2:])))
             for block in generator.modules() if isinstance(block, ResnetBlock)]
    try:
        with torch.no_grad():
            generator(torch.zeros(1, in_channels, height, width))
    finally:
        for hook in hooks:
            hook.remove()
    return sizes


def _rewrite(module: nn.Module, sizes: dict[int, tuple[int, int]], limits: tuple[int, int]) -> None:
    for name, child in module.named_children():
        if isinstance(child, nn.Sequential) and any(isinstance(layer, ResnetBlock) for layer in child):
            setattr(module, name, nn.Sequential(*_merge_runs(list(child), sizes, limits)))
        else:
            _rewrite(child, sizes, limits)


def _merge_runs(layers: list[nn.Module], sizes: dict[int, tuple[int, int]],
                limits: tuple[int, int]) -> list[nn.Module]:
    max_weight_bytes, min_channels = limits
    out: list[nn.Module] = []
    run: list[ResnetBlock] = []
    for layer in [*layers, None]:
        if isinstance(layer, ResnetBlock) and (not run or sizes[id(layer)] == sizes[id(run[0])]):
            run.append(layer)
            continue
        if run:
            height, width = sizes[id(run[0])]
            weight_bytes = sum(4 * 4 * p.numel() for block in run for p in block.parameters() if p.dim() == 4)
            channels = next(m for m in run[0].block if isinstance(m, nn.Conv2d)).out_channels
            fits = (height % TILE == 0 and width % TILE == 0 and weight_bytes <= max_weight_bytes
                    and channels >= min_channels)
            out += [WinogradResnetStack(run, height, width)] if fits else run
            run = []
        if isinstance(layer, ResnetBlock):
            run.append(layer)
        elif layer is not None:
            out.append(layer)
    return out


def winograd_generator(generator: nn.Module, in_channels: int, width: int, height: int,
                       max_weight_bytes: int = MAX_WEIGHT_BYTES, min_channels: int = MIN_CHANNELS) -> nn.Module:
    """An eval-mode copy of ``generator`` for ``[1, in_channels, height, width]`` inputs whose runs of residual
    blocks are :class:`WinogradResnetStack` s where their size is a multiple of 4 pixels, they have at least
    ``min_channels`` channels and their transformed filters take at most ``max_weight_bytes``; other blocks stay
    as they are."""
    generator = copy.deepcopy(generator).eval()
    sizes = _block_sizes(generator, in_channels, width, height)
    _rewrite(generator, sizes, (max_weight_bytes, min_channels))
    return generator
