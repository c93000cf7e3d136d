"""pix2pixHD (Wang et al. 2018) with Everybody Dance Now's temporal smoothing (Chan et al. 2019).

Images are ``[B, C, H, W]`` float tensors in [-1, 1]. The generator maps a skeleton label map (3 channels,
OpenPose colours) concatenated with the previous generated frame (3 channels; zeros for the first frame)
to an RGB frame. The spatial discriminator judges (label map, frame) pairs; the temporal discriminator judges
two consecutive pairs stacked on the channel axis. H and W must be divisible by ``2 ** n_downsample``
(times 2 with the local enhancer).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import torch
import torch.nn.functional as F
from torch import nn

from dancesynth.core.device import cpu_has_amx
from dancesynth.core.errors import DancesynthError

LABEL_CHANNELS = 3
IMAGE_CHANNELS = 3


@dataclass(frozen=True)
class Pix2PixHDConfig:
    """Network sizes, loss weights and optimisation settings.

    Attributes:
        width, height: model resolution in pixels (frames and label maps are letterboxed to it).
        ngf: generator filters in the first layer; doubled at each downsampling.
        n_downsample: stride-2 convolutions in the global generator.
        n_blocks: residual blocks at the global generator's bottleneck.
        local_enhancer: add pix2pixHD's local enhancer, so the global generator runs at half resolution.
        n_blocks_local: residual blocks in the local enhancer.
        ndf, n_layers_d, num_d: PatchGAN filters, strided layers and number of scales.
        temporal: Everybody Dance Now smoothing (previous frame as input, temporal discriminator).
        background: the generator and discriminators also see the crop of the scene's background plate, so the
            model paints the person over a given scene instead of learning the scene; training turns it on when
            the crop follows the person (the scene then moves through it).
        blend: with ``background``, the generator also outputs a soft mask and the frame is its RGB over the
            background crop through that mask (vid2vid's foreground/background split, Wang et al. 2018), starting
            near the plate; the model then spends its steps on the person, not on copying the scene through the
            bottleneck. Training turns it on together with ``background``.
        prior: the generator also sees the warped prior (:mod:`stage2_video.prior`: the person's own pixels from the
            nearest training frames moved part by part onto the pose, over the background crop, and its alpha) and
            ``blend`` paints over that (or with ``residual`` corrects it) instead of the bare background crop, so
            even an untrained network shows the real person and training repairs seams, lighting and occlusions.
            Needs ``blend``.
        residual: with ``prior``, the network's output is a correction added to the warped prior (its last layer
            starts at zero, so the untrained network renders the prior exactly and each step moves away from it only
            where the losses ask) instead of RGB and a mask painted over it.
        prior_scale: the prior is warped at this many times the model's resolution; the network's correction is
            upsampled onto it, so the output keeps the person's detail (rendered at ``prior_scale`` x the size).
        prior_candidates: with ``prior``, how many nearest bank frames make the prior (odd): the per-pixel median
            of their warps (:class:`stage2_video.prior.PriorRenderer`); 1: the nearest frame's warp. 3 gave the dancer
            clip better images and fewer stray parts, but left the ``sports2d`` man pale and half transparent, and
            warps twice as long (docs/methods/warped_prior.md).
        lambda_mask: with ``blend``, L1 weight pulling the mask towards where the real frame differs from the plate
            near the skeleton (:func:`foreground_target`), so the person comes out opaque rather than a
            half-transparent average.
        lambda_gan, lambda_feat, lambda_vgg: weights of the adversarial loss, discriminator feature matching and the
            VGG19 perceptual loss; with the first two at 0 the discriminators do not train.
        lambda_l1: pixel L1 weight; 0 in the paper. The CPU preset uses it because the VGG loss, which
            supplies pix2pixHD's reconstruction signal, needs ImageNet weights that cannot be downloaded here.
        lr, beta1: Adam settings for generator and discriminators.
        batch_size: consecutive-frame pairs per step.
        epochs_constant, epochs_decay: epochs at constant lr, then epochs with lr decaying linearly to 0.
        val_fraction: the last fraction of the video held out for validation.
        select_fraction: the last fraction of the frames before those that is not learnt from but scores every
            checkpoint, the warped prior alone (step 0) included: the model renders with the best (0: the latest).
    """

    width: int = 128
    height: int = 128
    ngf: int = 32
    n_downsample: int = 3
    n_blocks: int = 9
    local_enhancer: bool = False
    n_blocks_local: int = 3
    ndf: int = 32
    n_layers_d: int = 3
    num_d: int = 2
    temporal: bool = True
    background: bool = False
    blend: bool = False
    prior: bool = False
    residual: bool = False
    prior_scale: int = 2
    prior_candidates: int = 1
    lambda_gan: float = 1.0
    lambda_feat: float = 10.0
    lambda_vgg: float = 10.0
    lambda_l1: float = 10.0
    lambda_mask: float = 10.0
    lr: float = 2e-4
    beta1: float = 0.5
    batch_size: int = 4
    epochs_constant: int = 100
    epochs_decay: int = 100
    val_fraction: float = 0.15
    select_fraction: float = 0.0

    @property
    def adversarial(self) -> bool:
        """The discriminators train and their losses reach the generator (``lambda_gan`` or ``lambda_feat``)."""
        return self.lambda_gan > 0 or self.lambda_feat > 0

    @property
    def repairs(self) -> bool:
        """The generator adds a correction to the warped prior (``prior`` and ``residual``)."""
        return self.prior and self.residual

    def __post_init__(self) -> None:
        if self.blend and not self.background:
            raise DancesynthError("The blend setting paints over the background crop; turn background on with it.")
        if self.prior and not self.blend:
            raise DancesynthError("The prior setting paints over the warped person; turn background and blend on "
                                  "with it.")
        if self.repairs and self.lambda_mask:
            raise DancesynthError("A residual generator has no mask; set lambda_mask to 0 with residual.")
        if self.prior_scale < 1:
            raise DancesynthError(f"The prior scale must be 1 or more, got {self.prior_scale}.")
        if self.prior_candidates < 1 or self.prior_candidates % 2 == 0:
            raise DancesynthError(f"The prior's candidates must be an odd count (1, 3, 5, ...), got "
                                  f"{self.prior_candidates}.")
        factor = 2 ** (self.n_downsample + int(self.local_enhancer))
        if self.width % factor or self.height % factor:
            raise DancesynthError(
                f"Model size {self.width}x{self.height} must be divisible by {factor} for this generator; "
                "choose a multiple of it.")


# The warped prior, corrected by L1 alone in small steps: painted over through a mask, trained with the
# discriminators or at pix2pixHD's learning rate, the network lost the warp's poses within minutes (dancer clip,
# held-out PCK@0.1 after 10 min: 0.720 with mask and discriminators; 761 steps: 0.776 at lr 2e-4, 0.794 at 5e-5;
# docs/methods/warped_prior.md). Four residual blocks, not nine: a correction of the warp needs less than a person
# drawn from a skeleton, and the steps come 1.5x as fast (dancer, 10 min: 1149 steps, the same held-out scores).
_WARPED = {"background": True, "blend": True, "prior": True, "residual": True, "lambda_mask": 0.0, "lambda_gan": 0.0,
           "lambda_feat": 0.0, "lr": 5e-5, "select_fraction": 0.1, "n_blocks": 4}
PRESETS: dict[str, Pix2PixHDConfig] = {
    # CPU: global generator only, trains in minutes on a short video; it repairs the warped person (docs/methods).
    "small": Pix2PixHDConfig(**_WARPED),
    # The small network at 256 px: 4x the pixels per step, affordable with bf16 CPUs or a GPU; its prior is warped
    # at its own size, as small's is (about 9 ms per frame at 256 px on 2 cores, 4x that at 512).
    "medium": Pix2PixHDConfig(width=256, height=256, prior_scale=1, **_WARPED),
    # Published pix2pixHD 1024p / Everybody Dance Now settings (GPU); the enhancer's global generator gets 2 * ngf.
    "paper": Pix2PixHDConfig(width=1024, height=512, ngf=32, n_downsample=4, n_blocks=9, local_enhancer=True,
                             ndf=64, lambda_l1=0.0, batch_size=1),
}


def affordable_preset(device: torch.device, precision: torch.dtype) -> str:
    """The largest preset that trains well in minutes on ``device`` computing in ``precision``
    (:func:`dancesynth.core.device.resolve_precision`): ``medium`` (256 px) on GPUs and on CPUs with AMX computing
    in bf16, ``small`` (128 px) elsewhere. On a 2-core AVX-512-BF16 CPU without AMX a 256-px step in bf16 took
    4.2 s against 1.7 s at 128 px: in 8 minutes 113 steps (held-out SSIM 0.39) against 278 (SSIM 0.89)."""
    if device.type == "cuda":
        return "medium"
    return "medium" if precision == torch.bfloat16 and cpu_has_amx() else "small"


def preset(name: str, **overrides) -> Pix2PixHDConfig:
    """A copy of preset ``name`` with some fields replaced."""
    if name not in PRESETS:
        raise DancesynthError(f"Unknown preset {name!r}; choose one of {', '.join(PRESETS)}.")
    return replace(PRESETS[name], **overrides)


class ResnetBlock(nn.Module):
    """Two reflection-padded 3x3 convolutions with instance norm and a skip connection."""

    def __init__(self, channels: int) -> None:
        super().__init__()
        self.block = nn.Sequential(
            nn.ReflectionPad2d(1), nn.Conv2d(channels, channels, 3), nn.InstanceNorm2d(channels), nn.ReLU(True),
            nn.ReflectionPad2d(1), nn.Conv2d(channels, channels, 3), nn.InstanceNorm2d(channels),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.block(x)


def _down(cin: int, cout: int) -> list[nn.Module]:
    return [nn.Conv2d(cin, cout, 3, stride=2, padding=1), nn.InstanceNorm2d(cout), nn.ReLU(True)]


def _up(cin: int, cout: int) -> list[nn.Module]:
    return [nn.ConvTranspose2d(cin, cout, 3, stride=2, padding=1, output_padding=1), nn.InstanceNorm2d(cout),
            nn.ReLU(True)]


def _stem(cin: int, cout: int) -> list[nn.Module]:
    return [nn.ReflectionPad2d(3), nn.Conv2d(cin, cout, 7), nn.InstanceNorm2d(cout), nn.ReLU(True)]


def _head(cin: int, cout: int) -> list[nn.Module]:
    return [nn.ReflectionPad2d(3), nn.Conv2d(cin, cout, 7), nn.Tanh()]


class GlobalGenerator(nn.Module):
    """pix2pixHD's G1: stem, ``n_downsample`` strided convs, ``n_blocks`` residual blocks, mirrored upsampling.

    ``[B, in_channels, H, W]`` -> ``[B, out_channels, H, W]`` in [-1, 1].
    """

    def __init__(self, in_channels: int, ngf: int, n_downsample: int, n_blocks: int,
                 out_channels: int = IMAGE_CHANNELS) -> None:
        super().__init__()
        layers = _stem(in_channels, ngf)
        for i in range(n_downsample):
            layers += _down(ngf * 2 ** i, ngf * 2 ** (i + 1))
        bottleneck = ngf * 2 ** n_downsample
        layers += [ResnetBlock(bottleneck) for _ in range(n_blocks)]
        for i in range(n_downsample, 0, -1):
            layers += _up(ngf * 2 ** i, ngf * 2 ** (i - 1))
        self.features = nn.Sequential(*layers)
        self.head = nn.Sequential(*_head(ngf, out_channels))

    @property
    def output_conv(self) -> nn.Conv2d:
        """The convolution whose channels are the output's (before tanh)."""
        return self.head[1]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(x))


