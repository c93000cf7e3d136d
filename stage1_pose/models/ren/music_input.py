"""Ren et al.'s music input: the samples of each pose frame at ``WAVEFORM_SR`` Hz (1024 per frame at 15 fps), for
the convolutional audio encoder; row ``i`` covers seconds ``[i / fps, (i + 1) / fps)``. The song is first brought to
one level (:func:`~stage1_pose.music_features.level_normalised`, not in the paper): trained on the built-in songs, whose
level is steady, the model danced a real recording's quiet intro and its loud rest at different speeds."""

from __future__ import annotations

import numpy as np

from dancesynth.core.errors import DancesynthError
from stage1_pose.music_features import level_normalised, num_pose_frames, resample_audio

WAVEFORM_SR = 15360
# The recipe's version (stage1_pose.music_features.cache_name): 2 since the level normalisation.
VERSION = 2


def feature_dim(fps: float) -> int:
    """Samples per pose frame, ``WAVEFORM_SR / fps``; a rate that does not divide it raises a DancesynthError."""
    per_frame = WAVEFORM_SR / float(fps)
    if abs(per_frame - round(per_frame)) > 1e-6:
        raise DancesynthError(f"The waveform feature needs {WAVEFORM_SR} / fps to be a whole number of samples, "
                              f"but fps is {fps:g}; use an fps such as 10, 15, 20, 24, 30 or 60.")
    return int(round(per_frame))


def extract(samples: np.ndarray, sr: int, fps: float, beats: np.ndarray | None) -> np.ndarray:
    """Mono ``[N]`` samples at ``sr`` Hz -> ``[num_pose_frames, WAVEFORM_SR / fps]`` level-normalised samples, the
    last row padded with silence; ``beats`` are not used."""
    num_frames = num_pose_frames(len(samples), sr, fps)
    per_frame = feature_dim(fps)
    need = num_frames * per_frame
    y = level_normalised(resample_audio(samples, sr, WAVEFORM_SR), WAVEFORM_SR)
    y = np.pad(y, (0, max(0, need - len(y))))[:need]
    return y.reshape(num_frames, per_frame)
