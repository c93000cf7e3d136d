"""The learned tracker's input: log-mel frames at about 100 frames per second.

Frame ``i`` sits at ``i / FPS`` seconds (``FPS = SR / HOP``, 100.23; centred 2048-sample windows at 22050 Hz,
:func:`stage1_pose.music_features.log_mel`). Activations, targets and the decoder all count in these frames; times leave
this package in seconds.
"""

from __future__ import annotations

import numpy as np

from stage1_pose.music_features import log_mel, resample_audio

SR = 22050
HOP = 220
FPS = SR / HOP
N_MELS = 64
# Network input scale: decibels over the song's loud level (its 99th percentile) divided by this, so gain is
# removed and values stay near [-4, 1].
_DB_SCALE = 20.0
_LOUD_PERCENTILE = 99.0


def mel_frames(samples: np.ndarray, sr: int) -> np.ndarray:
    """``[T, N_MELS]`` float32 log-mel power in dB of a mono ``[N]`` song at ``sr`` Hz, ``T = 1 + N' // HOP``
    frames at ``FPS`` (``N'`` samples after resampling to ``SR``)."""
    return np.ascontiguousarray(log_mel(resample_audio(samples, sr, SR), SR, HOP, n_mels=N_MELS).T, np.float32)


def network_input(mel_db: np.ndarray) -> np.ndarray:
    """``[T, 2 * N_MELS]`` float32 network input from ``[T, N_MELS]`` dB frames: the levels relative to the
    excerpt's loud level, then their rise since the previous frame (half-wave rectified spectral flux)."""
    x = (mel_db - np.percentile(mel_db, _LOUD_PERCENTILE)) / _DB_SCALE
    flux = np.maximum(np.diff(x, axis=0, prepend=x[:1]), 0.0)
    return np.concatenate([x, flux], axis=1).astype(np.float32)


def frame_of(times: np.ndarray) -> np.ndarray:
    """Nearest frame index (int64) of each time in seconds."""
    return np.round(np.asarray(times, np.float64) * FPS).astype(np.int64)
