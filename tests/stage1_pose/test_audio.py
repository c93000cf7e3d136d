"""Audio features: exact pose-frame alignment for any length and sample rate; beat tracking on drum loops."""

import os

os.environ.setdefault("NUMBA_CACHE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", ".venv", "numba-cache"))

import numpy as np
import pytest

from stage1_pose import audio
from dancesynth.core.errors import DancesynthError


def drum_loop(bpm: float, seconds: float, sr: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Kick on every beat, a loud noise hi-hat half-way between beats; returns (samples, kick times in s)."""
    rng = np.random.default_rng(seed)
    y = np.zeros(int(seconds * sr))
    t = np.arange(int(0.15 * sr)) / sr
    kick = np.sin(2 * np.pi * (60 + 100 * np.exp(-t * 30)) * t) * np.exp(-t * 20)
    hat = rng.standard_normal(int(0.05 * sr)) * np.exp(-np.arange(int(0.05 * sr)) / sr * 80)
    beats = np.arange(0.0, seconds - 0.2, 60.0 / bpm)
    for b in beats:
        for start, sound, gain in ((b, kick, 1.0), (b + 30.0 / bpm, hat, 1.5)):
            i = int(start * sr)
            part = sound[:max(0, len(y) - i)]
            y[i:i + len(part)] += gain * part
    return (0.4 * y / np.abs(y).max()).astype(np.float32), beats


def test_num_pose_frames():
    assert audio.num_pose_frames(15360, 15360, 15) == 15
    assert audio.num_pose_frames(44099, 44100, 15) == 14
    assert audio.num_pose_frames(10, 44100, 15) == 1
    assert audio.num_pose_frames(30000 * 10, 30000, 29.97) == 299


@pytest.mark.parametrize("sr", [22050, 44100, 11025, 16000])
@pytest.mark.parametrize("kind", audio.FEATURE_KINDS)
def test_feature_rows_match_pose_frames_short(sr, kind):
    y = np.random.default_rng(sr).standard_normal(sr + 7).astype(np.float32) * 0.1
    features = audio.extract_features(y, sr, kind)
    assert features.shape == (audio.num_pose_frames(len(y), sr, 15), audio.feature_dim(kind))
    assert features.dtype == np.float32 and np.isfinite(features).all()


@pytest.mark.parametrize("kind", audio.FEATURE_KINDS)
def test_feature_rows_match_pose_frames_long(kind):
    sr = 11025
    y, _ = drum_loop(120, 61.0, sr)
    features = audio.extract_features(y, sr, kind)
    assert features.shape == (audio.num_pose_frames(len(y), sr, 15), audio.feature_dim(kind)) == (915, features.shape[1])
    assert np.isfinite(features).all()


def test_feature_dims_and_other_fps():
    assert audio.feature_dim("dance_revolution") == 438
    assert audio.feature_dim("dancing2music") == 28
    assert audio.feature_dim("waveform") == 1024 and audio.feature_dim("waveform", fps=10) == 1536
    y = np.random.default_rng(0).standard_normal(22050 * 2).astype(np.float32) * 0.1
    assert audio.extract_features(y, 22050, "dancing2music", fps=24).shape == (48, 28)
    with pytest.raises(DancesynthError, match="whole number"):
        audio.extract_features(y, 22050, "waveform", fps=7)
    with pytest.raises(DancesynthError, match="dance_revolution, dancing2music, waveform"):
        audio.extract_features(y, 22050, "mel")


def test_waveform_rows_are_consecutive_audio():
    y = np.arange(audio.WAVEFORM_SR * 2, dtype=np.float32) / 1e5
    rows = audio.extract_features(y, audio.WAVEFORM_SR, "waveform")
    np.testing.assert_array_equal(rows.reshape(-1), y)


def test_dance_revolution_beat_and_onset_columns_follow_the_kicks():
    sr = 22050
    y, beats = drum_loop(120, 8.0, sr)
    features = audio.extract_features(y, sr, "dance_revolution")
    beat_frames = np.flatnonzero(features[:, audio.BEAT_COLUMN])
    assert audio.beat_f_measure(beat_frames / 15.0, beats, tolerance=0.07) >= 0.9
    kick_frames = np.round(beats * 15).astype(int)
    onset = features[:, audio.BEAT_COLUMN - 1]
    assert onset[kick_frames].mean() > 2 * np.median(onset)


@pytest.mark.parametrize("bpm", [75, 128])
def test_beat_tracking_ignores_off_beat_hats(bpm):
    sr = 22050
    y, reference = drum_loop(bpm, 10.0, sr)
    assert audio.beat_f_measure(audio.beat_times(y, sr), reference) >= 0.9
    assert audio.tempo(y, sr) == pytest.approx(bpm, abs=2)


def test_click_track_at_odd_sample_rate():
    sr = 16000
    y = np.zeros(sr * 8, np.float32)
    reference = np.arange(0.25, 7.8, 0.5)
    for b in reference:
        i = int(b * sr)
        y[i:i + 200] = np.sin(2 * np.pi * 100 * np.arange(200) / sr)
    assert audio.beat_f_measure(audio.beat_times(y, sr), reference) >= 0.9


def test_onset_strength_peaks_on_clicks():
    sr = 22050
    y, beats = drum_loop(100, 6.0, sr)
    onset = audio.onset_strength(y, sr, fps=15)
    assert onset.shape == (90,)
    peaks = np.round(beats[1:] * 15).astype(int)  # spectral flux has no onset at t = 0
    assert onset[peaks].min() > 3 * np.median(onset)


def test_beat_f_measure():
    ref = np.array([1.0, 2.0, 3.0, 4.0])
    assert audio.beat_f_measure(ref + 0.05, ref) == 1.0
    assert audio.beat_f_measure(ref + 0.1, ref) == 0.0
    assert audio.beat_f_measure([1.0, 1.01, 2.0], ref) == pytest.approx(2 * (2 / 3 * 0.5) / (2 / 3 + 0.5))
    assert audio.beat_f_measure([], ref) == 0.0


def test_blockwise_analysis_equals_whole_song_analysis(monkeypatch):
    """Features are computed block by block (flat memory for any song length) yet match librosa's whole-song
    transforms."""
    import librosa

    sr, hop = audio.ANALYSIS_SR, 512
    rng = np.random.default_rng(0)
    t = np.arange(12 * sr) / sr
    y = (0.3 * np.sin(2 * np.pi * 443 * t) * (1 + np.sin(t)) + 0.05 * rng.standard_normal(len(t))).astype(np.float32)
    monkeypatch.setattr(audio, "_BLOCK_FRAMES", 64)  # 12 s = 361 frames: six blocks
    log_mel = audio._log_mel(y, sr, hop)
    np.testing.assert_allclose(log_mel, librosa.power_to_db(librosa.feature.melspectrogram(y=y, sr=sr, hop_length=hop)),
                               atol=1e-3)
    np.testing.assert_allclose(audio._onset_envelope(log_mel, sr, hop),
                               librosa.onset.onset_strength(y=y, sr=sr, hop_length=hop), atol=1e-3)
    assert audio._tuning(y, sr, 36) == pytest.approx(librosa.estimate_tuning(y=y, sr=sr, bins_per_octave=36))
    chroma = audio._chroma(y, sr, hop)
    reference = librosa.feature.chroma_cqt(y=y, sr=sr, hop_length=hop)
    np.testing.assert_allclose(chroma, reference, atol=1e-3)