class LocalEnhancer(nn.Module):
    """pix2pixHD's G2: a full-resolution branch whose features are added to G1's (run at half resolution).

    ``[B, in_channels, H, W]`` -> ``[B, out_channels, H, W]`` in [-1, 1].
    """

    def __init__(self, in_channels: int, ngf: int, n_downsample: int, n_blocks: int, n_blocks_local: int,
                 out_channels: int = IMAGE_CHANNELS) -> None:
        super().__init__()
        self.global_generator = GlobalGenerator(in_channels, ngf * 2, n_downsample, n_blocks)
        self.local_down = nn.Sequential(*_stem(in_channels, ngf), *_down(ngf, ngf * 2))
        self.local_up = nn.Sequential(*[ResnetBlock(ngf * 2) for _ in range(n_blocks_local)], *_up(ngf * 2, ngf),
                                      *_head(ngf, out_channels))

    @property
    def output_conv(self) -> nn.Conv2d:
        """The convolution whose channels are the output's (before tanh)."""
        return self.local_up[-2]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        half = F.avg_pool2d(x, 3, stride=2, padding=1, count_include_pad=False)
        return self.local_up(self.local_down(x) + self.global_generator.features(half))


class NLayerDiscriminator(nn.Module):
    """70x70-style PatchGAN; :meth:`forward` returns every layer's output (the last is the patch score map)."""

    def __init__(self, in_channels: int, ndf: int, n_layers: int) -> None:
        super().__init__()
        layers = [nn.Sequential(nn.Conv2d(in_channels, ndf, 4, stride=2, padding=2), nn.LeakyReLU(0.2, True))]
        nf = ndf
        for i in range(1, n_layers + 1):
            prev, nf = nf, min(nf * 2, 512)
            stride = 2 if i < n_layers else 1
            layers.append(nn.Sequential(nn.Conv2d(prev, nf, 4, stride=stride, padding=2), nn.InstanceNorm2d(nf),
                                        nn.LeakyReLU(0.2, True)))
        layers.append(nn.Sequential(nn.Conv2d(nf, 1, 4, stride=1, padding=2)))
        self.layers = nn.ModuleList(layers)

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        outs = []
        for layer in self.layers:
            x = layer(x)
            outs.append(x)
        return outs


