"""Dance Revolution (Huang et al., ICLR 2021): local-attention music encoder + LSTM dance decoder, trained
with dynamic auto-condition curriculum learning.

Encoder (Sec. 3.2): linear embedding of the 438-d music features, sinusoidal positional encoding, N post-norm
transformer layers whose self-attention is local (window k, O(n·k) memory), giving ``z_i`` per frame.
Decoder (Eq. 3-4): a 3-layer LSTM whose initial hidden and cell states are drawn from N(0, I) - the source of
variety: another seed gives another dance - fed the previous pose (frame 0: the all-zero begin-of-pose);
``y_i = [h_i; z_i] W + b``. Optionally (``code_dim`` > 0, the ``small`` preset) each input also carries a
choreography code drawn per segment (:mod:`stage1_pose.models.dance_revolution.segment_latent`), because the
decoder forgets its initial state within a few frames and seeds then give the same dance; and
(``beat_phase_input``) the frame's phase between two of the song's beats
(:mod:`stage1_pose.models.beat_clock`), because the music reaches the paper's LSTM
only through its own fed-back poses and the moves then drift off the beat; and (``z_smoothing``) the music's
term of the output is smoothed in time, because ``z_i`` follows the frame-to-frame changes of the features and made
the body jitter; and (``speed_weight``) the loss also compares each joint's speed with the real dance's, because
with the pose loss alone the dances neither slowed down on the beat nor moved at the real dances' speed; and
(``kinematic_output``) the output rows are a root position and bone directions placed by forward kinematics
(:mod:`stage1_pose.models.kinematics`), because the paper's free joint positions let bones change length.
Curriculum (Sec. 3.3): decoder inputs alternate ``p`` of its own predictions with ``q`` ground-truth frames,
``p = f(epoch)`` growing with one of const, ⌊λt⌋, ⌊λt²⌋, ⌊λeᵗ⌋; L1 loss.

Shapes: features ``[B, T, feature_dim]`` standardised features (one row per pose frame); beats ``[B, T]`` bool,
the song's beat frames; poses ``[B, T, 25, 2]`` model coordinates (:func:`dancesynth.core.skeleton.normalize`),
flattened to 50 numbers per frame inside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import torch
import torch.nn.functional as F
from torch import nn

from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import NUM_JOINTS
from stage1_pose.models.base import Batch, Stage1Method
from stage1_pose.models.beat_clock import beat_phase, phase_features
from stage1_pose.models.dance_revolution.local_attention import LocalSelfAttention
from stage1_pose.models.dance_revolution.segment_latent import (
    SegmentPosterior,
    beat_segments,
    fixed_segments,
    kl_with_free_bits,
    prior_codes,
)
from stage1_pose.models.kinematics import KinematicOutput, acceleration_loss, speed_loss
from stage1_pose.models.windowing import smooth_in_time

POSE_DIM = NUM_JOINTS * 2
SCHEDULES = ("const", "linear", "quadratic", "exponential")
PRECISIONS = ("fp32", "int8")


@dataclass(frozen=True)
class DanceRevolutionConfig:
    """Sizes, curriculum and optimisation settings.

    ``window`` is the local-attention width k in frames; ``curriculum`` one of :data:`SCHEDULES` with
    ``lam`` (λ) and ``q`` ground-truth frames per cycle (``const_p`` is p for the const schedule);
    ``window_frames`` the training sequence length in frames; ``lr`` Adam's learning rate.
    ``code_dim`` > 0 adds a choreography code (not in the paper, see
    :mod:`stage1_pose.models.dance_revolution.segment_latent`): ``code_dim`` numbers per segment of ``code_frames``
    frames (``code_on_beats``: per interval between the song's beats), appended to every decoder input, learned
    with a posterior over the real dance and a KL term weighted ``kl_weight`` against the L1 loss; 0 is the paper.
    ``free_bits``: the first ``free_bits`` nats of each code number's KL cost nothing (Kingma et al. 2016).
    ``speed_weight`` adds an L1 loss on each joint's speed, the length of its frame-to-frame change: how fast
    to move at each moment, without the pull towards standing still that an L1 loss on the changes themselves
    has when the direction of the next move is uncertain (the median of moves in all directions is no move).
    ``beat_phase_input`` appends the beat phase (sin, cos) of each frame to every decoder input, and
    ``z_smoothing`` > 0 smooths the music's term ``z_i W_z`` of the output over a Gaussian of that many frames
    (neither is in the paper). ``kinematic_output`` places the output by forward kinematics with the training
    data's body; ``epoch_windows`` > 0 makes an epoch that many training windows whatever the dataset's size
    (0: one pass), so the curriculum, which counts epochs, and the number of steps do not shrink with the data.
    ``accel_weight`` adds an L1 loss on each joint's acceleration magnitude (jitter; not in the paper).
    """

    feature_dim: int = 438
    d_model: int = 256
    heads: int = 8
    d_k: int = 64
    d_v: int = 64
    d_ff: int = 1024
    layers: int = 2
    window: int = 100
    dropout: float = 0.1
    lstm_hidden: int = 1024
    lstm_layers: int = 3
    curriculum: str = "linear"
    lam: float = 0.01
    q: int = 10
    const_p: int = 10
    lr: float = 1e-4
    batch_size: int = 32
    window_frames: int = 900
    epochs: int = 10000
    code_dim: int = 0
    code_frames: int = 15
    code_on_beats: bool = False
    kl_weight: float = 0.01
    free_bits: float = 0.0
    speed_weight: float = 0.0
    beat_phase_input: bool = False
    z_smoothing: float = 0.0
    kinematic_output: bool = False
    epoch_windows: int = 0
    accel_weight: float = 0.0

    def __post_init__(self) -> None:
        if self.curriculum not in SCHEDULES:
            raise DancesynthError(f"Unknown curriculum {self.curriculum!r}; choose one of {', '.join(SCHEDULES)}.")
        if self.code_dim < 0 or self.code_frames < 1 or self.kl_weight < 0 or self.free_bits < 0:
            raise DancesynthError("code_dim must be >= 0, code_frames >= 1, kl_weight >= 0 and free_bits >= 0.")
        if self.speed_weight < 0:
            raise DancesynthError("speed_weight must be >= 0 (0: the paper's L1 loss on poses only).")
        if self.z_smoothing < 0:
            raise DancesynthError("z_smoothing must be >= 0 frames (0: the paper's per-frame output).")

    @classmethod
    def preset(cls, name: str) -> "DanceRevolutionConfig":
        """A named preset from :data:`DANCE_REVOLUTION_PRESETS`."""
        if name not in DANCE_REVOLUTION_PRESETS:
            raise DancesynthError(f"Unknown dance_revolution preset {name!r}; "
                                  f"choose one of {', '.join(DANCE_REVOLUTION_PRESETS)}.")
        return DANCE_REVOLUTION_PRESETS[name]


DANCE_REVOLUTION_PRESETS: dict[str, DanceRevolutionConfig] = {
    # The paper's settings (Sec. 4.2).
    "paper": DanceRevolutionConfig(),
    # CPU-sized, plus what made seeds differ and moves land on beats in minutes (docs/methods/dance_revolution.md).
    "small": DanceRevolutionConfig(d_model=64, heads=4, d_k=16, d_v=16, d_ff=128, layers=2, window=30,
                                   lstm_hidden=128, lam=1.0, lr=1e-3, batch_size=16, window_frames=450, epochs=60,
                                   code_dim=8, code_on_beats=True, kl_weight=0.002, free_bits=0.25,
                                   speed_weight=5.0, beat_phase_input=True, z_smoothing=4.0,
                                   kinematic_output=True, epoch_windows=144, accel_weight=10.0),
}


def curriculum_p(schedule: str, epoch: int, lam: float, const_p: int, cap: int) -> int:
    """Predicted frames per cycle at ``epoch`` (0-based): const, ⌊λt⌋, ⌊λt²⌋ or ⌊λeᵗ⌋, at most ``cap``."""
    if schedule == "const":
        value = float(const_p)
    elif schedule == "linear":
        value = lam * epoch
    elif schedule == "quadratic":
        value = lam * epoch ** 2
    elif schedule == "exponential":
        # Compared in log space: e^t overflows a float after t = 709.
        value = cap if math.log(lam) + epoch >= math.log(cap + 1) else lam * math.exp(epoch)
    else:
        raise DancesynthError(f"Unknown curriculum {schedule!r}; choose one of {', '.join(SCHEDULES)}.")
    return int(min(math.floor(value), cap))


def predicted_inputs(frames: int, p: int, q: int) -> list[bool]:
    """Which decoder inputs are the model's own predictions, for output steps ``0 .. frames-1``.

    Input 0 is the begin-of-pose; then ``p`` predicted and ``q`` ground-truth inputs alternate (Sec. 3.3,
    ``Y_in = {y0, ŷ1..ŷp, y(p+1)..y(p+q), ŷ(p+q+1), ...}``). ``p = 0`` is teacher forcing.
    """
    return [i >= 1 and (i - 1) % (p + q) < p for i in range(frames)]


def sinusoidal_encoding(n: int, dim: int, device: torch.device | None = None, start: int = 0) -> torch.Tensor:
    """``[n, dim]`` sinusoidal positional encoding (Vaswani et al.) of positions ``start .. start+n-1``."""
    pos = torch.arange(start, start + n, dtype=torch.float32, device=device)[:, None]
    freq = torch.exp(torch.arange(0, dim, 2, dtype=torch.float32, device=device) * (-math.log(10000.0) / dim))
    out = torch.zeros(n, dim, device=device)
    out[:, 0::2] = torch.sin(pos * freq)
    out[:, 1::2] = torch.cos(pos * freq[: dim // 2])
    return out


class EncoderLayer(nn.Module):
    """Local self-attention and feed-forward sublayers, each ``LayerNorm(x + Dropout(sublayer(x)))``."""

    def __init__(self, cfg: DanceRevolutionConfig) -> None:
        super().__init__()
        self.attention = LocalSelfAttention(cfg.d_model, cfg.heads, cfg.d_k, cfg.d_v, cfg.window, cfg.dropout)
        self.ffn = nn.Sequential(nn.Linear(cfg.d_model, cfg.d_ff), nn.ReLU(), nn.Linear(cfg.d_ff, cfg.d_model))
        self.norm1, self.norm2 = nn.LayerNorm(cfg.d_model), nn.LayerNorm(cfg.d_model)
        self.drop = nn.Dropout(cfg.dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = self.norm1(x + self.drop(self.attention(x)))
        return self.norm2(x + self.drop(self.ffn(x)))


class MusicEncoder(nn.Module):
    """``[B, T, feature_dim]`` features -> ``[B, T, d_model]`` latent music ``z``; memory O(T · window)."""

    def __init__(self, cfg: DanceRevolutionConfig) -> None:
        super().__init__()
        self.embed = nn.Linear(cfg.feature_dim, cfg.d_model)
        self.drop = nn.Dropout(cfg.dropout)
        self.layers = nn.ModuleList(EncoderLayer(cfg) for _ in range(cfg.layers))

    def forward(self, features: torch.Tensor, start: int = 0) -> torch.Tensor:
        """``start``: the frame index of ``features[:, 0]`` in the song (for the positional encoding)."""
        x = self.embed(features)
        x = self.drop(x + sinusoidal_encoding(x.shape[1], x.shape[2], x.device, start))
        for layer in self.layers:
            x = layer(x)
        return x

    def encode_chunked(self, features: torch.Tensor, chunk: int = 900) -> torch.Tensor:
        """Same result as :meth:`forward` (eval mode) with memory bounded by ``chunk`` frames whatever the song
        length: each chunk is encoded with the ``layers x window // 2`` frames of context either side that
        its outputs can see, and only its own frames are kept."""
        halo = len(self.layers) * (self.layers[0].attention.window // 2) if self.layers else 0
        frames = features.shape[1]
        parts = []
        for s in range(0, frames, chunk):
            lo, hi = max(0, s - halo), min(frames, s + chunk + halo)
            parts.append(self(features[:, lo:hi], start=lo)[:, s - lo: s - lo + min(chunk, frames - s)])
        return torch.cat(parts, dim=1)


def _quantize_rows(w_ih: torch.Tensor, w_hh: torch.Tensor, rows: int = 256) -> tuple[torch.Tensor, torch.Tensor]:
    """``[W_ih W_hh]`` -> (int8 ``[4H, K]`` with K padded to a multiple of 64 as the int8 kernel needs, bfloat16
    per-row scales); a block of rows at a time so no full-size float temporaries are made."""
    n, k = w_ih.shape[0], w_ih.shape[1] + w_hh.shape[1]
    q = torch.zeros(n, k + (-k % 64), dtype=torch.int8, device=w_ih.device)
    scale = torch.empty(n, device=w_ih.device)
    for r in range(0, n, rows):
        block = torch.cat([w_ih[r:r + rows], w_hh[r:r + rows]], dim=1)
        scale[r:r + rows] = block.abs().amax(dim=1).clamp_min(1e-12) / 127.0
        q[r:r + rows, :k] = torch.round(block / scale[r:r + rows, None]).to(torch.int8)
    return q, scale.bfloat16()


class LSTMStepper:
    """Runs a multi-layer ``nn.LSTM`` one frame at a time with one fused gate matmul per layer.

    Per layer ``gates = [x; h] @ [W_ih W_hh]^T + b`` (PyTorch's gate order i, f, g, o). Batch-1 decoding is
    bound by reading these weights once per frame, so ``precision="int8"`` stores them as int8 per output
    row (scale = row max / 127) and multiplies in bfloat16 (CPU inference only: a quarter of the bytes,
    and the paper-size LSTM then fits in a 32 MB L3 cache). ``"fp32"`` is exact and differentiable.
    """

    def __init__(self, lstm: nn.LSTM, precision: str = "fp32") -> None:
        if precision not in PRECISIONS:
            raise DancesynthError(f"Unknown precision {precision!r}; choose one of {', '.join(PRECISIONS)}.")
        self.layers: list[tuple[torch.Tensor, torch.Tensor | None, torch.Tensor]] = []
        for layer in range(lstm.num_layers):
            w_ih, w_hh = getattr(lstm, f"weight_ih_l{layer}"), getattr(lstm, f"weight_hh_l{layer}")
            b = getattr(lstm, f"bias_ih_l{layer}") + getattr(lstm, f"bias_hh_l{layer}")
            if precision == "int8":
                self.layers.append((*_quantize_rows(w_ih.detach(), w_hh.detach()), b.detach()))
            else:
                self.layers.append((torch.cat([w_ih, w_hh], dim=1).t(), None, b))

    def step(self, x: torch.Tensor, h: list[torch.Tensor],
             c: list[torch.Tensor]) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        """One frame: ``x [B, input]``, per-layer ``h``, ``c`` ``[B, hidden]`` -> the new ``h``, ``c`` lists."""
        new_h, new_c = [], []
        for (w, scale, b), h_l, c_l in zip(self.layers, h, c):
            if scale is None:
                gates = torch.addmm(b, torch.cat([x, h_l], dim=1), w)
            else:
                inputs = x.new_zeros(x.shape[0], w.shape[1], dtype=torch.bfloat16)
                inputs[:, :x.shape[1]] = x
                inputs[:, x.shape[1]:x.shape[1] + h_l.shape[1]] = h_l
                gates = torch._weight_int8pack_mm(inputs, w, scale).float() + b
            i, f, g, o = gates.chunk(4, dim=1)
            c_l = torch.sigmoid(f) * c_l + torch.sigmoid(i) * torch.tanh(g)
            x = torch.sigmoid(o) * torch.tanh(c_l)
            new_h.append(x)
            new_c.append(c_l)
        return new_h, new_c


def extra_dim(cfg: DanceRevolutionConfig) -> int:
    """Numbers appended to each decoder input: the choreography code and the beat phase's (sin, cos)."""
    return cfg.code_dim + (2 if cfg.beat_phase_input else 0)


class PoseDecoder(nn.Module):
    """The 3-layer LSTM and the output layer ``y_i = [h_i; z_i] W + b``.

    The LSTM is one ``nn.LSTM`` (the same maths as stacked LSTM cells), so runs of known inputs - the
    ground-truth segments of the curriculum - go through it in one fused call; predicted frames step one
    at a time through :class:`LSTMStepper`. ``W`` is split into its ``h`` and ``z`` parts so the ``z``
    part is one matmul for all frames. Every input is a pose with ``extra_dim`` per-frame numbers appended (the
    choreography code and the beat phase, when configured).
    """

    def __init__(self, cfg: DanceRevolutionConfig) -> None:
        super().__init__()
        self.lstm = nn.LSTM(POSE_DIM + extra_dim(cfg), cfg.lstm_hidden, num_layers=cfg.lstm_layers, batch_first=True)
        self.out_h = nn.Linear(cfg.lstm_hidden, POSE_DIM, bias=False)
        self.out_z = nn.Linear(cfg.d_model, POSE_DIM)
        self.z_smoothing = cfg.z_smoothing
        self.kinematics = KinematicOutput() if cfg.kinematic_output else None

    def place(self, raw: torch.Tensor, lengths: torch.Tensor | None = None) -> torch.Tensor:
        """Output rows ``[..., 50]`` -> flattened poses ``[..., 50]``: themselves, or with kinematic output placed
        with bones of ``lengths`` (``[B, 25]`` per step, ``[B, 1, 25]`` per sequence; default the mean body)."""
        if self.kinematics is None:
            return raw
        return self.kinematics(raw.unflatten(-1, (NUM_JOINTS, 2)), lengths).flatten(-2)

    def initial_state(self, batch: int, device: torch.device,
                      generator: torch.Generator | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """``(h0, c0)``, each ``[layers, batch, hidden]`` from N(0, I) (drawn on ``generator``'s device)."""
        shape = (2, self.lstm.num_layers, batch, self.lstm.hidden_size)
        state = torch.randn(shape, generator=generator, device=None if generator is None else generator.device)
        state = state.to(device)
        return state[0].contiguous(), state[1].contiguous()

    def forward(self, z: torch.Tensor, state: tuple[torch.Tensor, torch.Tensor], targets: torch.Tensor,
                predicted: list[bool], extras: torch.Tensor, lengths: torch.Tensor | None = None) -> torch.Tensor:
        """Training: ``z [B, T, d_model]``, ``targets [B, T, 50]``, ``extras [B, T, extra_dim]`` (and with kinematic
        output the clips' bodies ``lengths [B, 1, 25]``) -> ``[B, T, 50]``.

        Input i is the begin-of-pose (i = 0), the model's previous output where ``predicted[i]``, else
        ``targets[:, i-1]``; each with ``extras[:, i]`` appended.
        """
        frames = z.shape[1]
        zw = smooth_in_time(self.out_z(z), self.z_smoothing)
        shifted = torch.cat([targets.new_zeros(targets.shape[0], 1, POSE_DIM), targets[:, :-1]], dim=1)
        shifted = torch.cat([shifted, extras], dim=2)
        stepper = LSTMStepper(self.lstm)
        h, c = list(state[0].unbind(0)), list(state[1].unbind(0))
        outputs: list[torch.Tensor] = []
        i = 0
        while i < frames:
            if predicted[i]:
                h, c = stepper.step(torch.cat([outputs[-1][:, -1], extras[:, i]], dim=1), h, c)
                step_lengths = None if lengths is None else lengths[:, 0]
                outputs.append(self.place(self.out_h(h[-1]) + zw[:, i], step_lengths)[:, None])
                i += 1
                continue
            j = i + 1
            while j < frames and not predicted[j]:
                j += 1
            seq, (hs, cs) = self.lstm(shifted[:, i:j], (torch.stack(h), torch.stack(c)))
            h, c = list(hs.unbind(0)), list(cs.unbind(0))
            outputs.append(self.place(self.out_h(seq) + zw[:, i:j], lengths))
            i = j
        return torch.cat(outputs, dim=1)

    @torch.no_grad()
    def generate(self, z: torch.Tensor, state: tuple[torch.Tensor, torch.Tensor], extras: torch.Tensor,
                 stepper: LSTMStepper | None = None) -> torch.Tensor:
        """Free running: ``z [B, T, d_model]``, ``extras [B, T, extra_dim]`` -> poses ``[B, T, 50]``, each frame
        fed back as the next input.

        ``stepper`` (default: exact fp32 on the current weights) lets inference reuse prepared weights.
        """
        batch, frames, _ = z.shape
        zw = smooth_in_time(self.out_z(z), self.z_smoothing)
        stepper = stepper or LSTMStepper(self.lstm)
        h, c = list(state[0].unbind(0)), list(state[1].unbind(0))
        out = z.new_empty(batch, frames, POSE_DIM)
        y = z.new_zeros(batch, POSE_DIM)
        for i in range(frames):
            h, c = stepper.step(torch.cat([y, extras[:, i]], dim=1), h, c)
            y = self.place(self.out_h(h[-1]) + zw[:, i])
            out[:, i] = y
        return out


class DanceRevolution(Stage1Method):
    """Dance Revolution as a stage-1 method; one optimizer ``main`` (Adam)."""

    method_name = "dance_revolution"
    feature_kind = "dance_revolution"

    def __init__(self, config: DanceRevolutionConfig) -> None:
        super().__init__(config)
        self.encoder = MusicEncoder(config)
        self.decoder = PoseDecoder(config)
        self.posterior = SegmentPosterior(POSE_DIM, config.code_dim) if config.code_dim else None
        self.epoch = 0
        # Prepared decoding weights for inference (see prepare_inference); None = exact, rebuilt per call.
        self._stepper: LSTMStepper | None = None

    @property
    def p(self) -> int:
        """Predicted frames per curriculum cycle at the current epoch."""
        cfg = self.config
        return curriculum_p(cfg.curriculum, self.epoch, cfg.lam, cfg.const_p, cfg.window_frames)

    def configure_optimizers(self) -> dict[str, torch.optim.Optimizer]:
        return {"main": torch.optim.Adam(self.parameters(), lr=self.config.lr)}

    def training_step(self, batch: Batch, epoch: int) -> dict[str, float]:
        self.epoch = epoch
        target = batch.poses.flatten(2)
        frames = target.shape[1]
        z = self.encoder(batch.features)
        state = self.decoder.initial_state(target.shape[0], target.device)
        if self.posterior is None:
            codes, kl = target.new_zeros(*target.shape[:2], 0), None
        else:
            codes, kl = self.posterior.sample(target, self.segments(batch.beats))
        extras = self.decoder_extras(batch.beats, codes)
        kinematics = self.decoder.kinematics
        lengths = None if kinematics is None else kinematics.observe(batch.poses)
        pred = self.decoder(z, state, target, predicted_inputs(frames, self.p, self.config.q), extras, lengths)
        l1 = F.l1_loss(pred, target)
        loss, scalars = l1, {"l1": l1.item(), "p": float(self.p)}
        if kinematics is not None:
            penalty = kinematics.take_penalty()
            loss = loss + penalty
            scalars["bone_rows"] = penalty.item()
        if kl is not None:
            loss = loss + self.config.kl_weight * kl_with_free_bits(kl, self.config.free_bits)
            scalars["kl"] = kl.mean().item()
        if self.config.speed_weight:
            speed = speed_loss(pred.unflatten(2, (NUM_JOINTS, 2)), batch.poses)
            loss = loss + self.config.speed_weight * speed
            scalars["speed"] = speed.item()
        if self.config.accel_weight:
            accel = acceleration_loss(pred.unflatten(2, (NUM_JOINTS, 2)), batch.poses)
            loss = loss + self.config.accel_weight * accel
            scalars["accel"] = accel.item()
        self.optimize("main", loss)
        return scalars

    @torch.no_grad()
    def generate(self, features: torch.Tensor, beats: torch.Tensor,
                 generator: torch.Generator | None = None) -> torch.Tensor:
        """``[B, T, feature_dim]`` features, ``[B, T]`` beat flags -> ``[B, T, 25, 2]`` for any T; the initial LSTM
        state and the choreography codes come from ``generator``."""
        batch, frames = features.shape[:2]
        beats = beats.to(features.device)
        z = self.encoder.encode_chunked(features)
        state = self.decoder.initial_state(batch, features.device, generator)
        codes = prior_codes(self.segments(beats), self.config.code_dim, generator)
        stepper = self._stepper if features.device.type == "cpu" else None
        poses = self.decoder.generate(z, state, self.decoder_extras(beats, codes), stepper)
        return poses.reshape(batch, frames, NUM_JOINTS, 2)

    def segments(self, beats: torch.Tensor) -> torch.Tensor:
        """Choreography-code segment ids ``[B, T]`` for beat flags ``[B, T]``: a new segment at every beat
        (``code_on_beats``) or every ``code_frames`` frames."""
        if self.config.code_on_beats:
            return beat_segments(beats)
        return fixed_segments(beats.shape[0], beats.shape[1], self.config.code_frames, beats.device)

    def decoder_extras(self, beats: torch.Tensor, codes: torch.Tensor) -> torch.Tensor:
        """``[B, T, extra_dim]``: per-frame ``codes [B, T, code_dim]`` and, with ``beat_phase_input``, the beat
        phase features of the beat flags ``beats [B, T]``."""
        if not self.config.beat_phase_input:
            return codes
        return torch.cat([codes, phase_features(beat_phase(beats))], dim=-1)

    def prepare_inference(self, precision: str = "fp32") -> None:
        """Freeze the current weights for fast decoding: ``"int8"`` quantises the LSTM (CPU only, about 3x
        faster at batch 1), ``"fp32"`` keeps them exact. Call after loading weights and before generating;
        GPUs always decode in fp32."""
        with torch.no_grad():
            self._stepper = LSTMStepper(self.decoder.lstm, precision)

    def curriculum_state(self) -> dict[str, Any]:
        return {"schedule": self.config.curriculum, "epoch": self.epoch, "p": self.p, "q": self.config.q}

    def load_curriculum_state(self, state: dict[str, Any]) -> None:
        self.epoch = int(state.get("epoch", 0))
