"""Training the beat network on songs with known beats: augmented excerpts, soft frame targets, Adam, a wall-clock
budget.

A song is its ``[T, n_mels]`` dB frames (:func:`stage1_pose.beat_tracking.spectrogram.mel_frames`) with beat and
downbeat times in seconds. Each excerpt is stretched in time (frames interpolated, the beats moved with them),
shifted in pitch (mel bands), tilted in spectrum and mixed with noise, all in the mel domain, so one rendering
serves many tempi, keys and mixes.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from stage1_pose.beat_tracking.model import PRESETS, BeatTCN, save_model
from stage1_pose.beat_tracking.spectrogram import FPS, network_input

_SAVE_MINUTES = 5.0


@dataclass(frozen=True)
class Song:
    """``mel`` ``[T, n_mels]`` dB frames at ``FPS``; ``beats`` and ``downbeats`` in seconds."""

    mel: np.ndarray
    beats: np.ndarray
    downbeats: np.ndarray


@dataclass(frozen=True)
class TrainConfig:
    """Budget (``minutes`` of wall clock or ``steps``, whichever ends first), batch of ``batch`` excerpts of
    ``excerpt_frames`` frames, Adam at ``lr`` (halved at 60 % and 85 % of the budget), and the augmentation ranges:
    time stretch (factor), pitch shift (mel bands), spectral tilt (dB from the lowest to the highest band), noise
    (probability, signal-to-noise ratio range in dB)."""

    minutes: float = 45.0
    steps: int = 1_000_000
    batch: int = 8
    excerpt_frames: int = 1536
    lr: float = 2e-3
    seed: int = 0
    stretch: tuple[float, float] = (0.8, 1.25)
    pitch_bands: int = 3
    tilt_db: float = 6.0
    noise_probability: float = 0.5
    snr_db: tuple[float, float] = (10.0, 40.0)
    # Target weight of the frames next to a beat (Böck & Davies 2020 widen the targets the same way).
    neighbour_weight: float = 0.5


def load_corpus(files: list[Path]) -> list[Song]:
    """Songs from ``.npz`` files holding ``mel``, ``beats`` and ``downbeats``."""
    songs = []
    for f in files:
        with np.load(f) as data:
            songs.append(Song(data["mel"], data["beats"], data["downbeats"]))
    return songs


def targets(frames: int, beats: np.ndarray, downbeats: np.ndarray, neighbour_weight: float) -> np.ndarray:
    """``[frames, 3]`` float32 soft class targets (none, beat, downbeat) for beat and downbeat times in frames
    (float): the nearest frame gets 1, its neighbours ``neighbour_weight``."""
    out = np.zeros((frames, 3), np.float32)
    is_down = np.zeros(len(beats), bool)
    if len(downbeats) and len(beats):
        is_down = np.min(np.abs(beats[:, None] - downbeats[None, :]), axis=1) < 0.5
    for weight, offset in ((neighbour_weight, -1), (neighbour_weight, 1), (1.0, 0)):
        idx = np.round(beats).astype(np.int64) + offset
        keep = (idx >= 0) & (idx < frames)
        for cls, mask in ((1, ~is_down), (2, is_down)):
            sel = idx[keep & mask]
            out[sel, 1:] = 0.0 if weight == 1.0 else out[sel, 1:]
            out[sel, cls] = np.maximum(out[sel, cls], weight)
    out[:, 0] = 1.0 - out[:, 1:].sum(axis=1)
    return out


def augmented_excerpt(song: Song, frames: int, config: TrainConfig,
                      rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(network input ``[frames, 2 * n_mels]``, targets ``[frames, 3]``) of a random augmented excerpt of
    ``song`` (zero-padded dB floor where the song is shorter)."""
    stretch = float(np.exp(rng.uniform(*np.log(config.stretch))))
    span = frames * stretch
    start = rng.uniform(-0.1 * span, max(len(song.mel) - 0.9 * span, 0.0))
    pos = start + np.arange(frames) * stretch
    lo = np.clip(np.floor(pos).astype(np.int64), 0, len(song.mel) - 1)
    hi = np.clip(lo + 1, 0, len(song.mel) - 1)
    w = (pos - np.floor(pos))[:, None]
    floor = float(song.mel.min())
    mel = (1 - w) * song.mel[lo].astype(np.float32) + w * song.mel[hi].astype(np.float32)
    mel[(pos < 0) | (pos > len(song.mel) - 1)] = floor
    shift = int(rng.integers(-config.pitch_bands, config.pitch_bands + 1))
    mel = mel[:, np.clip(np.arange(mel.shape[1]) - shift, 0, mel.shape[1] - 1)]
    mel = mel + rng.uniform(-1, 1) * config.tilt_db * np.linspace(-0.5, 0.5, mel.shape[1])[None, :]
    if rng.random() < config.noise_probability:
        loud = float(np.percentile(mel, 99))
        shape = rng.normal(0.0, 3.0, mel.shape[1])[None, :] + np.linspace(0, -rng.uniform(0, 20), mel.shape[1])
        noise_db = loud - rng.uniform(*config.snr_db) + shape + 10 * np.log10(rng.exponential(1.0, mel.shape) + 1e-6)
        mel = 10 * np.log10(10 ** (mel / 10) + 10 ** (noise_db / 10))
    to_frames = lambda t: (np.asarray(t) * FPS - start) / stretch  # noqa: E731
    return network_input(mel.astype(np.float32)), targets(frames, to_frames(song.beats), to_frames(song.downbeats),
                                                          config.neighbour_weight)


