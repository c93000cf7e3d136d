"""Ren et al. 2020, "Self-supervised Dance Video Synthesis Conditioned on Music": stage-1 networks and losses.

Generator: raw audio cut into one piece per pose frame -> 1-D conv encoder -> 2-layer bidirectional GRU,
concatenated with a noise sequence run through a small GRU -> residual MLP -> BODY_25 model coordinates.
Local Temporal Discriminator: a two-stream co-occurrence CNN (HCN) scoring K overlapping sub-sequences.
Global Content Discriminator: the same kind of pose encoder plus a music encoder with structured
self-attention, deciding whether dance and music belong together.
Objective (Eq. 7): adversarial (both D) + w_P pose perceptual (ST-GCN, Eq. 1) + w_FM feature matching on the
global D + w_L1 L1, plus a WGAN-GP gradient penalty and the attention penalty in the global D's loss.

Shapes: audio ``[B, T, S]`` raw samples (the ``waveform`` features), S = ``samples_per_frame`` per pose frame;
poses ``[B, T, 25, 2]`` model coordinates (:func:`dancesynth.core.skeleton.normalize`); beat flags ``[B, T]``
(read only with ``beat_phase_input``; the paper does not read the beats).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace

import torch
import torch.nn.functional as F
from torch import nn

from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import NUM_JOINTS
from stage1_pose.models.base import Batch, Stage1Method, bce_with_constant_target
from stage1_pose.models.beat_clock import with_beat_phase
from stage1_pose.models.kinematics import KinematicOutput, motion_statistics_loss, speed_loss
from stage1_pose.models.ren.perceptual import PosePerceptualLoss
from stage1_pose.models.ren.variety import best_of, held_noise
from stage1_pose.models.windowing import windowed

ABLATIONS = ("l1", "global_d", "local_d", "full")


@dataclass(frozen=True)
class RenConfig:
    """Every size and loss weight of the method.

    Sizes: ``samples_per_frame`` audio samples per pose frame (1024 = 15360 Hz / 15 fps);
    ``window_frames`` training window in pose frames; ``local_window`` / ``local_stride`` the frames per
    Local-D sub-sequence and the hop between them (K = (window_frames - local_window) // local_stride + 1).
    Weights (Eq. 4-7): ``w_local`` / ``w_global`` adversarial terms (0 removes that discriminator),
    ``w_fm`` feature matching, ``w_l1`` L1, ``w_perceptual`` pose perceptual loss (needs ``stgcn_run``,
    a run folder written by ``dancesynth train-stgcn``), ``w_gp`` gradient penalty, ``w_attention`` the
    self-attention penalty ||AA^T - I||_F^2.
    Deviations from the paper (paper values in the ``paper`` preset): ``head_kernel`` frames seen by the
    pose head's first layer (1 = the paper's per-frame MLP; wider lets it low-pass the per-frame audio codes,
    which are nearly white from frame to frame); ``w_velocity`` weight of an L1 loss between generated and
    real frame-to-frame motion (0 = the paper), which charges jitter directly but also damps uncertain motion.
    Noise (the paper has none; the official code concatenates a noise sequence run through a GRU): ``noise_dim``
    numbers per frame with standard deviation ``noise_std``, drawn independently every ``noise_frames`` frames
    and linearly interpolated in between (1 = a fresh draw every frame, as in the official code); with
    ``variety_samples`` K > 1 every training clip gets K noise draws and Eq. 7 is computed on the draw
    closest to the real dance (:mod:`stage1_pose.models.ren.variety`). With K = 1 the L1 and perceptual terms
    make the generator ignore its noise, and per-frame noise can only make it shake. ``kinematic_output`` places
    the poses by forward kinematics (:mod:`stage1_pose.models.kinematics`: bones keep their length);
    ``speed_weight`` adds an L1 loss between each joint's speed and the real dance's (on the draw Eq. 7 uses);
    ``motion_weight`` adds :func:`~stage1_pose.models.kinematics.motion_statistics_loss` on every draw (each should
    move as much as the real dance, however it times it: the draw nearest in L1 is the stillest one);
    ``epoch_windows`` > 0 makes an epoch that many training windows whatever the dataset's size (0: one pass).
    ``windowed_generation`` encodes a song in overlapping windows of ``window_frames``, the length the recurrent
    encoders were trained on (:func:`~stage1_pose.models.windowing.windowed`); the paper runs them over the whole
    test sequence. ``beat_phase_input`` gives the pose head each frame's phase between two beats
    (:mod:`stage1_pose.models.beat_clock`): the paper's generator hears the beats only through raw audio, and a
    model that cannot tell when the next beat comes meets the L1 term by holding its arms still.
    """

    samples_per_frame: int = 1024
    window_frames: int = 75
    audio_channels: tuple[int, ...] = (16, 32, 64, 128)
    code_dim: int = 256
    gru_hidden: int = 256
    noise_dim: int = 10
    noise_std: float = 0.33
    noise_frames: int = 1
    variety_samples: int = 1
    mlp_hidden: int = 1024
    mlp_blocks: int = 3
    head_kernel: int = 1
    dropout: float = 0.5
    local_window: int = 5
    local_stride: int = 3
    d_channels: int = 64
    d_embed: int = 256
    attention_dim: int = 40
    attention_hops: int = 4
    w_local: float = 1.0
    w_global: float = 1.0
    w_fm: float = 1.0
    w_l1: float = 200.0
    w_velocity: float = 0.0
    w_perceptual: float = 1.0
    w_gp: float = 1.0
    w_attention: float = 1.0
    perceptual_layer_weights: tuple[float, ...] = (20.0, 5.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    stgcn_run: str = ""
    lr_g: float = 3e-4
    lr_d_local: float = 3e-4
    lr_d_global: float = 5e-4
    batch_size: int = 16
    epochs: int = 400
    epoch_windows: int = 0
    kinematic_output: bool = False
    speed_weight: float = 0.0
    motion_weight: float = 0.0
    windowed_generation: bool = False
    beat_phase_input: bool = False

    @property
    def uses_local_d(self) -> bool:
        return self.w_local > 0

    @property
    def uses_global_d(self) -> bool:
        return self.w_global > 0 or self.w_fm > 0

    @property
    def uses_perceptual(self) -> bool:
        return self.w_perceptual > 0

    def __post_init__(self) -> None:
        if self.noise_frames < 1 or self.variety_samples < 1:
            raise DancesynthError(f"noise_frames and variety_samples must be at least 1, not "
                                  f"{self.noise_frames} and {self.variety_samples}.")

    @classmethod
    def preset(cls, name: str) -> "RenConfig":
        """A named preset (see :data:`REN_PRESETS`); unknown names raise a :class:`DancesynthError`."""
        if name not in REN_PRESETS:
            raise DancesynthError(f"Unknown ren preset {name!r}; choose one of {', '.join(REN_PRESETS)}.")
        return REN_PRESETS[name]


def _ablation(config: RenConfig, row: str) -> RenConfig:
    """The paper's ablation rows (Table 1) below the full model: l1 only; + global D; + local D."""
    off = {"l1": dict(w_local=0.0, w_global=0.0, w_fm=0.0, w_perceptual=0.0),
           "global_d": dict(w_local=0.0, w_perceptual=0.0),
           "local_d": dict(w_perceptual=0.0)}[row]
    return replace(config, **off)


