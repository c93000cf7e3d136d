"""Dancing2Music's music features (Lee et al. 2019): 29 numbers per pose frame, computed with librosa at
``ANALYSIS_SR``: MFCC 13, delta-MFCC 13, RMS energy 1, delta-RMS 1 (the paper's 28), and the song's tempo 1
(``log2(BPM / 120)`` from the given beats or the beat tracker's, the same in every row; not in the paper).

The tempo column is there for the music style classifier: the sound columns of three synthetic styles say nothing
reliable about a recorded song (the classifier called 3-minute rock songs ballet or pop depending on the training
run), while the tracker's tempo is measured on real recordings (``benchmarks/beat_benchmark.py``).
"""

from __future__ import annotations

import numpy as np

from stage1_pose.beats import beat_times
from stage1_pose.features import (
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

VERSION = 2
FEATURE_DIM = 13 + 13 + 1 + 1 + 1
# The columns that describe the sound; the last one is the tempo.
SOUND_COLUMNS = FEATURE_DIM - 1
# Tempo of the column's 0 and of a song with fewer than two beats.
_REFERENCE_BPM = 120.0


def feature_dim(fps: float) -> int:
    """29 at any ``fps``."""
    return FEATURE_DIM


def tempo_value(beats: np.ndarray) -> float:
    """The tempo column for beat times ``[B]`` in seconds: ``log2(BPM / 120)``, BPM from the median beat interval."""
    gaps = np.diff(np.asarray(beats, np.float64))
    gaps = gaps[gaps > 0]
    return float(np.log2(60.0 / np.median(gaps) / _REFERENCE_BPM)) if gaps.size else 0.0


def extract(samples: np.ndarray, sr: int, fps: float, beats: np.ndarray | None) -> np.ndarray:
    """Mono ``[N]`` samples at ``sr`` Hz and their beat times in seconds (None: tracked here) ->
    ``[num_pose_frames, 29]`` features (see the module docstring)."""
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
    tempo = tempo_value(beat_times(samples, sr) if beats is None else beats)
    return np.concatenate([mfcc[:, rows].T, delta[:13, rows].T, rms[:, rows].T, delta[13:, rows].T,
                           np.full((len(rows), 1), tempo)], axis=1)
