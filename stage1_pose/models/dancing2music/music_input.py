"""Dancing2Music's music features (Lee et al. 2019): 28 numbers per pose frame, computed with librosa at
``ANALYSIS_SR``: MFCC 13, delta-MFCC 13, RMS energy 1, delta-RMS 1."""

from __future__ import annotations

import numpy as np

from stage1_pose.music_features import (
    ANALYSIS_SR,
    N_FFT,
    analysis_hop,
    analysis_signal,
    blockwise,
    log_mel,
    num_pose_frames,
    pose_rows,
    stft_margin,
)

FEATURE_DIM = 13 + 13 + 1 + 1


def feature_dim(fps: float) -> int:
    """28 at any ``fps``."""
    return FEATURE_DIM


def extract(samples: np.ndarray, sr: int, fps: float, beats: np.ndarray | None) -> np.ndarray:
    """Mono ``[N]`` samples at ``sr`` Hz -> ``[num_pose_frames, 28]`` features (see the module docstring); ``beats``
    are not used."""
    import librosa

    num_frames = num_pose_frames(len(samples), sr, fps)
    y = analysis_signal(samples, sr)
    hop = analysis_hop(fps)
    mfcc = librosa.feature.mfcc(S=log_mel(y, ANALYSIS_SR, hop), n_mfcc=13)
    rms = blockwise(y, hop, stft_margin(hop), lambda block: librosa.feature.rms(
        y=block, frame_length=N_FFT, hop_length=hop))
    stacked = np.concatenate([mfcc, rms])
    delta = librosa.feature.delta(stacked, mode="nearest")
    rows = pose_rows(num_frames, fps, hop, stacked.shape[-1])
    return np.concatenate([mfcc[:, rows].T, delta[:13, rows].T, rms[:, rows].T, delta[13:, rows].T], axis=1)