class MultiscaleDiscriminator(nn.Module):
    """``num_d`` PatchGANs on the input downsampled by 1, 2, 4, ...; returns one feature list per scale."""

    def __init__(self, in_channels: int, ndf: int, n_layers: int, num_d: int) -> None:
        super().__init__()
        self.scales = nn.ModuleList(NLayerDiscriminator(in_channels, ndf, n_layers) for _ in range(num_d))

    def forward(self, x: torch.Tensor) -> list[list[torch.Tensor]]:
        outs = []
        for i, d in enumerate(self.scales):
            if i:
                x = F.avg_pool2d(x, 3, stride=2, padding=1, count_include_pad=False)
            outs.append(d(x))
        return outs


# The warped prior's channels: the person over the background crop (RGB) and the warp's alpha.
PRIOR_CHANNELS = 4


def blend_base(condition: torch.Tensor, prior: bool) -> torch.Tensor:
    """What a blending generator paints over, ``[B, 3, H, W]``: the warped prior's RGB with ``prior``, else the
    background crop, of a ``[B, C, H, W]`` generator input or condition."""
    start = LABEL_CHANNELS + IMAGE_CHANNELS if prior else LABEL_CHANNELS
    return condition[:, start:start + IMAGE_CHANNELS]


def condition_channels(config: Pix2PixHDConfig) -> int:
    """Channels of what a frame is conditioned on: the label map (+ the background crop (+ the warped prior))."""
    return LABEL_CHANNELS + (IMAGE_CHANNELS if config.background else 0) + (PRIOR_CHANNELS if config.prior else 0)


