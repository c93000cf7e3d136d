"""Dance Revolution's features: the beat one-hot and onset columns follow the kicks of a drum loop."""

import mir_eval
import numpy as np

from stage1_pose.music_features import extract_features

ONSET_COLUMN, BEAT_COLUMN = 20 + 20 + 12, 20 + 20 + 12 + 1  # after MFCC, delta-MFCC and chroma


def test_beat_and_onset_columns_follow_the_kicks(drum_loop):
    sr = 22050
    y, beats = drum_loop(120, 8.0, sr)
    feats = extract_features(y, sr, "dance_revolution")
    beat_frames = np.flatnonzero(feats[:, BEAT_COLUMN])
    assert mir_eval.beat.f_measure(beats, beat_frames / 15.0, f_measure_threshold=0.07) >= 0.9
    kick_frames = np.round(beats * 15).astype(int)
    onset = feats[:, ONSET_COLUMN]
    assert onset[kick_frames].mean() > 2 * np.median(onset)


def test_given_beats_fill_the_beat_column():
    y = np.random.default_rng(0).standard_normal(22050 * 3).astype(np.float32) * 0.1
    feats = extract_features(y, 22050, "dance_revolution", beats=np.array([0.52, 1.0, 2.2]))
    assert np.flatnonzero(feats[:, BEAT_COLUMN]).tolist() == [8, 15, 33]