_PAPER = RenConfig()
# CPU-sized (10 epochs < 20 min), with held noise, best of 4 draws and L1 weight 50 so the seed chooses the dance.
_SMALL = RenConfig(window_frames=45, audio_channels=(8, 16, 32, 32), code_dim=64, gru_hidden=64,
                   mlp_hidden=128, mlp_blocks=2, dropout=0.0, d_channels=16, d_embed=64, attention_dim=16,
                   batch_size=8, epochs=10, noise_std=1.0, noise_frames=45, variety_samples=4, w_l1=50.0,
                   epoch_windows=1872, kinematic_output=True, motion_weight=5.0,
                   windowed_generation=True, beat_phase_input=True)

# "small" / "paper" are the full model; "<row>-small" / "<row>-paper" the ablation rows.
REN_PRESETS: dict[str, RenConfig] = {"small": _SMALL, "paper": _PAPER}
for _row in ABLATIONS[:-1]:
    REN_PRESETS[f"{_row}-small"] = _ablation(_SMALL, _row)
    REN_PRESETS[f"{_row}-paper"] = _ablation(_PAPER, _row)


class AudioEncoder(nn.Module):
    """One raw-audio piece per pose frame -> a code: ``[N, S]`` samples -> ``[N, code_dim]``.

    Strided 1-D convolutions after Ren et al.'s Table 2 (a wide first kernel, then stride-2 stages and a
    stride-4 stage), flattened into one fully-connected layer. Sizes follow ``samples_per_frame``.
    """

    def __init__(self, samples_per_frame: int, channels: tuple[int, ...], code_dim: int) -> None:
        super().__init__()
        first_kernel = max(8, samples_per_frame // 16)
        first_stride = max(1, samples_per_frame // 128)
        specs = [(first_kernel, first_stride)] + [(4, 2)] * (len(channels) - 2) + [(8, 4)]
        layers: list[nn.Module] = []
        c_in = 1
        for c, (k, s) in zip(channels, specs):
            layers += [nn.Conv1d(c_in, c, k, s, padding=(k - s) // 2), nn.BatchNorm1d(c), nn.LeakyReLU(0.2)]
            c_in = c
        self.convs = nn.Sequential(*layers)
        with torch.no_grad():
            flat = self.convs.eval()(torch.zeros(1, 1, samples_per_frame)).numel()
        self.convs.train()
        self.fc = nn.Linear(flat, code_dim)
        self.samples_per_frame = samples_per_frame

    def forward(self, pieces: torch.Tensor) -> torch.Tensor:
        return self.fc(self.convs(pieces.unsqueeze(1)).flatten(1))


class WaveformMusicEncoder(nn.Module):
    """``[B, T, S]`` audio -> ``[B, T, 2 * hidden]`` hidden states of a 2-layer bidirectional GRU over the
    per-frame codes."""

    def __init__(self, samples_per_frame: int, channels: tuple[int, ...], code_dim: int, hidden: int) -> None:
        super().__init__()
        self.pieces = AudioEncoder(samples_per_frame, channels, code_dim)
        self.gru = nn.GRU(code_dim, hidden, num_layers=2, batch_first=True, bidirectional=True)

    def forward(self, audio: torch.Tensor) -> torch.Tensor:
        b, t, s = audio.shape
        if s != self.pieces.samples_per_frame:
            raise DancesynthError(
                f"The audio has {s} samples per pose frame but this model expects {self.pieces.samples_per_frame}; "
                "use the waveform features the dataset was built with.")
        codes = self.pieces(audio.reshape(b * t, s)).view(b, t, -1)
        return self.gru(codes)[0]


class ResidualBlock(nn.Module):
    """Two Linear-LayerNorm-ReLU layers with an identity skip (Ren et al.'s Fig. 14).

    LayerNorm instead of the official BatchNorm over the time axis, which tied the model to one window
    length and batch size; generation runs on one song of any length.
    """

    def __init__(self, width: int) -> None:
        super().__init__()
        self.layers = nn.Sequential(nn.Linear(width, width), nn.LayerNorm(width), nn.ReLU(),
                                    nn.Linear(width, width), nn.LayerNorm(width), nn.ReLU())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.layers(x)


class RenGenerator(nn.Module):
    """Music (+ noise) -> dance: ``[B, T, S]`` audio, ``[B, T, noise_dim]`` noise -> ``[B, T, 25, 2]``.

    The output layer is linear, not the official tanh: model coordinates are in torso lengths with the
    MidHip slot relative to the canvas centre, so they are not confined to [-1, 1] and tanh would squash
    wide poses and saturate its gradient.
    """

    def __init__(self, config: RenConfig) -> None:
        super().__init__()
        self.music = WaveformMusicEncoder(config.samples_per_frame, config.audio_channels, config.code_dim,
                                          config.gru_hidden)
        self.noise_gru = nn.GRU(config.noise_dim, config.noise_dim, batch_first=True)
        k = config.head_kernel
        if k < 1 or k % 2 == 0:
            raise DancesynthError(f"head_kernel must be an odd number of frames >= 1, not {k}; use e.g. 1 or 9.")
        # One linear layer over the k frames centred on each frame: a temporal convolution whose weights keep
        # the paper's per-frame layer shape for k = 1 (so runs saved before this option still load).
        self.head_kernel = k
        self.beat_phase_input = config.beat_phase_input
        extra = 2 if config.beat_phase_input else 0
        self.inp = nn.Linear(k * (2 * config.gru_hidden + config.noise_dim + extra), config.mlp_hidden)
        self.blocks = nn.Sequential(*[ResidualBlock(config.mlp_hidden) for _ in range(config.mlp_blocks)])
        self.dropout = nn.Dropout(config.dropout)
        self.out = nn.Linear(config.mlp_hidden, NUM_JOINTS * 2)
        self.kinematics = KinematicOutput() if config.kinematic_output else None

    def forward(self, audio: torch.Tensor, noise: torch.Tensor, window: int = 0,
                beats: torch.Tensor | None = None) -> torch.Tensor:
        """``[B, T, S]`` audio, ``[B, T, noise_dim]`` noise, ``[B, T]`` beat flags (needed with
        ``beat_phase_input``) -> ``[B, T, 25, 2]`` poses; ``window`` > 0 runs both recurrent encoders on windows of
        that many frames (:func:`~stage1_pose.models.windowing.windowed`) instead of once over the whole song."""
        codes = windowed(lambda a, n: torch.cat([self.music(a), self.noise_code(n)], dim=-1), (audio, noise), window)
        return self.head(self.with_phase(codes, beats))

    def with_phase(self, codes: torch.Tensor, beats: torch.Tensor | None) -> torch.Tensor:
        """``[B, T, C]`` per-frame codes -> ``[B, T, C + 2]`` with each frame's beat phase (sin, cos) from ``[B, T]``
        beat flags when the generator reads the beats, else ``codes`` unchanged."""
        return with_beat_phase(codes, beats) if self.beat_phase_input else codes

    def noise_code(self, noise: torch.Tensor) -> torch.Tensor:
        """``[B, T, noise_dim]`` noise -> ``[B, T, noise_dim]`` codes of the noise GRU."""
        return torch.tanh(self.noise_gru(noise)[0])

    def decode(self, h: torch.Tensor, noise: torch.Tensor, lengths: torch.Tensor | None = None,
               beats: torch.Tensor | None = None) -> torch.Tensor:
        """Music codes ``h [B, T, 2 * gru_hidden]`` (from ``self.music``) + noise (+ ``[B, T]`` beat flags) -> poses
        ``[B, T, 25, 2]``; with kinematic output, bones of ``lengths`` (``[B, 1, 25]``, default the training data's
        mean body)."""
        return self.head(self.with_phase(torch.cat([h, self.noise_code(noise)], dim=-1), beats), lengths)

    def head(self, codes: torch.Tensor, lengths: torch.Tensor | None = None) -> torch.Tensor:
        """Per-frame codes ``[B, T, 2 * gru_hidden + noise_dim (+ 2 beat phase)]`` -> poses ``[B, T, 25, 2]``."""
        x = self.blocks(self.inp(frame_context(codes, self.head_kernel)))
        b, t, _ = codes.shape
        out = self.out(self.dropout(x)).view(b, t, NUM_JOINTS, 2)
        return out if self.kinematics is None else self.kinematics(out, lengths)


def frame_context(x: torch.Tensor, k: int) -> torch.Tensor:
    """``[B, T, C]`` -> ``[B, T, k * C]``: each frame with its k // 2 neighbours on either side (edge frames
    repeated at the ends), frame-major, so a linear layer on it is a temporal convolution of width k."""
    pad = k // 2
    padded = torch.cat([x[:, :1].expand(-1, pad, -1), x, x[:, -1:].expand(-1, pad, -1)], dim=1)
    return padded.unfold(1, k, 1).transpose(2, 3).flatten(2)


def temporal_difference(poses: torch.Tensor) -> torch.Tensor:
    """Frame-to-frame motion ``[N, C, T, V]`` -> same shape: the T-1 differences linearly resampled to T
    frames (the HCN motion stream)."""
    n, c, t, v = poses.shape
    diff = poses[:, :, 1:] - poses[:, :, :-1]
    if t < 2:
        return torch.zeros_like(poses)
    flat = diff.permute(0, 1, 3, 2).reshape(n, c * v, t - 1)
    flat = F.interpolate(flat, size=t, mode="linear", align_corners=False)
    return flat.view(n, c, v, t).permute(0, 1, 3, 2)


class CooccurrenceEncoder(nn.Module):
    """Two-stream Hierarchical Co-occurrence Network (Li et al. 2018; Ren et al.'s Fig. 12, App. C).

    ``[N, T, 25, 2]`` poses -> (``[N, embed]``, list of intermediate feature maps). Each stream (positions;
    temporal differences) first learns point-level features with kernels of width 1 along the joint axis,
    then moves joints into channels so later convolutions see all joints at once (co-occurrence).
    """

    def __init__(self, channels: int, embed: int) -> None:
        super().__init__()
        half = channels // 2

        def stream() -> nn.ModuleList:
            return nn.ModuleList([
                nn.Sequential(nn.Conv2d(2, channels, 1), nn.LeakyReLU(0.2)),
                nn.Conv2d(channels, half, (3, 1), padding=(1, 0)),
                nn.Conv2d(NUM_JOINTS, half, 3, padding=1),
                nn.Sequential(nn.Conv2d(half, channels, 3, padding=1), nn.LeakyReLU(0.2)),
            ])

        self.position = stream()
        self.motion = stream()
        self.conv5 = nn.Sequential(nn.Conv2d(2 * channels, 2 * channels, 3, padding=1), nn.LeakyReLU(0.2))
        self.conv6 = nn.Sequential(nn.Conv2d(2 * channels, 4 * channels, 3, padding=1), nn.LeakyReLU(0.2))
        # Pooling to a fixed grid lets one encoder take 5-frame sub-sequences and whole windows alike.
        self.pool = nn.AdaptiveMaxPool2d((2, 2))
        self.fc = nn.Sequential(nn.Linear(16 * channels, embed), nn.LeakyReLU(0.2))

    @staticmethod
    def _run(stream: nn.ModuleList, x: torch.Tensor, feats: list[torch.Tensor]) -> torch.Tensor:
        x = stream[1](stream[0](x))                       # [N, half, T, V]: point-level
        x = x.permute(0, 3, 2, 1)                         # [N, V, T, half]: joints as channels
        x = stream[3](stream[2](x))
        feats.append(x)
        return x

    def forward(self, poses: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
        x = poses.permute(0, 3, 1, 2)                     # [N, 2, T, V]
        feats: list[torch.Tensor] = []
        p = self._run(self.position, x, feats)
        m = self._run(self.motion, temporal_difference(x), feats)
        y = self.conv5(torch.cat([p, m], dim=1))
        feats.append(y)
        y = self.conv6(y)
        feats.append(y)
        return self.fc(self.pool(y).flatten(1)), feats


def sub_sequences(poses: torch.Tensor, length: int, stride: int) -> torch.Tensor:
    """``[B, T, 25, 2]`` -> ``[B, K, length, 25, 2]`` overlapping windows, K = (T - length) // stride + 1."""
    if poses.shape[1] < length:
        raise DancesynthError(f"Sequences of {poses.shape[1]} frames are shorter than the local discriminator's "
                              f"{length}-frame window; use longer training windows.")
    return poses.unfold(1, length, stride).permute(0, 1, 4, 2, 3)


class LocalTemporalDiscriminator(nn.Module):
    """``[B, T, 25, 2]`` -> ``[B, K]`` realism logits, one per overlapping sub-sequence (PatchGAN in time)."""

    def __init__(self, config: RenConfig) -> None:
        super().__init__()
        self.length, self.stride = config.local_window, config.local_stride
        self.encoder = CooccurrenceEncoder(config.d_channels, config.d_embed)
        self.classifier = nn.Sequential(nn.Linear(config.d_embed, config.d_embed // 2), nn.LeakyReLU(0.2),
                                        nn.Linear(config.d_embed // 2, 1))

    def forward(self, poses: torch.Tensor) -> torch.Tensor:
        windows = sub_sequences(poses, self.length, self.stride)
        b, k = windows.shape[:2]
        emb, _ = self.encoder(windows.reshape(b * k, *windows.shape[2:]))
        return self.classifier(emb).view(b, k)


class StructuredSelfAttention(nn.Module):
    """Lin et al. 2017 (Ren et al. Eq. 2-3): A = softmax(W_s2 tanh(W_s1 H^T)) over time, M = A H.

    ``[B, T, k]`` hidden states -> (M ``[B, r, k]``, A ``[B, r, T]``) with r = ``hops``, l = ``dim``.
    """

    def __init__(self, k: int, dim: int, hops: int) -> None:
        super().__init__()
        self.w_s1 = nn.Linear(k, dim, bias=False)
        self.w_s2 = nn.Linear(dim, hops, bias=False)

    def forward(self, h: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        a = torch.softmax(self.w_s2(torch.tanh(self.w_s1(h))).transpose(1, 2), dim=-1)
        return a @ h, a


def attention_penalty(a: torch.Tensor) -> torch.Tensor:
    """||A A^T - I||_F^2 averaged over the batch; ``a`` is ``[B, r, T]``. Pushes the r hops apart."""
    eye = torch.eye(a.shape[1], device=a.device, dtype=a.dtype)
    return ((a @ a.transpose(1, 2) - eye) ** 2).sum(dim=(1, 2)).mean()


class GlobalContentDiscriminator(nn.Module):
    """(``[B, T, 25, 2]`` poses, ``[B, T, S]`` audio) -> ``[B]`` logit that they belong together.

    Split into :meth:`encode_music` and :meth:`judge` so one music encoding serves every pose sequence
    judged against it in a step.

    Ren et al. use a single attention hop (r = 1), for which ||AA^T - I||^2 only rewards a one-hot A; r hops
    (flattened and projected to F^M) keep the penalty meaningful, as in Lin et al.
    """

    def __init__(self, config: RenConfig) -> None:
        super().__init__()
        e = config.d_embed
        self.pose = CooccurrenceEncoder(config.d_channels, e)
        self.music = WaveformMusicEncoder(config.samples_per_frame, config.audio_channels, config.code_dim, e // 2)
        self.attention = StructuredSelfAttention(e, config.attention_dim, config.attention_hops)
        self.music_fc = nn.Linear(config.attention_hops * e, e)
        # "A small classifier composed of a 1D convolutional layer and a FC layer" over [F^M; F^P].
        self.fuse = nn.Sequential(nn.Conv1d(2, 8, 5, padding=2), nn.LeakyReLU(0.2))
        self.fc = nn.Linear(8 * e, 1)

    def encode_music(self, audio: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``[B, T, S]`` -> (F^M ``[B, d_embed]``, attention A ``[B, r, T]``)."""
        m, a = self.attention(self.music(audio))
        return self.music_fc(m.flatten(1)), a

    def judge(self, poses: torch.Tensor, f_m: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """Poses and an encoded music clip -> (``[B]`` logit, pose-encoder feature maps)."""
        f_p, feats = self.pose(poses)
        logit = self.fc(self.fuse(torch.stack([f_m, f_p], dim=1)).flatten(1)).squeeze(1)
        return logit, feats

    def forward(self, poses: torch.Tensor, audio: torch.Tensor) -> torch.Tensor:
        """``[B]`` logits that ``poses`` dance to ``audio``."""
        return self.judge(poses, self.encode_music(audio)[0])[0]


def gradient_penalty(critic: Callable[[torch.Tensor], torch.Tensor], real: torch.Tensor, fake: torch.Tensor,
                     generator: torch.Generator | None = None) -> torch.Tensor:
    """WGAN-GP (Gulrajani et al. 2017): E[(||grad_x critic(x)||_2 - 1)^2] on random interpolates of real and
    fake samples (``[B, ...]``, one mixing weight per sample); ``critic`` maps ``[B, ...]`` -> ``[B]``."""
    alpha = torch.rand((real.shape[0],) + (1,) * (real.dim() - 1), generator=generator,
                       device=real.device if generator is None else generator.device).to(real)
    x = (alpha * real.detach() + (1 - alpha) * fake.detach()).requires_grad_(True)
    (grad,) = torch.autograd.grad(critic(x).sum(), x, create_graph=True)
    return ((grad.flatten(1).norm(dim=1) - 1) ** 2).mean()


def feature_matching(real: list[torch.Tensor], fake: list[torch.Tensor]) -> torch.Tensor:
    """Eq. 6: sum over layers of the mean L1 distance between D's features for real and generated input."""
    return sum(F.l1_loss(f, r.detach()) for r, f in zip(real, fake))


@contextlib.contextmanager
def frozen(*modules: nn.Module) -> Iterator[None]:
    """Stop gradients into ``modules`` (the discriminators during the generator update)."""
    params = [p for m in modules for p in m.parameters()]
    for p in params:
        p.requires_grad_(False)
    try:
        yield
    finally:
        for p in params:
            p.requires_grad_(True)


class RenMethod(Stage1Method):
    """Ren et al. 2020 as a stage-1 method: optimizers ``G``, ``D_local``, ``D_global`` (those the config's
    ablation row uses)."""

    method_name = "ren"
    feature_kind = "waveform"

    def __init__(self, config: RenConfig) -> None:
        super().__init__(config)
        self.generator = RenGenerator(config)
        self.d_local = LocalTemporalDiscriminator(config) if config.uses_local_d else None
        self.d_global = GlobalContentDiscriminator(config) if config.uses_global_d else None
        # The frozen ST-GCN is not part of this model's weights: it is loaded from its own run folder when
        # training starts and is not needed to generate.
        self.perceptual: PosePerceptualLoss | None = None

    def configure_optimizers(self) -> dict[str, torch.optim.Optimizer]:
        cfg = self.config
        if cfg.uses_perceptual and self.perceptual is None:
            device = next(self.parameters()).device
            self.perceptual = PosePerceptualLoss.from_run(cfg.stgcn_run, cfg.perceptual_layer_weights, device)
        opts = {"G": torch.optim.Adam(self.generator.parameters(), lr=cfg.lr_g)}
        if self.d_local is not None:
            opts["D_local"] = torch.optim.Adam(self.d_local.parameters(), lr=cfg.lr_d_local)
        if self.d_global is not None:
            opts["D_global"] = torch.optim.Adam(self.d_global.parameters(), lr=cfg.lr_d_global)
        return opts

    def sample_noise(self, batch: int, frames: int, device: torch.device,
                     generator: torch.Generator | None = None) -> torch.Tensor:
        """``[batch, frames, noise_dim]`` noise held over ``noise_frames`` (:func:`held_noise`)."""
        cfg = self.config
        return held_noise(batch, frames, cfg.noise_dim, cfg.noise_frames, cfg.noise_std, device, generator)

    def training_step(self, batch: Batch, epoch: int) -> dict[str, float]:
        cfg = self.config
        audio, real = batch.features, batch.poses
        k, (b, t) = cfg.variety_samples, real.shape[:2]
        # The music is encoded once; the K noise draws share it as one batch of K x B clips.
        codes = self.generator.music(audio).repeat(k, 1, 1)
        kinematics = self.generator.kinematics
        lengths = None if kinematics is None else kinematics.observe(real).repeat(k, 1, 1)
        fakes = self.generator.decode(codes, self.sample_noise(k * b, t, real.device), lengths,
                                      batch.beats.repeat(k, 1))
        fake, l1 = best_of(fakes.view(k, b, t, NUM_JOINTS, 2), real)
        logs: dict[str, float] = {}
        bone_rows = fakes.new_zeros(()) if kinematics is None else kinematics.take_penalty()

        if self.d_local is not None:
            loss = 0.5 * (bce_with_constant_target(self.d_local(real), 1.0)
                          + bce_with_constant_target(self.d_local(fake.detach()), 0.0))
            self.optimize("D_local", loss)
            logs["d_local"] = loss.item()

        if self.d_global is not None:
            f_m, attn = self.d_global.encode_music(audio)
            logit_real = self.d_global.judge(real, f_m)[0]
            negatives = [bce_with_constant_target(self.d_global.judge(fake.detach(), f_m)[0], 0.0)]
            if real.shape[0] > 1:
                # Real dance on another clip's music: teaches D the dance-music correspondence.
                negatives.append(bce_with_constant_target(self.d_global.judge(real, f_m.roll(1, dims=0))[0], 0.0))
            # Penalised w.r.t. the poses only: real and fake share the music, so there is nothing to
            # interpolate on that side (and no double backward through the GRU is needed).
            f_m_const = f_m.detach()
            gp = gradient_penalty(lambda x: self.d_global.judge(x, f_m_const)[0], real, fake)
            penalty = attention_penalty(attn)
            loss = (0.5 * (bce_with_constant_target(logit_real, 1.0) + sum(negatives) / len(negatives))
                    + cfg.w_gp * gp + cfg.w_attention * penalty)
            self.optimize("D_global", loss)
            logs.update(d_global=loss.item(), gp=gp.item(), attn_penalty=penalty.item())

        discriminators = [d for d in (self.d_local, self.d_global) if d is not None]
        with frozen(*discriminators):
            loss = cfg.w_l1 * l1
            logs["l1"] = l1.item()
            if kinematics is not None:
                loss = loss + bone_rows
                logs["bone_rows"] = bone_rows.item()
            if cfg.w_velocity > 0:
                velocity = F.l1_loss(fake.diff(dim=1), real.diff(dim=1))
                loss = loss + cfg.w_velocity * velocity
                logs["velocity"] = velocity.item()
            if cfg.speed_weight > 0:
                speed = speed_loss(fake, real)
                loss = loss + cfg.speed_weight * speed
                logs["speed"] = speed.item()
            if cfg.motion_weight > 0:
                motion = motion_statistics_loss(fakes, real.repeat(k, 1, 1, 1))
                loss = loss + cfg.motion_weight * motion
                logs["motion"] = motion.item()
            if self.d_local is not None:
                adv_local = bce_with_constant_target(self.d_local(fake), 1.0)
                loss = loss + cfg.w_local * adv_local
                logs["g_local"] = adv_local.item()
            if self.d_global is not None:
                f_m = self.d_global.encode_music(audio)[0]
                logit_fake, feats_fake = self.d_global.judge(fake, f_m)
                feats_real = self.d_global.judge(real, f_m)[1]
                adv_global, fm = bce_with_constant_target(logit_fake, 1.0), feature_matching(feats_real, feats_fake)
                loss = loss + cfg.w_global * adv_global + cfg.w_fm * fm
                logs.update(g_global=adv_global.item(), fm=fm.item())
            if self.perceptual is not None:
                perceptual = self.perceptual(real, fake)
                loss = loss + cfg.w_perceptual * perceptual
                logs["perceptual"] = perceptual.item()
            self.optimize("G", loss)
        logs["g_total"] = loss.item()
        return logs

    @torch.no_grad()
    def generate(self, features: torch.Tensor, beats: torch.Tensor,
                 generator: torch.Generator | None = None) -> torch.Tensor:
        """``[B, T, S]`` audio, ``[B, T]`` beat flags (read with ``beat_phase_input``) -> ``[B, T, 25, 2]``; the
        noise (hence the dance) is drawn from ``generator``."""
        noise = self.sample_noise(features.shape[0], features.shape[1], features.device, generator)
        window = self.config.window_frames if self.config.windowed_generation else 0
        return self.generator(features, noise, window, beats)