def generator_channels(config: Pix2PixHDConfig) -> int:
    """The generator's input channels: the condition (+ the previous frame when temporal)."""
    return condition_channels(config) + (IMAGE_CHANNELS if config.temporal else 0)


class PlateBlend(nn.Module):
    """Paints ``inner``'s RGB over the input's background crop (with ``prior``, over the warped prior) through
    ``inner``'s fourth channel as a mask.

    ``[B, C, H, W]`` (label map, background crop, ...; :func:`generator_channels`) -> ``[B, 3, H, W]`` in [-1, 1].
    """

    # The mask channel's initial pre-tanh bias: the first frames are about 88 % plate, and tanh still passes 42 %
    # of the gradient.
    START = -1.0

    def __init__(self, inner: GlobalGenerator | LocalEnhancer, prior: bool = False) -> None:
        super().__init__()
        self.inner, self.prior = inner, prior
        with torch.no_grad():
            inner.output_conv.bias[IMAGE_CHANNELS] = self.START

    def frame_and_mask(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The composed ``[B, 3, H, W]`` frame and the ``[B, 1, H, W]`` mask in [0, 1] it was composed with."""
        return blend(self.inner(x), blend_base(x, self.prior))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.frame_and_mask(x)[0]


def blend(raw: torch.Tensor, base: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """A blending generator's ``[B, 4, H, W]`` raw output (RGB and mask in [-1, 1]) painted over ``base``
    (``[B, 3, H, W]``): the ``[B, 3, H, W]`` frame and the ``[B, 1, H, W]`` mask in [0, 1]."""
    mask = raw[:, IMAGE_CHANNELS:].add(1.0).mul(0.5)
    return base + mask * (raw[:, :IMAGE_CHANNELS] - base), mask


class PriorRepair(nn.Module):
    """Adds ``inner``'s output, a correction, to the warped prior in its input (:attr:`Pix2PixHDConfig.residual`).

    ``[B, C, H, W]`` (:func:`generator_channels`) -> ``[B, 3, H, W]``; the last layer starts at zero, so before
    training the frame is the prior.
    """

    def __init__(self, inner: GlobalGenerator | LocalEnhancer) -> None:
        super().__init__()
        self.inner = inner
        with torch.no_grad():
            inner.output_conv.weight.zero_()
            inner.output_conv.bias.zero_()

    def frame_and_mask(self, x: torch.Tensor) -> tuple[torch.Tensor, None]:
        """The ``[B, 3, H, W]`` frame, and no mask (a correction has none)."""
        return repair(self.inner(x), blend_base(x, True)), None

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.frame_and_mask(x)[0]


# A correction's range: tanh's [-1, 1] doubled, so it can turn any colour of the prior into any other.
REPAIR_RANGE = 2.0


def repair(raw: torch.Tensor, base: torch.Tensor) -> torch.Tensor:
    """A residual generator's ``[B, 3, H, W]`` raw output (in [-1, 1]) added to ``base``: the frame (not clipped)."""
    return base + REPAIR_RANGE * raw


def carry_correction(frame: torch.Tensor, base: torch.Tensor, base_high: torch.Tensor) -> torch.Tensor:
    """A repaired ``[B, 3, h, w]`` frame's correction (``frame - base``, ``base`` the prior it repaired) upsampled
    bilinearly onto the same prior at a larger size, ``base_high`` ``[B, 3, H, W]``: the frame at that size."""
    correction = F.interpolate(frame - base, size=base_high.shape[2:], mode="bilinear", align_corners=False)
    return base_high + correction


# A pixel is foreground where the real frame differs from the plate by this much (0-255 scale: ~25 grey levels)
# in some channel: above the plate's own error (a median of frames) and the video's noise.
FOREGROUND_THRESHOLD = 0.2
# How far from the skeleton's drawn lines the person's body can reach, in model pixels per 128 of frame height.
FOREGROUND_REACH = 10


def foreground_target(condition: torch.Tensor, real: torch.Tensor, prior: bool = False) -> torch.Tensor:
    """Where the generator must paint: ``[B, 1, H, W]`` in {0, 1}, 1 where the ``[B, 3, H, W]`` real frame differs
    from what it paints over (:func:`blend_base` of ``condition``: the background crop, or with ``prior`` the warped
    person over it; values in [-1, 1]) by more than ``FOREGROUND_THRESHOLD`` and lies within ``FOREGROUND_REACH`` of
    the drawn skeleton (so the scene's own changes, e.g. leaves moving, do not count)."""
    differs = (real - blend_base(condition, prior)).abs().amax(1, keepdim=True) > FOREGROUND_THRESHOLD
    skeleton = (condition[:, :LABEL_CHANNELS] > -1.0).any(1, keepdim=True).float()
    reach = max(1, round(FOREGROUND_REACH * condition.shape[2] / 128))
    near = F.max_pool2d(skeleton, 2 * reach + 1, stride=1, padding=reach) > 0
    return (differs & near).float()


def build_generator(config: Pix2PixHDConfig) -> nn.Module:
    """The generator the config describes (input: :func:`generator_channels`)."""
    cin = generator_channels(config)
    cout = IMAGE_CHANNELS + int(config.blend and not config.repairs)
    if config.local_enhancer:
        inner = LocalEnhancer(cin, config.ngf, config.n_downsample, config.n_blocks, config.n_blocks_local, cout)
    else:
        inner = GlobalGenerator(cin, config.ngf, config.n_downsample, config.n_blocks, cout)
    if config.repairs:
        return PriorRepair(inner)
    return PlateBlend(inner, config.prior) if config.blend else inner


class Pix2PixHD(nn.Module):
    """Generator plus (for training) spatial and temporal multiscale discriminators.

    Only ``generator`` is needed to render; the discriminators are kept in the same module so one
    checkpoint resumes training exactly.
    """

    def __init__(self, config: Pix2PixHDConfig) -> None:
        super().__init__()
        self.config = config
        self.generator = build_generator(config)
        pair = condition_channels(config) + IMAGE_CHANNELS
        self.discriminator = MultiscaleDiscriminator(pair, config.ndf, config.n_layers_d, config.num_d)
        self.temporal_discriminator = (
            MultiscaleDiscriminator(2 * pair, config.ndf, config.n_layers_d, config.num_d) if config.temporal else None)

    def generate(self, label: torch.Tensor, previous: torch.Tensor | None = None) -> torch.Tensor:
        """``[B, C, H, W]`` condition (label map, + background crop; :func:`condition_channels`) and previous
        frame (zeros when None) -> ``[B, 3, H, W]`` frame in [-1, 1]."""
        return self.generate_with_mask(label, previous)[0]

    def generate_with_mask(self, label: torch.Tensor,
                        previous: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor | None]:
        """:meth:`generate`'s frame and, with ``blend`` (unless it ``repairs``), the ``[B, 1, H, W]`` mask it
        painted the person through."""
        if self.config.temporal:
            if previous is None:
                previous = label.new_zeros(label.shape[0], IMAGE_CHANNELS, *label.shape[2:])
            label = torch.cat([label, previous], dim=1)
        if self.config.blend:
            return self.generator.frame_and_mask(label)
        return self.generator(label), None


def lsgan_loss(outputs: list[list[torch.Tensor]], target_is_real: bool) -> torch.Tensor:
    """Least-squares GAN loss on the last output of every scale, averaged over scales."""
    target = 1.0 if target_is_real else 0.0
    losses = [F.mse_loss(scale[-1], torch.full_like(scale[-1], target)) for scale in outputs]
    return torch.stack(losses).mean()


def feature_matching_loss(fake: list[list[torch.Tensor]], real: list[list[torch.Tensor]], n_layers: int,
                          weight: float) -> torch.Tensor:
    """pix2pixHD's discriminator feature matching: L1 between intermediate features (real ones detached),

    weighted ``4 / (n_layers + 1)`` per layer and ``1 / num_d`` per scale, times ``weight`` (lambda_feat).
    """
    num_d = len(fake)
    loss = fake[0][0].new_zeros(())
    for fake_scale, real_scale in zip(fake, real):
        for f, r in zip(fake_scale[:-1], real_scale[:-1]):
            loss = loss + (4.0 / (n_layers + 1)) * (1.0 / num_d) * F.l1_loss(f, r.detach())
    return loss * weight
