"""Beat tracking on drum loops, click tracks and a real recording; beats placed on pose frames; onset strength."""

import json
from pathlib import Path

import mir_eval
import numpy as np
import pytest

from dancesynth.core.media import load_song
from stage1_pose import beats
from stage1_pose.beats import DANCE_MAX_BPM, beat_times, beats_on_frames, dance_tempo, onset_strength, tempo

REAL_SONG = Path(__file__).parents[1] / "data" / "real_song" / "escape_from_chaosland_40-65s"


@pytest.mark.parametrize("bpm", [75, 128])
def test_beat_tracking_ignores_off_beat_hats(bpm, drum_loop):
    sr = 22050
    y, reference = drum_loop(bpm, 10.0, sr)
    assert mir_eval.beat.f_measure(reference, beat_times(y, sr)) >= 0.9
    assert tempo(y, sr) == pytest.approx(bpm, abs=2)


def test_click_track_at_odd_sample_rate():
    sr = 16000
    y = np.zeros(sr * 8, np.float32)
    reference = np.arange(0.25, 7.8, 0.5)
    for b in reference:
        i = int(b * sr)
        y[i:i + 200] = np.sin(2 * np.pi * 100 * np.arange(200) / sr)
    assert mir_eval.beat.f_measure(reference, beat_times(y, sr)) >= 0.9


def test_a_steady_kick_wins_over_a_slightly_stronger_unrelated_hat_tempo(monkeypatch):
    """Kicks at 95 BPM under hi-hats at 126 BPM loud enough that 126 scores a little higher in the tempograms: the
    beats tracked at each close tempo decide, and the kicks' beats sit on the stronger onsets."""
    sr, seconds = 22050, 30.0
    t = np.arange(int(seconds * sr)) / sr
    y = np.zeros_like(t)
    kicks = np.arange(0.0, seconds - 0.2, 60 / 95)
    for b in kicks:
        i = int(b * sr)
        y[i:i + 3300] += np.sin(2 * np.pi * 60 * t[:3300]) * np.exp(-t[:3300] / 0.0375)
    rng = np.random.default_rng(0)
    for b in np.arange(0.11, seconds - 0.1, 60 / 126):
        i = int(b * sr)
        y[i:i + 661] += 0.28 * rng.standard_normal(661) * np.exp(-t[:661] / 0.008)
    y = y.astype(np.float32)
    assert tempo(y, sr) == 95.0
    assert mir_eval.beat.f_measure(kicks, beat_times(y, sr)) >= 0.9
    monkeypatch.setattr(beats, "_TEMPO_TIE", 0.0)  # the tempograms alone pick the hats
    assert tempo(y, sr) == 126.0


def test_real_rock_recording_beats_tempo_and_timing():
    """25 s of a recorded rock song (135 BPM, distorted guitars, drums) whose beats come from its chart."""
    sr = 22050
    y = load_song(REAL_SONG.with_suffix(".ogg"), sr)
    reference = np.array(json.loads(REAL_SONG.with_suffix(".beats.json").read_text())["beats"])
    tracked = beat_times(y, sr)
    assert mir_eval.beat.f_measure(reference, tracked) >= 0.8
    assert tempo(y, sr) == pytest.approx(135, abs=3)
    # On time, not only within the F-measure's 70 ms: librosa's centred onset envelope put them 29 ms late here.
    offsets = tracked[:, None] - reference[None]
    assert abs(np.median(offsets[np.arange(len(tracked)), np.abs(offsets).argmin(axis=1)])) <= 0.025


def test_dance_tempo_is_half_time_for_fast_songs():
    assert dance_tempo(120.0) == 120.0 and dance_tempo(DANCE_MAX_BPM) == DANCE_MAX_BPM
    assert dance_tempo(176.0) == 88.0 and dance_tempo(300.0) == 75.0


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


def test_the_mean_tempogram_is_librosas_tempogram_averaged_over_frames():
    # The tracker computes it itself (4x faster); a song longer than one block of frames, ending mid-block.
    import librosa

    onset = np.random.default_rng(0).random(2500)
    win = int(round(beats._TEMPO_WINDOW_SECONDS * beats._BEAT_SR / beats._BEAT_HOP))
    expected = librosa.feature.tempogram(onset_envelope=onset, sr=beats._BEAT_SR, hop_length=beats._BEAT_HOP,
                                         win_length=win).mean(axis=1)
    np.testing.assert_allclose(beats._mean_tempogram(onset), expected, atol=1e-12)


@pytest.mark.parametrize("bpm, tightness, dtype", [(96.0, 400.0, np.float32), (143.5, 100.0, np.float64)])
def test_the_beat_dynamic_programme_gives_librosas_frames(bpm, tightness, dtype):
    # The tracker runs it itself (librosa's compiles numba kernels in every process, seconds before the first
    # song): a click every beat with a drifting phase and noise, silent at both ends, so every step of it counts.
    import librosa

    rng = np.random.default_rng(1)
    rate = beats._BEAT_SR / beats._BEAT_HOP
    onset = rng.random(3000) * 0.3
    clicks = np.cumsum(rng.normal(60 * rate / bpm, 1.5, 60)).astype(int) + 200
    onset[clicks[clicks < 2700]] += 2.0
    onset[:150] = onset[2800:] = 0.0
    onset = onset.astype(dtype)
    expected = librosa.beat.beat_track(onset_envelope=onset, sr=beats._BEAT_SR, hop_length=beats._BEAT_HOP, bpm=bpm,
                                       tightness=tightness, units="frames")[1]
    found = beats.dp_beats(onset, bpm, rate, tightness)
    assert len(found) > 40 and np.array_equal(found, expected)