def train(songs: list[Song], preset: str = "small", config: TrainConfig | None = None,
          folder: Path | None = None, init: BeatTCN | None = None) -> tuple[BeatTCN, dict]:
    """Train a :class:`BeatTCN` of ``preset`` (or go on training ``init``, a trained network) on ``songs`` (excerpts
    drawn in proportion to song length) for the budget; returns the model in eval mode and a log (steps, minutes,
    final loss, the configs). With ``folder``, the model so far is saved there every ``_SAVE_MINUTES``, so a stopped
    training leaves a usable model."""
    config = config or TrainConfig()
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    model = init if init is not None else BeatTCN(PRESETS[preset])
    opt = torch.optim.Adam(model.parameters(), lr=config.lr)
    weights = np.array([len(s.mel) for s in songs], np.float64)
    weights /= weights.sum()
    begin = time.monotonic()
    budget = 60.0 * config.minutes
    step, running, saved = 0, float("nan"), begin

    def log() -> dict:
        return {"preset": preset, "steps": step, "minutes": round((time.monotonic() - begin) / 60, 1),
                "loss": round(running, 4), "train": asdict(config)}

    while step < config.steps and time.monotonic() - begin < budget:
        done = (time.monotonic() - begin) / budget
        for g in opt.param_groups:
            g["lr"] = config.lr * (0.25 if done > 0.85 else 0.5 if done > 0.6 else 1.0)
        batch = [augmented_excerpt(songs[i], config.excerpt_frames, config, rng)
                 for i in rng.choice(len(songs), size=config.batch, p=weights)]
        x = torch.from_numpy(np.stack([b[0] for b in batch]))
        y = torch.from_numpy(np.stack([b[1] for b in batch]))
        model.train()
        loss = -(y * torch.log_softmax(model(x), dim=-1)).sum(-1).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        step += 1
        running = loss.item() if np.isnan(running) else 0.98 * running + 0.02 * loss.item()
        if step % 100 == 0:
            print(f"step {step} loss {running:.4f} {(time.monotonic() - begin) / 60:.1f} min", flush=True)
        if folder is not None and time.monotonic() - saved > 60 * _SAVE_MINUTES:
            save(model.eval(), folder, log())
            saved = time.monotonic()
    model.eval()
    return model, log()


def save(model: BeatTCN, folder: Path, log: dict) -> None:
    """Save the trained model and its training log (see :func:`stage1_pose.beat_tracking.model.save_model`)."""
    save_model(model, folder, {"training": log})
