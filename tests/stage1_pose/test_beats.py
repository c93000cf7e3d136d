"""Beat tracking on drum loops and click tracks, beats placed on pose frames, onset strength and beat scoring."""

import numpy as np
import pytest

from stage1_pose.beats import beat_f_measure, beat_times, beats_on_frames, onset_strength, tempo


@pytest.mark.parametrize("bpm", [75, 128])
def test_beat_tracking_ignores_off_beat_hats(bpm, drum_loop):
    sr = 22050
    y, reference = drum_loop(bpm, 10.0, sr)
    assert beat_f_measure(beat_times(y, sr), reference) >= 0.9
    assert tempo(y, sr) == pytest.approx(bpm, abs=2)


def test_click_track_at_odd_sample_rate():
    sr = 16000
    y = np.zeros(sr * 8, np.float32)
    reference = np.arange(0.25, 7.8, 0.5)
    for b in reference:
        i = int(b * sr)
        y[i:i + 200] = np.sin(2 * np.pi * 100 * np.arange(200) / sr)
    assert beat_f_measure(beat_times(y, sr), reference) >= 0.9


def test_beats_land_on_the_nearest_pose_frame():
    flags = beats_on_frames(np.array([-0.5, 0.0, 0.31, 0.52, 0.92, 0.99]), 15, 15.0)
    assert flags.dtype == bool and flags.shape == (15,)
    assert np.flatnonzero(flags).tolist() == [0, 5, 8, 14]  # frames 4.65, 7.8, 13.8; 14.85 rounds past the end


def test_onset_strength_peaks_on_clicks(drum_loop):
    sr = 22050
    y, beats = drum_loop(100, 6.0, sr)
    onset = onset_strength(y, sr, fps=15)
    assert onset.shape == (90,)
    peaks = np.round(beats[1:] * 15).astype(int)  # spectral flux has no onset at t = 0
    assert onset[peaks].min() > 3 * np.median(onset)


def test_beat_f_measure():
    ref = np.array([1.0, 2.0, 3.0, 4.0])
    assert beat_f_measure(ref + 0.05, ref) == 1.0
    assert beat_f_measure(ref + 0.1, ref) == 0.0
    assert beat_f_measure([1.0, 1.01, 2.0], ref) == pytest.approx(2 * (2 / 3 * 0.5) / (2 / 3 + 0.5))
    assert beat_f_measure([], ref) == 0.0
