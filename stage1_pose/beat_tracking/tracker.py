"""The learned tracker end to end: log-mel frames -> network activations (the mean of the shipped networks', as
madmom averages its networks) -> bar-pointer Viterbi -> beat and downbeat times in seconds.

The network runs at ``FPS`` (100.2 frames per second); the decoder at half that (activations max-pooled over
frame pairs: the Viterbi pass costs a quarter), and each decoded beat then moves to the strongest activation among
the full-rate frames within ``_REFINE`` of it, so times keep the 10-ms grid.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch

from stage1_pose.beat_tracking.decoder import DEFAULT_DECODER, Decoded, DecoderConfig, decode
from stage1_pose.beat_tracking.model import BeatTCN, load_model
from stage1_pose.beat_tracking.spectrogram import FPS, frame_of, mel_frames, network_input

# One folder per shipped network (the same architecture and corpus, another seed).
PRETRAINED = Path(__file__).resolve().parent.parent / "pretrained" / "beat_tracker"
_POOL = 2
# A decoded beat is the start of its beat region (at least 2 frames at 50 fps, DecoderConfig.observation_frames):
# the peak lies within 4 full-rate frames (40 ms) of it.
_REFINE = 4


@functools.lru_cache(maxsize=1)
def pretrained_models() -> tuple[BeatTCN, ...]:
    """The shipped networks (each subfolder of ``stage1_pose/pretrained/beat_tracker``), loaded once."""
    return tuple(load_model(folder) for folder in sorted(PRETRAINED.iterdir()) if (folder / "config.json").is_file())


def activations(samples: np.ndarray, sr: int, model: BeatTCN | Sequence[BeatTCN] | None = None) -> np.ndarray:
    """``[T, 3]`` float32 class probabilities (none, beat, downbeat) per frame at ``FPS`` of a mono ``[N]`` song
    at ``sr`` Hz: the mean of the networks' (``model``: one or several; default the shipped ones)."""
    models = pretrained_models() if model is None else (model,) if isinstance(model, BeatTCN) else tuple(model)
    x = torch.from_numpy(network_input(mel_frames(samples, sr)))[None]
    with torch.inference_mode():
        return torch.stack([torch.softmax(m(x)[0], dim=-1) for m in models]).mean(0).numpy()


def decode_activations(probs: np.ndarray, config: DecoderConfig = DEFAULT_DECODER) -> Decoded:
    """Beats and downbeats (seconds) of ``[T, 3]`` probabilities at ``FPS``: decoded at ``FPS / 2``, refined at
    ``FPS``."""
    frames = len(probs) // _POOL * _POOL
    pooled = probs[:frames].reshape(-1, _POOL, 3).max(axis=1)
    coarse = decode(pooled[:, 1], pooled[:, 2], FPS / _POOL, config)
    strength = probs[:, 1] + probs[:, 2]

    def refine(times: np.ndarray) -> np.ndarray:
        centre = frame_of(times)
        window = np.clip(centre[:, None] + np.arange(-_REFINE, _REFINE + 1)[None, :], 0, len(probs) - 1)
        return window[np.arange(len(window)), strength[window].argmax(axis=1)] / FPS

    beats = refine(coarse.beats)
    downbeats = beats[np.isin(frame_of(coarse.beats), frame_of(coarse.downbeats))]
    return Decoded(beats, downbeats, coarse.metre, coarse.bpm)


def track(samples: np.ndarray, sr: int, model: BeatTCN | Sequence[BeatTCN] | None = None,
          config: DecoderConfig = DEFAULT_DECODER) -> Decoded:
    """Beat and downbeat times in seconds, beats per bar and median tempo (BPM) of a mono ``[N]`` song at ``sr``
    Hz (``model``: see :func:`activations`)."""
    return decode_activations(activations(samples, sr, model), config)
