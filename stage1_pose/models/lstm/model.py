"""The LSTM baseline of Dance Revolution's comparison (after Shlizerman et al. 2018): music features ->
stacked LSTM -> poses, one pose per frame, deterministic, trained with L1; the baseline does not read the beats. The
``small`` preset places its poses by forward kinematics (bones keep their length), adds a loss on each joint's speed,
reads each frame's beat phase, smooths the root's path and drops music features in training.

Shapes: features ``[B, T, feature_dim]`` standardised features; beat flags ``[B, T]``; poses ``[B, T, 25, 2]`` model
coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import NUM_JOINTS, ROOT
from stage1_pose.models.base import Batch, Stage1Method
from stage1_pose.models.beat_clock import with_beat_phase
from stage1_pose.models.dance_revolution.music_input import TEMPOGRAM_WINDOW
from stage1_pose.models.kinematics import KinematicOutput, mean_raw_rows, speed_loss
from stage1_pose.models.windowing import smooth_in_time, windowed


@dataclass(frozen=True)
class LSTMConfig:
    """``hidden`` units in each of ``layers`` LSTM layers; training window ``window_frames`` frames.

    Not in the baseline (``paper`` keeps it as published): ``kinematic_output`` places the poses by forward
    kinematics (:mod:`stage1_pose.models.kinematics`); ``speed_weight`` adds an L1 loss between each joint's speed
    and the real dance's (:func:`~stage1_pose.models.kinematics.speed_loss`); ``epoch_windows`` > 0 makes an epoch
    that many training windows whatever the dataset's size (0: one pass); ``windowed_generation`` runs the LSTM
    over overlapping windows of ``window_frames`` (:func:`~stage1_pose.models.windowing.windowed`), the length it
    was trained on, instead of once over the whole song, where its state drifts and the dance slows down;
    ``stride_frames`` is the hop between training windows (0: the trainer's default, half a window); ``small``
    starts one every 7 frames, so windows begin at every phase of the beat and the bar: trained on windows that
    began every 45 frames (3 s, on the built-in songs' bars) the LSTM turned the body upside down in 30 % of the
    frames of windows that began elsewhere, as generation's do (7 frames: 0.6 %; not a guarantee);
    ``beat_phase_input`` appends each frame's phase between two beats to its features
    (:mod:`stage1_pose.models.beat_clock`): the features' beat one-hot says when a beat is, not when the next comes;
    ``root_smoothing`` > 0 smooths the root's (MidHip's) output row over a Gaussian of that many frames, in training
    and generation alike: each frame's root was regressed on its own and jittered, which moved every joint on the
    canvas, the legs most of all relative to their own motion; ``feature_dropout`` drops that share of the music
    features' entries in training (never the beat phase): with it, its dances to real recordings, whose timbre the
    built-in songs do not share, hit the true beats on more songs; ``centre_features`` subtracts from the music
    features their mean over the window the LSTM reads (a training window, or a generation window), so an offset
    that lasts the window (a recording's timbre, its level) is not heard; ``mean_pose_start`` sets the output
    layer's bias, before the first training step, to the first batch's mean root position and bone vectors: a
    kinematic output normalises each bone's direction, and a torso that started pointing down could stay there;
    ``tempogram`` False leaves out the features' last ``TEMPOGRAM_WINDOW`` (the tempogram, 384 of the 438): the
    built-in songs span 60-135 BPM, and on faster real recordings that never-seen tempogram made the LSTM dance
    whole passages at a quarter of the real speed (set to its training mean, the same passages moved at 0.5-1.1x);
    the beat phase still says where the beats are.
    """

    feature_dim: int = 438
    hidden: int = 1024
    layers: int = 3
    dropout: float = 0.1
    lr: float = 1e-4
    batch_size: int = 32
    window_frames: int = 900
    epochs: int = 500
    epoch_windows: int = 0
    kinematic_output: bool = False
    speed_weight: float = 0.0
    windowed_generation: bool = False
    beat_phase_input: bool = False
    stride_frames: int = 0
    root_smoothing: float = 0.0
    feature_dropout: float = 0.0
    centre_features: bool = False
    mean_pose_start: bool = False
    tempogram: bool = True

    def __post_init__(self) -> None:
        if not self.tempogram and self.feature_dim <= TEMPOGRAM_WINDOW:
            raise DancesynthError(f"feature_dim {self.feature_dim} leaves no music features once the "
                                  f"{TEMPOGRAM_WINDOW}-column tempogram is left out; use the dance_revolution "
                                  "features (438) or tempogram=true.")

    @classmethod
    def preset(cls, name: str) -> "LSTMConfig":
        """A named preset from :data:`LSTM_PRESETS`."""
        if name not in LSTM_PRESETS:
            raise DancesynthError(f"Unknown lstm preset {name!r}; choose one of {', '.join(LSTM_PRESETS)}.")
        return LSTM_PRESETS[name]


LSTM_PRESETS: dict[str, LSTMConfig] = {
    # Sized like Dance Revolution's decoder and trained like it (Adam 1e-4, batch 32, 60-s windows).
    "paper": LSTMConfig(),
    # epoch_windows: what one pass over the built-in dataset's 48 training clips of 60 s gives.
    "small": LSTMConfig(hidden=128, layers=2, dropout=0.0, lr=1e-3, batch_size=16, window_frames=90, epochs=60,
                        epoch_windows=912, kinematic_output=True, speed_weight=5.0, windowed_generation=True,
                        beat_phase_input=True, stride_frames=7, root_smoothing=2.0, feature_dropout=0.5,
                        centre_features=True, mean_pose_start=True, tempogram=False),
}


class LSTMBaseline(Stage1Method):
    """Music features -> LSTM -> linear -> poses; one optimizer ``main``."""

    method_name = "lstm"
    feature_kind = "dance_revolution"

    def __init__(self, config: LSTMConfig) -> None:
        super().__init__(config)
        inputs = self._music_dim() + (2 if config.beat_phase_input else 0)
        self.lstm = nn.LSTM(inputs, config.hidden, num_layers=config.layers, batch_first=True,
                            dropout=config.dropout if config.layers > 1 else 0.0)
        self.out = nn.Linear(config.hidden, NUM_JOINTS * 2)
        self.kinematics = KinematicOutput() if config.kinematic_output else None

    def forward(self, features: torch.Tensor, lengths: torch.Tensor | None = None, window: int = 0,
                beats: torch.Tensor | None = None) -> torch.Tensor:
        """``[B, T, feature_dim]`` (+ ``[B, T]`` beat flags with ``beat_phase_input``) -> ``[B, T, 25, 2]``; with
        kinematic output, bones of ``lengths`` (``[B, 1, 25]``, default the training data's mean body); ``window`` > 0:
        the LSTM runs on windows of that many frames."""
        music = features[..., :self._music_dim()]
        inputs = with_beat_phase(music, beats) if self.config.beat_phase_input else music
        h = windowed(lambda f: self.lstm(self._music_view(f, music.shape[-1]))[0], (inputs,), window)
        out = self.out(h).reshape(features.shape[0], features.shape[1], NUM_JOINTS, 2)
        if self.config.root_smoothing:
            root = smooth_in_time(out[:, :, ROOT], self.config.root_smoothing)
            out = torch.cat([out[:, :, :ROOT], root[:, :, None], out[:, :, ROOT + 1:]], dim=2)
        return out if self.kinematics is None else self.kinematics(out, lengths)

    def _music_dim(self) -> int:
        """How many leading feature columns the LSTM reads."""
        return self.config.feature_dim - (0 if self.config.tempogram else TEMPOGRAM_WINDOW)

    def _music_view(self, inputs: torch.Tensor, dim: int) -> torch.Tensor:
        """One window's ``[B, t, dim + extra]`` inputs with its first ``dim`` columns (the music features) centred
        on the window's mean (``centre_features``) and dropped out in training (``feature_dropout``)."""
        music = inputs[..., :dim]
        if self.config.centre_features:
            music = music - music.mean(dim=1, keepdim=True)
        music = F.dropout(music, self.config.feature_dropout, self.training)
        return torch.cat([music, inputs[..., dim:]], dim=-1)

    def configure_optimizers(self) -> dict[str, torch.optim.Optimizer]:
        return {"main": torch.optim.Adam(self.parameters(), lr=self.config.lr)}

    def training_step(self, batch: Batch, epoch: int) -> dict[str, float]:
        if self.config.mean_pose_start and self.kinematics is not None and not self.kinematics.seen:
            with torch.no_grad():
                self.out.bias.copy_(mean_raw_rows(batch.poses).flatten())
        lengths = None if self.kinematics is None else self.kinematics.observe(batch.poses)
        pred = self(batch.features, lengths, beats=batch.beats)
        l1 = F.l1_loss(pred, batch.poses)
        loss, logs = l1, {"l1": l1.item()}
        if self.kinematics is not None:
            penalty = self.kinematics.take_penalty()
            loss = loss + penalty
            logs["bone_rows"] = penalty.item()
        if self.config.speed_weight:
            speed = speed_loss(pred, batch.poses)
            loss = loss + self.config.speed_weight * speed
            logs["speed"] = speed.item()
        self.optimize("main", loss)
        return logs

    @torch.no_grad()
    def generate(self, features: torch.Tensor, beats: torch.Tensor,
                 generator: torch.Generator | None = None) -> torch.Tensor:
        """Deterministic: ``generator`` is ignored; ``beats`` are read with ``beat_phase_input``."""
        return self(features, window=self.config.window_frames if self.config.windowed_generation else 0,
                    beats=beats)
