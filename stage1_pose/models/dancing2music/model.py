"""Dancing to Music (Lee et al., NeurIPS 2019): DU-VAE, music style classifier, MM-GAN and recurrent generation.

Training has two phases driven by one ``training_step`` (the phase follows the epoch, see
:attr:`Dancing2MusicConfig.decomp_epochs`):

* Decomposition (Sec. 3.1): every training window is cut at its kinematic beats into dance units
  (:mod:`stage1_pose.models.dancing2music.dance_units`, 32 frames, 4 beats at fixed frames). The DU-VAE learns
  them with an initial-pose encoder ``E_ini`` (MLP, first frame -> z_ini), a movement encoder ``E_mov``
  (GRU -> z_mov) and a unit decoder ``G_uni`` (GRU), trained with Eq. 3-5 (L1 reconstruction, KL on both latents, shift
  reconstruction). The music style classifier (GRU over the 28-d features -> style logits; its last hidden state
  is the style feature s) is trained alongside on the windows' style labels.
* Composition (Sec. 3.2): runs of 3-5 consecutive units are encoded to z_mov sequences by the frozen ``E_mov``.
  MM-GAN: movement-to-dance encoder ``E_mtd`` (GRU, VAE head) -> z_dan, style-to-dance encoder ``E_std``
  (MLP on s and noise) -> z~_dan, recurrent dance decoder ``G_dan`` (GRU) -> z_mov sequence, movement
  discriminator ``D_mov`` conditioned on the units' music features, dance-code discriminator ``D_dan``, style regressor
  ``E_sty``; Eq. 6-10.

Generation (Sec. 3.3, Eq. 11) composes movement codes from the song's style, decodes units recurrently (each
unit starts from the previous unit's last frame, re-encoded by ``E_ini``) and warps them onto the song's beats.

Poses are all 25 BODY_25 joints in model coordinates (:func:`dancesynth.core.skeleton.normalize`, unit = torso
length), flattened to 50 numbers per frame; the paper's 14-joint subset is not used, so generated dances have
feet and face points. Music is ``[B, T, 28]`` standardised ``dancing2music`` features, one row per pose frame,
and the song's beats ``[B, T]`` (bool beat frames), which the beat warper follows.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from dancesynth.core.errors import DancesynthError
from dancesynth.core.motion import kinematic_beats
from dancesynth.core.skeleton import NUM_JOINTS, ROOT
from stage1_pose.models.base import Batch, Stage1Method, bce_with_constant_target
from stage1_pose.models.dancing2music import dance_units as du
from stage1_pose.models.gaussian import kl_to_standard_normal, reparameterize
from stage1_pose.models.kinematics import (
    KinematicOutput,
    absolute_positions,
    bone_vectors,
    forward_kinematics,
    joint_lengths,
    speed_loss,
)
from stage1_pose.models.windowing import smooth_in_time

POSE_DIM = NUM_JOINTS * 2
PHASES = ("decomposition", "composition")


@dataclass(frozen=True)
class Dancing2MusicConfig:
    """Sizes, loss weights and schedule.

    Sizes: ``gru_hidden`` of E_mov, G_uni, E_mtd, G_dan; ``mlp_hidden`` width of the MLPs (E_ini, E_std, E_sty,
    the discriminators); ``z_ini`` / ``z_mov`` / ``z_dan`` latent sizes; ``style_hidden`` the style feature s;
    ``noise_dim`` the noise fed to E_std with s.
    Units: ``min_units`` .. ``max_units`` units per composition sequence; kinematic beat intervals outside
    ``min_beat_gap`` .. ``max_beat_gap`` frames break a run of units; ``shift_x`` / ``shift_y`` the largest
    spatial shift in model units (torso lengths) for augmentation and u' of Eq. 4 (0.5 / 0.2 = the paper's
    ±50 / ±20 px for a 100-px torso).
    Weights: ``w_kl`` (λ_KL^u, λ_KL^d), ``w_shift`` (λ_recon^shift), ``w_adv`` (λ_adv^m, λ_adv^d),
    ``w_style`` (λ_recon^s).
    Movement scale: with ``relative_movement`` E_mov reads each unit as displacements from its first frame (a
    movement independent of where it starts, which the shift loss asks for); ``motion_scale`` multiplies what
    E_mov reads and divides G_uni's outputs, so both networks work at unit scale although joints move only a few
    hundredths of a torso length per frame. The paper feeds poses as they are (False, 1).
    Schedule: ``decomp_epochs`` epochs of decomposition, then composition until ``epochs``; ``composition``
    False is the paper's "w/o L_comp" ablation (units' movement codes drawn from the DU-VAE prior, no MM-GAN).
    Test time: units whose motion is below ``redraw_motion`` times the real units' mean motion are drawn again,
    up to ``redraw_tries`` draws (the authors' code redraws until motion exceeds a threshold); ``redraw_motion`` 0
    switches redrawing off. The beat warper aligns the generated units' kinematic beats with the music beats
    (:func:`stage1_pose.models.dancing2music.dance_units.align_beats`), speeding up or slowing down a beat
    interval by at most ``warp_stretch``; 1 puts the normalised beat frames on the music beats. ``beat_accent`` > 0
    makes the units decelerate on every music beat (:func:`stage1_pose.models.dancing2music.dance_units.warp_units`);
    ``warp_stretch`` 1 and ``beat_accent`` 0 are the paper's warper.
    ``kinematic_output`` (not in the paper) decodes units by forward kinematics (see :class:`UnitDecoder`) and warps
    their bone vectors, so bones keep their length; ``epoch_windows`` > 0 makes an epoch that many training windows
    whatever the dataset's size (0: one pass), so the phases, which count epochs, do not shrink with the data.
    ``speed_weight`` (not in the paper) adds an L1 loss between the joint speeds of reconstructed and real units
    (:func:`~stage1_pose.models.kinematics.speed_loss`): the L1 reconstruction alone decodes about half the real motion.
    ``stage_seconds`` > 0 (not in the paper) keeps a generated dance where it started (:func:`keep_on_stage`): the
    units are shift-invariant (Eq. 4), so nothing holds the dancer in place, and chained units carried a small
    sideways step each, which over a 3-minute song walked the dancer 1,243 px across a 1,280-px canvas. With it,
    E_ini also reads each chained pose as if it stood where the dance began (:meth:`Dancing2MusicMethod._posture_code`).
    ``song_style`` (not in the paper; generation only) gives every group of units the mean of the groups' style
    features, one style for the whole song: decided group by group, a real song's intro and its rest got different
    styles, and the intro was danced at about twice the speed of the rest.
    ``steady_energy`` > 0 (not in the paper; generation only) holds the song's energy: the median motion of the
    first group's first draws sets a target (at least the floor times ``exp(steady_energy)``), and every group is
    drawn again until its motion lies within a factor ``exp(steady_energy)`` of it, keeping the nearest draw: each
    group drew its energy on its own, and 10-s stretches of one dance moved at 0.6-1.8x the real speed.
    ``chain_weight`` > 0 (not in the paper) adds the reconstruction of every real unit that follows another,
    decoded from the last frame of its predecessor's reconstruction, as at test time
    (:meth:`Dancing2MusicMethod.decomposition_losses`): decoded only from true first frames, the units' small errors
    added up along a song, the body folded (mean joint distance from the nose down by a quarter over 3 minutes) and
    the units slowed down.
    """

    feature_dim: int = 28
    num_styles: int = 3
    style_hidden: int = 30
    gru_hidden: int = 1024
    mlp_hidden: int = 1024
    z_ini: int = 10
    z_mov: int = 512
    z_dan: int = 512
    noise_dim: int = 64
    min_units: int = 3
    max_units: int = 5
    min_beat_gap: float = 3.0
    max_beat_gap: float = 20.0
    shift_x: float = 0.5
    shift_y: float = 0.2
    w_kl: float = 0.01
    w_shift: float = 1.0
    w_adv: float = 0.1
    w_style: float = 1.0
    lr: float = 1e-4
    betas: tuple[float, float] = (0.5, 0.999)
    fps: float = 15.0
    batch_size: int = 512
    window_frames: int = 240
    epochs: int = 600
    decomp_epochs: int = 300
    composition: bool = True
    relative_movement: bool = False
    motion_scale: float = 1.0
    redraw_motion: float = 0.5
    redraw_tries: int = 10
    warp_stretch: float = 1.0
    beat_accent: float = 0.0
    kinematic_output: bool = False
    epoch_windows: int = 0
    speed_weight: float = 0.0
    stage_seconds: float = 0.0
    song_style: bool = False
    chain_weight: float = 0.0
    steady_energy: float = 0.0

    def __post_init__(self) -> None:
        if not 1 <= self.min_units <= self.max_units:
            raise DancesynthError(f"Need 1 <= min_units <= max_units, got {self.min_units} and {self.max_units}.")
        if self.redraw_motion < 0 or self.redraw_tries < 1:
            raise DancesynthError(f"Need redraw_motion >= 0 and redraw_tries >= 1, got {self.redraw_motion} and "
                                  f"{self.redraw_tries}.")
        if self.warp_stretch < 1 or not 0 <= self.beat_accent < 1:
            raise DancesynthError(f"Need warp_stretch >= 1 and 0 <= beat_accent < 1, got {self.warp_stretch} and "
                                  f"{self.beat_accent}.")
        if self.composition and self.decomp_epochs >= self.epochs:
            raise DancesynthError(f"decomp_epochs ({self.decomp_epochs}) must be below epochs ({self.epochs}) "
                                  "so the composition phase runs; raise epochs.")
        if self.stage_seconds < 0:
            raise DancesynthError(f"stage_seconds must be >= 0 (0: the paper's free root), got {self.stage_seconds}.")

    @classmethod
    def preset(cls, name: str) -> "Dancing2MusicConfig":
        """A named preset from :data:`DANCING2MUSIC_PRESETS`."""
        if name not in DANCING2MUSIC_PRESETS:
            raise DancesynthError(f"Unknown dancing2music preset {name!r}; "
                                  f"choose one of {', '.join(DANCING2MUSIC_PRESETS)}.")
        return DANCING2MUSIC_PRESETS[name]


# The paper's sizes and weights (Sec. 4); it gives no epoch counts, these are ours.
_PAPER = Dancing2MusicConfig()
# CPU-sized, with the learning rate, movement scale and beat warper that made dances move on the beat in minutes.
_SMALL = Dancing2MusicConfig(gru_hidden=128, mlp_hidden=128, z_mov=32, z_dan=32, noise_dim=16, lr=3e-3,
                             batch_size=32, epochs=420, decomp_epochs=180, relative_movement=True, motion_scale=20.0,
                             warp_stretch=2.0, beat_accent=0.3, kinematic_output=True, epoch_windows=288,
                             speed_weight=5.0, stage_seconds=2.0, song_style=True,
                             chain_weight=1.0, redraw_tries=30, redraw_motion=0.6, steady_energy=0.2)
DANCING2MUSIC_PRESETS: dict[str, Dancing2MusicConfig] = {
    "paper": _PAPER,
    "small": _SMALL,
    "paper-nocomp": replace(_PAPER, composition=False, decomp_epochs=_PAPER.epochs),
    "small-nocomp": replace(_SMALL, composition=False, decomp_epochs=_SMALL.epochs),
}


def mlp(sizes: Sequence[int], layer_norm: bool = False) -> nn.Sequential:
    """Fully connected layers ``sizes[0] -> ... -> sizes[-1]`` with LeakyReLU (and LayerNorm) between them."""
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers.append(nn.Linear(a, b))
        if i < len(sizes) - 2:
            layers += [nn.LayerNorm(b)] if layer_norm else []
            layers.append(nn.LeakyReLU(0.2))
    return nn.Sequential(*layers)


def shift_root(units: torch.Tensor, shift: torch.Tensor) -> torch.Tensor:
    """Spatially shift whole units: ``[N, F, 25, 2]`` model coordinates plus ``[N, 2]`` model units.

    Only the root slot holds an absolute position (the others are root-relative), so only it moves.
    """
    out = units.clone()
    out[:, :, ROOT] = out[:, :, ROOT] + shift[:, None]
    return out


def keep_on_stage(dance: torch.Tensor, sigma: float) -> torch.Tensor:
    """``[T, 25, 2]`` model coordinates with the root's slow wandering (its path smoothed over a Gaussian of ``sigma``
    frames) replaced by where that slow path starts: steps, sways and bounces stay, a walk off the canvas does not.
    The built-in real dances' roots keep within 12 px (std) of their place; their 2-s slow path within 5 px."""
    root = dance[:, ROOT]
    slow = smooth_in_time(root[None], sigma)[0]
    out = dance.clone()
    out[:, ROOT] = root - slow + slow[:1]
    return out


