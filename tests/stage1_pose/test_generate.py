import numpy as np
import pytest
import torch
from torch import nn

# The machine is shared: one intra-op thread avoids OpenMP contention that makes tiny ops take milliseconds.
torch.set_num_threads(1)

from dancesynth.core.checkpoint import save_checkpoint  # noqa: E402
from dancesynth.core.errors import DancesynthError  # noqa: E402
from stage1_pose.generate import generate_from_features, load_pose_model  # noqa: E402
from stage1_pose.train import TrainerConfig, train  # noqa: E402

TINY_DR = dict(d_model=16, heads=2, d_k=8, d_v=8, d_ff=32, layers=1, window=6, lstm_hidden=32, window_frames=30,
               batch_size=4, epoch_windows=0)


@pytest.fixture(scope="module")
def run(tiny_stage1_dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("gen") / "run"
    train("dance_revolution", tiny_stage1_dataset, out, overrides=TINY_DR, epochs=1,
          options=TrainerConfig(preview_every=0))
    return out


BEATS = np.arange(0.0, 30.0, 0.5)  # seconds: 120 BPM


def test_generated_dance_is_in_pixels_any_length_and_seeded(run):
    model = load_pose_model(run, "cpu", "fp32")
    feats = np.random.default_rng(0).standard_normal((400, 438)).astype(np.float32)
    a, b, c = (generate_from_features(model, feats, BEATS, seed=s) for s in (1, 1, 2))
    assert len(a) == 400 and a.fps == 15.0 and (a.width, a.height) == (1280, 720)
    assert np.isfinite(a.keypoints).all() and (a.confidence == 1).all()
    assert 0 < np.median(a.xy[..., 0]) < 1280
    np.testing.assert_array_equal(a.keypoints, b.keypoints)
    assert not np.allclose(a.keypoints, c.keypoints)
    with pytest.raises(DancesynthError, match="438"):
        generate_from_features(model, feats[:, :20], BEATS)


def test_int8_decoding_close_to_fp32_in_pixels(run):
    feats = np.random.default_rng(1).standard_normal((60, 438)).astype(np.float32)
    exact = generate_from_features(load_pose_model(run, "cpu", "fp32"), feats, BEATS)
    fast = generate_from_features(load_pose_model(run, "cpu", "int8"), feats, BEATS)
    assert np.abs(exact.xy - fast.xy).mean() < 5.0  # pixels on a 1280x720 canvas


def test_a_stage2_run_is_refused_with_a_hint(tmp_path):
    save_checkpoint(tmp_path, nn.Linear(2, 2), {"kind": "stage2"})
    with pytest.raises(DancesynthError, match="appearance model.*pose model"):
        load_pose_model(tmp_path)
    with pytest.raises(DancesynthError, match="precision"):
        load_pose_model(tmp_path, precision="int4")


def test_methods_get_the_songs_tracked_beats():
    """Dancing2Music warps its units onto the song's beats: generate_dance must hand it the tracked beats."""
    from dataclasses import replace

    from stage1_pose.generate import LoadedPoseModel, generate_dance
    from stage1_pose.models.dancing2music.model import DANCING2MUSIC_PRESETS, Dancing2MusicMethod

    sr, seconds = 22050, 8.0
    song = np.zeros(int(seconds * sr), np.float32)
    for beat in np.arange(0, seconds, 0.5):  # 120 BPM kicks
        k = int(beat * sr)
        song[k:k + 2000] += np.sin(2 * np.pi * 60 * np.arange(2000) / sr) * np.exp(-np.arange(2000) / 400)
    method = Dancing2MusicMethod(replace(DANCING2MUSIC_PRESETS["small"], gru_hidden=16, mlp_hidden=16, z_mov=4,
                                         z_dan=4, noise_dim=2)).eval()
    received = []
    plain = method.generate
    method.generate = lambda features, beats, generator=None: received.append(beats) or plain(features, beats,
                                                                                              generator)
    meta = {"fps": 15.0, "feature_kind": "dancing2music", "canvas": [1280, 720], "body_scale": 100.0,
            "feature_stats": {"mean": [0.0] * 28, "std": [1.0] * 28}}
    dance = generate_dance(LoadedPoseModel(method, meta, torch.device("cpu")), song, sr)
    assert len(dance) == 120
    assert received[0].shape == (1, 120) and received[0].dtype == torch.bool
    beats = torch.nonzero(received[0][0]).flatten().numpy()
    true_frames = np.arange(0, seconds, 0.5) * 15
    assert np.abs(beats[:, None] - true_frames[None]).min(axis=1).max() < 1.0 and len(beats) >= 14
