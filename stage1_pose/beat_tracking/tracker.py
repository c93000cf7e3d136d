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
# Support tolerance: the benchmark's +-70 ms, in full-rate frames.
_SUPPORT_FRAMES = 7
# Another tracker's beats replace the decoded ones only when the activations support them by more than this: with
# the decoder's beat regions at 1/10 of a beat, smaller margins swapped right decodings on the benchmark's held-out
# pieces for the DSP beats or a half.
SUPPORT_MARGIN = 0.1
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
    strength = _strength(probs)

    def refine(times: np.ndarray) -> np.ndarray:
        window = _windows(times, _REFINE, len(probs))
        return window[np.arange(len(window)), strength[window].argmax(axis=1)] / FPS

    beats = refine(coarse.beats)
    downbeats = beats[np.isin(frame_of(coarse.beats), frame_of(coarse.downbeats))]
    return Decoded(beats, downbeats, coarse.metre, coarse.bpm)


def track(samples: np.ndarray, sr: int, model: BeatTCN | Sequence[BeatTCN] | None = None,
          config: DecoderConfig = DEFAULT_DECODER) -> Decoded:
    """Beat and downbeat times in seconds, beats per bar and median tempo (BPM) of a mono ``[N]`` song at ``sr``
    Hz (``model``: see :func:`activations`)."""
    return decode_activations(activations(samples, sr, model), config)


def _strength(probs: np.ndarray) -> np.ndarray:
    """``[T]`` beat strength of ``[T, 3]`` probabilities: a beat of either kind."""
    return probs[:, 1] + probs[:, 2]


def _windows(times: np.ndarray, half: int, length: int) -> np.ndarray:
    """``[len(times), 2 * half + 1]`` frame indices (at ``FPS``, clipped to ``length``) around each time (seconds)."""
    centre = np.clip(frame_of(np.asarray(times)), 0, length - 1)
    return np.clip(centre[:, None] + np.arange(-half, half + 1)[None, :], 0, length - 1)


def support(beats: np.ndarray, probs: np.ndarray) -> float:
    """How well ``[T, 3]`` probabilities at ``FPS`` support beat times ``beats`` (seconds), in [0, 1]: the harmonic
    mean of the mean beat strength (beat + downbeat probability) at its strongest within 70 ms of each beat, and the
    share of the strength's peaks, weighted by height, within 70 ms of a beat. A half-tempo answer loses the
    second, a double-tempo one the first. 0 with fewer than 2 beats."""
    strength = _strength(probs)
    if len(beats) < 2 or len(strength) < 3:
        return 0.0
    window = _windows(beats, _SUPPORT_FRAMES, len(strength))
    precision = float(strength[window].max(axis=1).mean())
    peaks = np.flatnonzero((strength[1:-1] >= strength[:-2]) & (strength[1:-1] > strength[2:])) + 1
    near = np.zeros(len(strength), bool)
    near[window.ravel()] = True
    recall = float(strength[peaks][near[peaks]].sum() / max(strength[peaks].sum(), 1e-9))
    return 2 * precision * recall / max(precision + recall, 1e-9)


def checked(decoded: Decoded, probs: np.ndarray, beats: np.ndarray, bpm: float) -> Decoded:
    """``decoded`` (from ``probs``), or the best supported of its alternatives when ``probs`` support it by more
    than :data:`SUPPORT_MARGIN` (:func:`support`): another tracker's ``beats`` (seconds, at ``bpm``) and every other
    decoded beat (either phase, at half the tempo). The decoder's tempo model can settle on a ratio its own
    activations do not bear out (double tempo, 3:2). The bars are then every 3rd or 4th of the beats taken, the
    metre and phase on whose beats the downbeat probability is highest on average (the decoded metre and downbeats
    came from the wrong tempo)."""
    alternatives = [(np.asarray(beats, np.float64), bpm),
                    *((decoded.beats[phase::2], decoded.bpm / 2) for phase in (0, 1))]
    scores = [support(times, probs) for times, _ in alternatives]
    best = int(np.argmax(scores))
    if scores[best] <= support(decoded.beats, probs) + SUPPORT_MARGIN:
        return decoded
    beats, bpm = alternatives[best]
    at_beats = probs[:, 2][_windows(beats, _SUPPORT_FRAMES, len(probs))].max(axis=1)
    # Only reached with at least 2 beats (support is 0 below), so every metre's first phase has beats.
    _, metre, phase = max((at_beats[phase::metre].mean(), metre, phase) for metre in DEFAULT_DECODER.metres
                          for phase in range(metre) if len(at_beats[phase::metre]))
    return Decoded(beats, beats[phase::metre], metre, bpm)