# Draws of a song's first group that set its energy for ``steady_energy``.
_ENERGY_PROBE = 8


def _band_miss(motion: float, band: tuple[float, float]) -> float:
    """How far (log ratio, 0 inside) a group's motion lies outside ``band`` = (lowest, highest) motion."""
    low, high = band
    motion = max(motion, 1e-12)
    return math.log(low / motion) if motion < low else math.log(motion / high) if motion > high else 0.0


def unit_motion(units: torch.Tensor) -> float:
    """Mean joint displacement per frame (model units, joints placed absolutely) of ``[n, 32, 50]`` units."""
    xy = absolute_positions(units.detach().reshape(*units.shape[:2], NUM_JOINTS, 2))
    return float((xy[:, 1:] - xy[:, :-1]).norm(dim=-1).mean()) if units.shape[1] > 1 else 0.0


class InitialPoseEncoder(nn.Module):
    """E_ini: one pose ``[N, 50]`` -> (mu, logvar) of z_ini, each ``[N, z_ini]`` (3 FC layers)."""

    def __init__(self, hidden: int, z_ini: int) -> None:
        super().__init__()
        self.net = mlp([POSE_DIM, hidden, hidden, 2 * z_ini])

    def forward(self, pose: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.net(pose).chunk(2, dim=-1)


class MovementEncoder(nn.Module):
    """E_mov: a unit ``[N, 32, 50]`` -> (mu, logvar) of z_mov, each ``[N, z_mov]`` (GRU, last hidden state).

    ``relative``: read the unit as displacements from its first frame; ``scale`` multiplies what is read.
    """

    def __init__(self, hidden: int, z_mov: int, relative: bool = False, scale: float = 1.0) -> None:
        super().__init__()
        self.gru = nn.GRU(POSE_DIM, hidden, batch_first=True)
        self.head = nn.Linear(hidden, 2 * z_mov)
        self.relative, self.scale = relative, scale

    def forward(self, unit: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = unit - unit[:, :1] if self.relative else unit
        return self.head(self.gru(x * self.scale)[1][0]).chunk(2, dim=-1)


class UnitDecoder(nn.Module):
    """G_uni: (z_ini, z_mov) -> a unit ``[N, 32, 50]``.

    The GRU's initial state comes from both codes and it reads both codes plus the unit phase (0..1) at every
    step. Its outputs are displacements from an anchor pose, taken relative to the first step so frame 0 is the
    anchor exactly. The anchor is the unit's true first frame in training and the previous unit's last frame at
    test time, which makes consecutive units join without a jump; without one (a dance's first unit) it is z_ini
    decoded by an MLP (``init_pose``). Displacements are ``scale`` times smaller than the network's outputs. With
    ``kinematic`` they displace the anchor's bone vectors (:func:`~stage1_pose.models.kinematics.bone_vectors`) and
    the unit is placed by forward kinematics with the anchor's bone lengths, so a dance keeps its first pose's body.
    """

    def __init__(self, hidden: int, z_ini: int, z_mov: int, frames: int = du.UNIT_FRAMES, scale: float = 1.0,
                 kinematic: bool = False) -> None:
        super().__init__()
        self.frames, self.scale = frames, scale
        self.init_pose = mlp([z_ini, hidden, hidden, POSE_DIM])
        self.h0 = nn.Linear(z_ini + z_mov, hidden)
        self.gru = nn.GRU(z_ini + z_mov + 1, hidden, batch_first=True)
        self.out = nn.Linear(hidden, POSE_DIM)
        self.kinematics = KinematicOutput() if kinematic else None

    def initial(self, z_ini: torch.Tensor) -> torch.Tensor:
        """A dance's first pose ``[N, 50]`` from ``z_ini`` (with kinematic output: the training data's mean body)."""
        pose = self.init_pose(z_ini)
        if self.kinematics is None:
            return pose
        return self.kinematics(pose.unflatten(-1, (NUM_JOINTS, 2))).flatten(-2)

    def forward(self, z_ini: torch.Tensor, z_mov: torch.Tensor, anchor: torch.Tensor | None = None) -> torch.Tensor:
        codes = torch.cat([z_ini, z_mov], dim=-1)
        phase = torch.linspace(0.0, 1.0, self.frames, device=codes.device)
        inputs = torch.cat([codes[:, None].expand(-1, self.frames, -1),
                            phase[None, :, None].expand(codes.shape[0], -1, 1)], dim=-1)
        h = self.gru(inputs, torch.tanh(self.h0(codes))[None])[0]
        moves = self.out(h) / self.scale
        anchor = self.initial(z_ini) if anchor is None else anchor
        if self.kinematics is None:
            return anchor[:, None] + moves - moves[:, :1]
        first = anchor.unflatten(-1, (NUM_JOINTS, 2))
        raw = bone_vectors(first)[:, None] + (moves - moves[:, :1]).unflatten(-1, (NUM_JOINTS, 2))
        return self.kinematics(raw, joint_lengths(first)[:, None]).flatten(-2)


class MusicStyleClassifier(nn.Module):
    """Music style classifier: features ``[N, T, 28]`` -> (logits ``[N, styles]``, style feature s ``[N, 30]``)."""

    def __init__(self, feature_dim: int, hidden: int, num_styles: int) -> None:
        super().__init__()
        self.gru = nn.GRU(feature_dim, hidden, batch_first=True)
        self.head = nn.Linear(hidden, num_styles)

    def forward(self, features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        s = self.gru(features)[1][0]
        return self.head(s), s


class MovementToDanceEncoder(nn.Module):
    """E_mtd: z_mov sequence ``[N, n, z_mov]`` -> (mu, logvar) of z_dan, each ``[N, z_dan]`` (GRU)."""

    def __init__(self, z_mov: int, hidden: int, z_dan: int) -> None:
        super().__init__()
        self.gru = nn.GRU(z_mov, hidden, batch_first=True)
        self.head = nn.Linear(hidden, 2 * z_dan)

    def forward(self, z_movs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.head(self.gru(z_movs)[1][0]).chunk(2, dim=-1)


class DanceToMovementDecoder(nn.Module):
    """G_dan: z_dan ``[N, z_dan]`` -> z_mov sequence ``[N, n, z_mov]`` (GRU started from z_dan, reading z_dan and
    its own previous output at every step)."""

    def __init__(self, z_dan: int, hidden: int, z_mov: int) -> None:
        super().__init__()
        self.z_mov = z_mov
        self.h0 = nn.Linear(z_dan, hidden)
        self.cell = nn.GRUCell(z_dan + z_mov, hidden)
        self.out = nn.Linear(hidden, z_mov)

    def forward(self, z_dan: torch.Tensor, n: int) -> torch.Tensor:
        h = torch.tanh(self.h0(z_dan))
        prev = z_dan.new_zeros(z_dan.shape[0], self.z_mov)
        outs = []
        for _ in range(n):
            h = self.cell(torch.cat([z_dan, prev], dim=-1), h)
            prev = self.out(h)
            outs.append(prev)
        return torch.stack(outs, dim=1)


class StyleToDanceEncoder(nn.Module):
    """E_std: (s ``[N, style_hidden]``, noise ``[N, noise_dim]``) -> z~_dan ``[N, z_dan]`` (3 FC layers)."""

    def __init__(self, style_hidden: int, noise_dim: int, hidden: int, z_dan: int) -> None:
        super().__init__()
        self.net = mlp([style_hidden + noise_dim, hidden, hidden, z_dan])

    def forward(self, s: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
        return self.net(torch.cat([s, noise], dim=-1))


class MovementDiscriminator(nn.Module):
    """D_mov: (z_mov sequence ``[N, n, z_mov]``, units' music features ``[N, n, 32, 28]``) -> logit ``[N]``.

    Each unit's music is summarised by a GRU; a GRU runs over (z_mov, music summary) pairs and 5 FC layers with
    layer normalisation judge its last state.
    """

    def __init__(self, z_mov: int, feature_dim: int, music_hidden: int, hidden: int) -> None:
        super().__init__()
        self.audio_gru = nn.GRU(feature_dim, music_hidden, batch_first=True)
        self.seq_gru = nn.GRU(z_mov + music_hidden, hidden, batch_first=True)
        self.net = mlp([hidden] * 5 + [1], layer_norm=True)

    def forward(self, z_movs: torch.Tensor, feature_units: torch.Tensor) -> torch.Tensor:
        n, u = feature_units.shape[:2]
        a = self.audio_gru(feature_units.flatten(0, 1))[1][0].view(n, u, -1)
        return self.net(self.seq_gru(torch.cat([z_movs, a], dim=-1))[1][0]).squeeze(-1)


class Dancing2MusicMethod(Stage1Method):
    """Dancing2Music as a stage-1 method: optimizers ``vae`` and ``style`` (decomposition phase), ``gen`` and
    ``disc`` (composition phase)."""

    method_name = "dancing2music"
    feature_kind = "dancing2music"

    def __init__(self, config: Dancing2MusicConfig) -> None:
        super().__init__(config)
        c = config
        self.e_ini = InitialPoseEncoder(c.mlp_hidden, c.z_ini)
        self.e_mov = MovementEncoder(c.gru_hidden, c.z_mov, c.relative_movement, c.motion_scale)
        self.g_uni = UnitDecoder(c.gru_hidden, c.z_ini, c.z_mov, scale=c.motion_scale, kinematic=c.kinematic_output)
        self.style = MusicStyleClassifier(c.feature_dim, c.style_hidden, c.num_styles)
        self.e_mtd = MovementToDanceEncoder(c.z_mov, c.gru_hidden, c.z_dan)
        self.g_dan = DanceToMovementDecoder(c.z_dan, c.gru_hidden, c.z_mov)
        self.e_std = StyleToDanceEncoder(c.style_hidden, c.noise_dim, c.mlp_hidden, c.z_dan)
        self.e_sty = mlp([c.z_dan, c.mlp_hidden, c.mlp_hidden, c.style_hidden])
        self.d_mov = MovementDiscriminator(c.z_mov, c.feature_dim, c.style_hidden, c.mlp_hidden)
        self.d_dan = mlp([c.z_dan] + [c.mlp_hidden] * 4 + [1], layer_norm=True)
        # Typical kinematic beat interval of the training dances (frames): at test time one dance beat spans as
        # many music beats as fit in it. Running mean over training windows, saved with the weights.
        self.register_buffer("beat_interval", torch.tensor(c.fps / 2.0))
        self.register_buffer("beat_windows", torch.tensor(0, dtype=torch.int64))
        # Mean motion of the real training units (running mean over decomposition batches): the redraw threshold.
        self.register_buffer("unit_motion", torch.tensor(0.0))
        # Optimisation steps done in each phase, so generation knows whether the MM-GAN has trained.
        self.register_buffer("phase_steps", torch.zeros(len(PHASES), dtype=torch.int64))

    def load_state_dict(self, state_dict: Mapping[str, Any], strict: bool = True, assign: bool = False) -> Any:
        # Runs saved before the redraw threshold existed load with it at 0: they generate without redraws.
        state = dict(state_dict)
        state.setdefault("unit_motion", torch.tensor(0.0))
        return super().load_state_dict(state, strict, assign)

    def _groups(self) -> dict[str, list[nn.Module]]:
        return {"vae": [self.e_ini, self.e_mov, self.g_uni], "style": [self.style],
                "gen": [self.e_mtd, self.g_dan, self.e_std, self.e_sty], "disc": [self.d_mov, self.d_dan]}

    def configure_optimizers(self) -> dict[str, torch.optim.Optimizer]:
        c = self.config
        names = ("vae", "style", "gen", "disc") if c.composition else ("vae", "style")
        groups = self._groups()
        return {k: torch.optim.Adam([p for m in groups[k] for p in m.parameters()], lr=c.lr, betas=c.betas)
                for k in names}

    @property
    def composes(self) -> bool:
        """Whether generation composes movements with the MM-GAN (composition configured and trained)."""
        return self.config.composition and int(self.phase_steps[1]) > 0

    def phase(self, epoch: int) -> str:
        """``decomposition`` for the first ``decomp_epochs`` epochs (0-based ``epoch``), then ``composition``."""
        return PHASES[int(self.config.composition and epoch >= self.config.decomp_epochs)]

    def curriculum_state(self) -> dict[str, object]:
        """Steps done per phase, for the run's JSON (the ``phase_steps`` buffer in the weights is what counts)."""
        return {"phase_steps": [int(v) for v in self.phase_steps]}

    # --- data: windows -> units -------------------------------------------------------------------------------

    def window_runs(self, poses: np.ndarray) -> list[list[np.ndarray]]:
        """Unit runs (``[n, 5]`` beat frames each, :func:`stage1_pose.models.dancing2music.dance_units.unit_runs`)
        of every window of ``[B, T, 25, 2]`` model-coordinate poses; also updates the running beat interval."""
        c = self.config
        runs = []
        for window in poses:
            beats = np.asarray(kinematic_beats(absolute_positions(window), c.fps), dtype=np.float64)
            runs.append(du.unit_runs(beats, c.min_beat_gap, c.max_beat_gap))
            gaps = np.diff(beats)
            gaps = gaps[(gaps >= c.min_beat_gap) & (gaps <= c.max_beat_gap)]
            if self.training and gaps.size:
                self.beat_windows += 1
                self.beat_interval += (float(np.median(gaps)) - self.beat_interval) / self.beat_windows
        return runs

    def random_shift(self, n: int, device: torch.device) -> torch.Tensor:
        """``[n, 2]`` uniform shifts within ±shift_x, ±shift_y model units."""
        limit = torch.tensor([self.config.shift_x, self.config.shift_y], device=device)
        return (torch.rand(n, 2, device=device) * 2.0 - 1.0) * limit

    # --- DU-VAE -----------------------------------------------------------------------------------------------

    def decomposition_losses(self, units: torch.Tensor, follows: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
        """Eq. 3-5 on ``[N, 32, 25, 2]`` units: ``recon``, ``kl``, ``shift``, ``chain`` and the weighted ``total``.

        ``follows`` (``[P]`` indices ``i``: unit ``i + 1`` continues unit ``i`` in the same dance) feeds ``chain``:
        unit ``i + 1`` decoded from the last frame of unit ``i``'s reconstruction (detached) against the real one,
        its root moved to start there; the units' random shifts differ, the dance's path does not."""
        c = self.config
        if self.g_uni.kinematics is not None:
            self.g_uni.kinematics.observe(units)
        u = shift_root(units, self.random_shift(units.shape[0], units.device))
        flat = u.flatten(2)
        mu_i, lv_i = self.e_ini(flat[:, 0])
        mu_m, lv_m = self.e_mov(flat)
        z_ini = reparameterize(mu_i, lv_i)
        # Decoded from the true first frame, as at test time (where the anchor is the previous unit's last
        # frame), so the decoder never learns a correction jump for an imperfect anchor; the initial pose's own
        # reconstruction from z_ini (used for a dance's first unit) is its own term.
        anchor = flat[:, 0]
        decoded = self.g_uni(z_ini, reparameterize(mu_m, lv_m), anchor)
        recon = F.l1_loss(decoded, flat) + F.l1_loss(self.g_uni.initial(z_ini), anchor)
        # KL averaged over latent numbers and batch, so the weight λ_KL does not depend on the latent size.
        kl = kl_to_standard_normal(mu_i, lv_i) + kl_to_standard_normal(mu_m, lv_m)
        # A relative movement encoder subtracts the unit's first frame, which cancels a whole-unit shift exactly:
        # its code for the shifted unit is the one just computed, so a second pass (a tenth of a training step)
        # would only repeat it.
        if c.relative_movement:
            mov_shifted = (mu_m, lv_m)
        else:
            mov_shifted = self.e_mov(shift_root(u, self.random_shift(units.shape[0], units.device)).flatten(2))
        shift = F.l1_loss(self.g_uni(z_ini, reparameterize(*mov_shifted), anchor), flat)
        chain = torch.zeros((), device=units.device)
        if follows is not None and len(follows):
            anchor_next = decoded[follows, -1].detach()
            target = u[follows + 1].clone()
            target[:, :, ROOT] += (anchor_next.unflatten(-1, (NUM_JOINTS, 2))[:, ROOT] - target[:, 0, ROOT])[:, None]
            chained = self.g_uni(reparameterize(*self.e_ini(anchor_next)),
                                 reparameterize(mu_m[follows + 1], lv_m[follows + 1]), anchor_next)
            chain = F.l1_loss(chained, target.flatten(2))
        total = recon + c.w_kl * kl + c.w_shift * shift + c.chain_weight * chain
        if c.speed_weight:
            total = total + c.speed_weight * speed_loss(decoded.unflatten(-1, (NUM_JOINTS, 2)), u)
        if self.g_uni.kinematics is not None:
            total = total + self.g_uni.kinematics.take_penalty()
        return {"recon": recon, "kl": kl, "shift": shift, "chain": chain, "total": total}

    def _decomposition_step(self, batch: Batch) -> dict[str, float]:
        logits, _ = self.style(batch.features)
        style_loss = F.cross_entropy(logits, batch.style)
        self.optimize("style", style_loss)
        logs = {"style_ce": style_loss.item(),
                "style_acc": (logits.argmax(-1) == batch.style).float().mean().item()}
        poses = batch.poses.detach().cpu().numpy()
        units = [du.cut_units(p, r) for p, runs in zip(poses, self.window_runs(poses)) for r in runs]
        if not units:
            return logs | {"units": 0.0}
        real = torch.from_numpy(np.concatenate(units)).to(batch.poses.device)
        follows = None
        if self.config.chain_weight:
            # Within a run unit i + 1 starts where unit i ends; the last unit of a run has no successor.
            ends = np.cumsum([len(run) for run in units])
            follows = torch.from_numpy(np.setdiff1d(np.arange(ends[-1]), ends - 1)).to(batch.poses.device)
        losses = self.decomposition_losses(real, follows)
        self.optimize("vae", losses["total"])
        self.phase_steps[0] += 1
        self.unit_motion += (unit_motion(real.flatten(2)) - self.unit_motion) / self.phase_steps[0]
        return logs | {f"vae_{k}": v.item() for k, v in losses.items()} | {"units": float(sum(map(len, units)))}

    # --- MM-GAN -----------------------------------------------------------------------------------------------

    def _composition_sequences(self, batch: Batch) -> tuple[torch.Tensor, torch.Tensor] | None:
        """Runs of n consecutive units (n drawn in min_units..max_units, lowered to what the windows have):
        poses ``[N, n, 32, 25, 2]`` and music features ``[N, n, 32, 28]``, or None when no window has min_units."""
        c = self.config
        poses, features = batch.poses.detach().cpu().numpy(), batch.features.detach().cpu().numpy()
        runs = [(k, r) for k, rs in enumerate(self.window_runs(poses)) for r in rs if len(r) >= c.min_units]
        if not runs:
            return None
        n = min(int(torch.randint(c.min_units, c.max_units + 1, ())), max(len(r) for _, r in runs))
        picked = [(k, r[s:s + n]) for k, r in runs if len(r) >= n for s in [int(torch.randint(len(r) - n + 1, ()))]]
        dev = batch.poses.device
        p = torch.from_numpy(np.stack([du.cut_units(poses[k], r) for k, r in picked])).to(dev)
        f = torch.from_numpy(np.stack([du.cut_units(features[k], r) for k, r in picked])).to(dev)
        return p, f

    def style_feature(self, feature_units: torch.Tensor) -> torch.Tensor:
        """Style feature s ``[N, style_hidden]`` of the music under ``[N, n, 32, 28]`` units."""
        return self.style(feature_units.flatten(1, 2))[1]

    def _composition_step(self, batch: Batch) -> dict[str, float]:
        c = self.config
        seqs = self._composition_sequences(batch)
        if seqs is None:
            return {"sequences": 0.0}
        units, music = seqs
        n_seq, n = units.shape[:2]
        with torch.no_grad():
            z_mov = self.e_mov(units.flatten(0, 1).flatten(2))[0].view(n_seq, n, -1)
            s = self.style_feature(music)
        mu, logvar = self.e_mtd(z_mov)
        z_dan = reparameterize(mu, logvar)
        z_dan_music = self.e_std(s, torch.randn(n_seq, c.noise_dim, device=units.device))
        z_mov_hat, z_mov_music = self.g_dan(z_dan, n), self.g_dan(z_dan_music, n)

        d_loss = 0.5 * (bce_with_constant_target(self.d_mov(z_mov_hat.detach(), music), 1.0)
                        + bce_with_constant_target(self.d_mov(z_mov_music.detach(), music), 0.0)
                        + bce_with_constant_target(self.d_dan(z_dan.detach()).squeeze(-1), 1.0)
                        + bce_with_constant_target(self.d_dan(z_dan_music.detach()).squeeze(-1), 0.0))
        self.optimize("disc", d_loss)

        recon = F.l1_loss(z_mov_hat, z_mov)
        style = (self.e_sty(z_dan) - s).abs().mean() + (self.e_sty(z_dan_music) - s).abs().mean()
        adv_mov = bce_with_constant_target(self.d_mov(z_mov_music, music), 1.0)
        adv_dan = bce_with_constant_target(self.d_dan(z_dan_music).squeeze(-1), 1.0)
        kl = kl_to_standard_normal(mu, logvar)
        total = recon + c.w_style * style + c.w_adv * (adv_mov + adv_dan) + c.w_kl * kl
        self.optimize("gen", total)
        # The discriminators' gradients from the generator loss are discarded by the next zero_grad.
        self.phase_steps[1] += 1
        return {"d": d_loss.item(), "recon_m": recon.item(), "style_l1": style.item(), "adv_m": adv_mov.item(),
                "adv_d": adv_dan.item(), "kl_d": kl.item(), "g_total": total.item(), "sequences": float(n_seq)}

    def training_step(self, batch: Batch, epoch: int) -> dict[str, float]:
        if batch.style.max().item() >= self.config.num_styles:
            raise DancesynthError(f"The dataset has more styles than the model's {self.config.num_styles}; "
                                  "set num_styles in the config to the dataset's style count.")
        if self.phase(epoch) == "decomposition":
            return self._decomposition_step(batch)
        return self._composition_step(batch)

    # --- generation -------------------------------------------------------------------------------------------

    def _randn(self, shape: tuple[int, ...], generator: torch.Generator | None) -> torch.Tensor:
        device = next(self.parameters()).device
        return torch.randn(shape, generator=generator,
                           device=device if generator is None else generator.device).to(device)

    def movement_codes(self, count: int, style: torch.Tensor | None,
                       generator: torch.Generator | None) -> torch.Tensor:
        """Movement codes ``[count, z_mov]``: z~_dan from a music style feature ``[1, style_hidden]``
        (:meth:`style_feature`) through E_std, decoded by G_dan; ``style`` None (the ablation, and a model saved
        before its composition phase trained, e.g. previews during decomposition) draws them from the DU-VAE prior."""
        c = self.config
        if style is None:
            return self._randn((count, c.z_mov), generator)
        return self.g_dan(self.e_std(style, self._randn((1, c.noise_dim), generator)), count)[0]

    def dance_units(self, feature_units: torch.Tensor, generator: torch.Generator | None,
                    tempo_scale: float = 1.0) -> torch.Tensor:
        """Eq. 11: units ``[n, 32, 25, 2]`` for ``[n, 32, 28]`` feature units, decoded one after another; the first
        starts from a prior sample of z_ini, each next one from the previous unit's last frame (encoded by E_ini).

        Units are drawn in groups (max_units composed together, or one at a time from the prior). As in the
        authors' test code, a group whose motion stays below ``redraw_motion`` times the real units' mean motion
        is drawn again, up to ``redraw_tries`` draws, keeping the liveliest. ``tempo_scale`` is the song's dance
        beat interval over the training one (frames per frames): above 1 the warper plays the units that much slower
        than they were learnt, so the floor rises by it and holds for the motion as danced (below 1 it stays: a unit
        must be lively in itself). With ``steady_energy`` a group is also drawn again while its motion lies outside
        the song's band (see :class:`Dancing2MusicConfig`). Each group's style feature is read once, from its own
        units, or with ``song_style`` as the mean of all groups' style features.
        """
        c = self.config
        z_ini = self._randn((1, c.z_ini), generator)
        anchor = None
        home = self.g_uni.initial(z_ini).view(NUM_JOINTS, 2)[ROOT] if c.stage_seconds > 0 else None
        floor = c.redraw_motion * float(self.unit_motion) * max(1.0, tempo_scale)
        size = c.max_units if self.composes else 1
        starts = range(0, len(feature_units), size)
        styles = [self.style_feature(feature_units[None, start:start + size]) if self.composes else None
                  for start in starts]
        if c.song_style and self.composes:
            styles = [torch.stack(styles).mean(0)] * len(styles)
        band = (floor, np.inf)  # (lowest, highest) motion a group may have
        energy_known = c.steady_energy == 0
        groups = []
        for start, style in zip(starts, styles):
            count = len(feature_units[start:start + size])
            draws = []  # (units, motion)
            for _ in range(c.redraw_tries):
                units = self._decode_group(z_ini, anchor, self.movement_codes(count, style, generator), home)
                draws.append((units, unit_motion(units)))
                if not energy_known:
                    if len(draws) < min(_ENERGY_PROBE, c.redraw_tries):
                        continue
                    # The first group's draws tell the song's energy; the band sits above the floor.
                    target = max(float(np.median([d[1] for d in draws])), floor * np.exp(c.steady_energy))
                    band = (target * np.exp(-c.steady_energy), target * np.exp(c.steady_energy))
                    energy_known = True
                if _band_miss(draws[-1][1], band) == 0:
                    break
            best = min(draws, key=lambda d: _band_miss(d[1], band))[0]
            groups.append(best)
            anchor = best[-1:, -1]
            z_ini = self._posture_code(anchor, home)
        return torch.cat(groups).view(len(feature_units), du.UNIT_FRAMES, NUM_JOINTS, 2)

    def _decode_group(self, z_ini: torch.Tensor, anchor: torch.Tensor | None, z_movs: torch.Tensor,
                      home: torch.Tensor | None) -> torch.Tensor:
        """Units ``[n, 32, 50]`` from ``[n, z_mov]`` codes, continuing from ``anchor`` (``[1, 50]`` or None)."""
        units = []
        for z_mov in z_movs:
            unit = self.g_uni(z_ini, z_mov[None], anchor)
            units.append(unit[0])
            anchor = unit[:, -1]
            z_ini = self._posture_code(anchor, home)
        return torch.stack(units)

    def _posture_code(self, pose: torch.Tensor, home: torch.Tensor | None) -> torch.Tensor:
        """z_ini ``[1, z_ini]`` (E_ini's mean) of a ``[1, 50]`` pose, read with its root at ``home`` (``[2]``, model
        units) unless None: E_ini reads where the root is, and the units' small steps, which add up along a song,
        took z_ini ever further from its prior (norm 2.4 to 12.9 over 3 minutes) and the dance's motion down."""
        if home is not None:
            pose = pose.view(-1, NUM_JOINTS, 2).clone()
            pose[:, ROOT] = home
            pose = pose.flatten(1)
        return self.e_ini(pose)[0]

    @torch.no_grad()
    def generate(self, features: torch.Tensor, beats: torch.Tensor,
                 generator: torch.Generator | None = None) -> torch.Tensor:
        """``[B, T, 28]`` features and ``[B, T]`` beat flags -> ``[B, T, 25, 2]`` model-coordinate dances.

        The beat warper lays the units on each song's beat frames; a song needs at least two. Noise (the initial
        pose, the style-to-dance noise) is drawn from ``generator``.
        """
        b, t = features.shape[:2]
        out = []
        for i in range(b):
            feats = features[i].cpu().numpy()
            music_beats = torch.nonzero(beats[i]).flatten().cpu().numpy().astype(np.float64)
            grid = du.beat_grid(music_beats, t, du.beat_stride(music_beats, float(self.beat_interval)))
            n = du.units_needed(grid)
            # Unit i spans grid beats 4i..4i+4; past the grid's end the same interval continues.
            extra = np.arange(1, 4 * n + 2 - len(grid)) * float(np.median(np.diff(grid)))
            full = np.concatenate([grid, grid[-1] + extra])
            spans = np.stack([full[4 * k:4 * k + 5] for k in range(n)])
            feature_units = torch.from_numpy(du.cut_units(feats, spans)).to(features.device)
            tempo_scale = float(np.median(np.diff(grid))) / float(self.beat_interval)
            units = self.dance_units(feature_units, generator, tempo_scale).cpu().numpy()
            unit_beats = None  # the paper's warper: the normalised beat frames
            if self.config.warp_stretch > 1:
                moves = kinematic_beats(absolute_positions(units.reshape(-1, NUM_JOINTS, 2)), self.config.fps)
                unit_beats = du.align_beats(moves, len(grid), self.config.warp_stretch)
            dance = self._warp(units, grid, t, unit_beats)
            out.append(keep_on_stage(dance, self.config.stage_seconds * self.config.fps)
                       if self.config.stage_seconds > 0 else dance)
        return torch.stack(out).to(features.device)

    def _warp(self, units: np.ndarray, grid: np.ndarray, frames: int, unit_beats: np.ndarray | None) -> torch.Tensor:
        """:func:`~stage1_pose.models.dancing2music.dance_units.warp_units` of ``[n, 32, 25, 2]`` units -> ``[frames,
        25, 2]``; kinematic units are warped as bone vectors and placed again with their body's lengths, since
        interpolating joint positions shortens a turning bone."""
        accent = self.config.beat_accent
        if self.g_uni.kinematics is None:
            return torch.from_numpy(du.warp_units(units, grid, frames, unit_beats, accent))
        poses = torch.from_numpy(units)
        raw = du.warp_units(bone_vectors(poses).numpy(), grid, frames, unit_beats, accent)
        return forward_kinematics(torch.from_numpy(raw), joint_lengths(poses[0, 0]))
