"""Music features: exact pose-frame alignment for any length and sample rate, every method's recipe through one
dispatch, and block-wise analyses equal to librosa's whole-song ones."""

import numpy as np
import pytest

from dancesynth.core.errors import DancesynthError
from stage1_pose import music_features
from stage1_pose.music_features import FEATURE_KINDS, extract_features, feature_dim, num_pose_frames


def test_num_pose_frames():
    assert num_pose_frames(15360, 15360, 15) == 15
    assert num_pose_frames(44099, 44100, 15) == 14
    assert num_pose_frames(10, 44100, 15) == 1
    assert num_pose_frames(30000 * 10, 30000, 29.97) == 299


@pytest.mark.parametrize("sr", [22050, 44100, 11025, 16000])
@pytest.mark.parametrize("kind", FEATURE_KINDS)
def test_feature_rows_match_pose_frames_short(sr, kind):
    y = np.random.default_rng(sr).standard_normal(sr + 7).astype(np.float32) * 0.1
    feats = extract_features(y, sr, kind)
    assert feats.shape == (num_pose_frames(len(y), sr, 15), feature_dim(kind))
    assert feats.dtype == np.float32 and np.isfinite(feats).all()


@pytest.mark.parametrize("kind", FEATURE_KINDS)
def test_feature_rows_match_pose_frames_long(kind, drum_loop):
    sr = 11025
    y, _ = drum_loop(120, 61.0, sr)
    feats = extract_features(y, sr, kind)
    assert feats.shape == (num_pose_frames(len(y), sr, 15), feature_dim(kind)) == (915, feats.shape[1])
    assert np.isfinite(feats).all()


def test_feature_dims_and_other_fps():
    assert feature_dim("dance_revolution") == 438
    assert feature_dim("dancing2music") == 28
    assert feature_dim("waveform") == 1024 and feature_dim("waveform", fps=10) == 1536
    y = np.random.default_rng(0).standard_normal(22050 * 2).astype(np.float32) * 0.1
    assert extract_features(y, 22050, "dancing2music", fps=24).shape == (48, 28)
    with pytest.raises(DancesynthError, match="whole number"):
        extract_features(y, 22050, "waveform", fps=7)
    with pytest.raises(DancesynthError, match="dance_revolution, dancing2music, waveform"):
        extract_features(y, 22050, "mel")


def test_blockwise_analysis_equals_whole_song_analysis(monkeypatch):
    """Features are computed block by block (flat memory for any song length) yet match librosa's whole-song
    transforms."""
    import librosa

    sr, hop = music_features.ANALYSIS_SR, 512
    rng = np.random.default_rng(0)
    t = np.arange(12 * sr) / sr
    y = (0.3 * np.sin(2 * np.pi * 443 * t) * (1 + np.sin(t)) + 0.05 * rng.standard_normal(len(t))).astype(np.float32)
    monkeypatch.setattr(music_features, "_BLOCK_FRAMES", 64)  # 12 s = 361 frames: six blocks
    mel_db = music_features.log_mel(y, sr, hop)
    np.testing.assert_allclose(mel_db, librosa.power_to_db(librosa.feature.melspectrogram(y=y, sr=sr, hop_length=hop)),
                               atol=1e-3)
    np.testing.assert_allclose(music_features.onset_envelope(mel_db, sr, hop),
                               librosa.onset.onset_strength(y=y, sr=sr, hop_length=hop), atol=1e-3)
    assert music_features._tuning(y, sr, 36) == pytest.approx(librosa.estimate_tuning(y=y, sr=sr, bins_per_octave=36))
    reference = librosa.feature.chroma_cqt(y=y, sr=sr, hop_length=hop)
    np.testing.assert_allclose(music_features.chroma(y, sr, hop), reference, atol=1e-3)
