"""Ren et al.'s waveform input: consecutive pieces of the song, one per pose frame."""

import numpy as np

from stage1_pose.features import extract_features
from stage1_pose.models.ren.features import WAVEFORM_SR


def test_waveform_rows_are_consecutive_audio():
    y = np.arange(WAVEFORM_SR * 2, dtype=np.float32) / 1e5
    rows = extract_features(y, WAVEFORM_SR, "waveform")
    np.testing.assert_array_equal(rows.reshape(-1), y)
