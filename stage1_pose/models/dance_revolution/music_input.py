"""Dance Revolution's music features (Huang et al. 2021, Sec. 4.1): 438 numbers per pose frame, computed with
librosa at ``ANALYSIS_SR`` (15360 Hz, hop 512 at 15 fps).

Columns: MFCC 20, delta-MFCC 20, chroma (CQT) 12, onset strength 1, beat one-hot 1 (the given beats, or the beat
tracker's, :func:`stage1_pose.beats.beat_times`), tempogram 384. The model reads the song's beats from its own ``beats``
input, not from the one-hot column, which is kept as the paper's feature.
"""

from __future__ import annotations

import numpy as np

from stage1_pose.beats import beat_times, beats_on_frames
from stage1_pose.music_features import (
    ANALYSIS_SR,
    analysis_hop,
    analysis_signal,
    blockwise,
    chroma,
    log_mel,
    num_pose_frames,
    onset_envelope,
    pose_rows,
)

# The tempogram's autocorrelation window in analysis frames, as in the paper's code: its number of columns.
TEMPOGRAM_WINDOW = 384
FEATURE_DIM = 20 + 20 + 12 + 1 + 1 + TEMPOGRAM_WINDOW


def feature_dim(fps: float) -> int:
    """438 at any ``fps``."""
    return FEATURE_DIM


def extract(samples: np.ndarray, sr: int, fps: float, beats: np.ndarray | None) -> np.ndarray:
    """Mono ``[N]`` samples at ``sr`` Hz and their beat times in seconds (None: tracked here) ->
    ``[num_pose_frames, 438]`` features (see the module docstring)."""
    import librosa

    num_frames = num_pose_frames(len(samples), sr, fps)
    y = analysis_signal(samples, sr)
    hop = analysis_hop(fps)
    mel_db = log_mel(y, ANALYSIS_SR, hop)
    mfcc = librosa.feature.mfcc(S=mel_db, n_mfcc=20)
    mfcc_delta = librosa.feature.delta(mfcc, mode="nearest")
    pitch = chroma(y, ANALYSIS_SR, hop)
    onset = onset_envelope(mel_db, ANALYSIS_SR, hop)
    tempogram = blockwise(onset, 1, TEMPOGRAM_WINDOW // 2 + 1, lambda block: librosa.feature.tempogram(
        onset_envelope=block, sr=ANALYSIS_SR, hop_length=hop, win_length=TEMPOGRAM_WINDOW), frames=len(onset))
    available = min(m.shape[-1] for m in (mfcc, pitch, onset[None], tempogram))
    rows = pose_rows(num_frames, fps, hop, available)
    # Beats are placed on the nearest pose frame rather than subsampled, so none is lost between kept frames.
    beats = beat_times(samples, sr) if beats is None else beats
    beat = beats_on_frames(beats, num_frames, fps).astype(np.float32)
    return np.concatenate([mfcc[:, rows].T, mfcc_delta[:, rows].T, pitch[:, rows].T, onset[rows, None],
                           beat[:, None], tempogram[:, rows].T], axis=1)
