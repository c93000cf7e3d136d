"""PoseSequence and BODY_25 helpers: exact normalisation inverse, gap filling, resampling, layouts, files."""

import numpy as np
import pytest

from dancesynth.core import skeleton
from dancesynth.core.errors import DancesynthError
from dancesynth.core.motion import mean_jerk
from dancesynth.core.skeleton import NECK, NUM_JOINTS, ROOT, PoseSequence


def random_sequence(frames: int = 12, seed: int = 0, width: int = 640, height: int = 360) -> PoseSequence:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 1, (frames, NUM_JOINTS, 2)) * (width, height)
    conf = rng.uniform(0.2, 1.0, (frames, NUM_JOINTS, 1))
    return PoseSequence(np.concatenate([xy, conf], axis=-1), 15.0, width, height)


def test_value_type_checks_and_properties():
    seq = random_sequence(30)
    assert len(seq) == 30 and seq.duration == 2.0 and seq.xy.shape == (30, 25, 2) and seq.confidence.shape == (30, 25)
    assert seq.keypoints.dtype == np.float32
    assert len(seq.slice_frames(5, 10)) == 5
    with pytest.raises(ValueError):
        PoseSequence(np.zeros((3, 18, 3)), 15, 10, 10)
    with pytest.raises(ValueError):
        PoseSequence(np.zeros((3, 25, 3)), 0, 10, 10)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_normalize_is_exactly_inverted(seed):
    seq = random_sequence(seed=seed, width=1280, height=720)
    model, params = skeleton.normalize(seq)
    assert model.shape == (12, 25, 2) and model.dtype == np.float32
    back = skeleton.denormalize(model, params, seq.confidence)
    np.testing.assert_allclose(back.keypoints, seq.keypoints, atol=1e-4 * params.scale + 1e-4)
    assert (back.width, back.height, back.fps) == (seq.width, seq.height, seq.fps)
    # Torso length is one model unit (median over frames), and the root is relative to the canvas centre.
    torso = np.linalg.norm(model[:, NECK], axis=-1)
    assert np.median(torso) == pytest.approx(1.0, rel=1e-5)
    np.testing.assert_allclose(model[:, ROOT] * params.scale + (640, 360), seq.xy[:, ROOT], atol=1e-3)


def test_interpolate_missing():
    kp = np.zeros((6, NUM_JOINTS, 3), np.float32)
    kp[:, :, 2] = 1.0
    kp[:, 0, 0] = np.arange(6) * 10.0  # joint 0 moves linearly in x
    kp[[0, 2, 3], 0, 2] = 0.0         # absent at the start and in a gap
    kp[:, 5, 2] = 0.0                 # joint 5 never seen
    out = skeleton.interpolate_missing(PoseSequence(kp, 15, 100, 100))
    assert out.keypoints[0, 0, 0] == 10.0  # start gap holds the first observed value
    np.testing.assert_allclose(out.keypoints[2:4, 0, 0], [20.0, 30.0])  # inner gap filled linearly
    np.testing.assert_allclose(out.keypoints[[0, 2, 3], 0, 2], 0.1)
    assert out.keypoints[1, 0, 2] == 1.0
    assert not out.confidence[:, 5].any()


def test_a_joint_lost_for_longer_than_the_largest_gap_stays_absent():
    kp = np.ones((12, NUM_JOINTS, 3), np.float32)
    kp[2:4, 0, 2] = 0.0   # lost for 2 frames: filled
    kp[6:, 1, 2] = 0.0    # lost from frame 6 to the end: not held for 6 frames
    kp[:3, 2, 2] = 0.0    # lost for the first 3 frames: not held either
    out = skeleton.interpolate_missing(PoseSequence(kp, 15, 100, 100), max_gap=2)
    np.testing.assert_allclose(out.confidence[2:4, 0], 0.1)
    assert not out.confidence[6:, 1].any() and not out.confidence[:3, 2].any()
    assert (out.confidence[:6, 1] == 1).all() and (out.confidence[3:, 2] == 1).all()


def test_resample_keeps_duration_and_linear_motion():
    t = np.arange(30) / 30.0
    kp = np.ones((30, NUM_JOINTS, 3), np.float32)
    kp[:, :, 0] = (100 * t)[:, None]
    seq = PoseSequence(kp, 30.0, 200, 200)
    out = skeleton.resample(seq, 15.0)
    assert len(out) == 15 and out.fps == 15.0 and out.duration == seq.duration
    np.testing.assert_allclose(out.keypoints[:, 0, 0], 100 * np.arange(15) / 15.0, atol=1e-4)
    up = skeleton.resample(seq, 60.0)
    assert len(up) == 60
    np.testing.assert_allclose(up.keypoints[:58, 3, 0], 100 * np.arange(58) / 60.0, atol=1e-4)



def dance_at_15fps(seconds: float = 4.0) -> PoseSequence:
    """Joints swinging at 0.5-1.9 Hz, sampled at 15 fps as stage 1 makes dances."""
    t = np.arange(int(seconds * 15))[:, None] / 15.0
    j = np.arange(NUM_JOINTS)[None, :]
    kp = np.ones((len(t), NUM_JOINTS, 3), np.float32)
    kp[..., 0] = 320 + 40 * np.sin(2 * np.pi * (0.5 + 0.05 * j) * t) + 3 * j
    kp[..., 1] = 180 + 25 * np.cos(2 * np.pi * (0.7 + 0.04 * j) * t + j) - 4 * j
    return PoseSequence(kp, 15.0, 640, 360)


def test_resample_is_smooth_and_passes_through_the_source_frames():
    seq = dance_at_15fps()
    up = skeleton.resample(seq, 30.0)
    assert len(up) == 2 * len(seq) and up.duration == seq.duration
    # Every second output frame sits at a source frame's time and reproduces it.
    np.testing.assert_allclose(up.keypoints[::2], seq.keypoints, atol=1e-4)
    linear = np.stack([np.interp(np.arange(len(up)) / 30.0, np.arange(len(seq)) / 15.0, c)
                       for c in seq.xy.reshape(len(seq), -1).T], axis=1).reshape(len(up), NUM_JOINTS, 2)
    assert mean_jerk(up.xy, 30.0) < 0.5 * mean_jerk(linear, 30.0)
    # C1: the velocity into a source frame matches the velocity out of it (linear interpolation jumps there).
    fine = skeleton.resample(seq, 1500.0).xy.astype(np.float64)
    v = np.diff(fine, axis=0) * 1500.0
    at_source = np.arange(100, len(fine) - 100, 100)
    jump = np.abs(v[at_source] - v[at_source - 1]).max()
    assert jump < 0.05 * np.abs(v).max()


def test_resample_ignores_positions_of_absent_joints():
    seq = dance_at_15fps(2.0)
    kp = seq.keypoints.copy()
    kp[10, 4] = (0.0, 0.0, 0.0)  # a dropped detection: its (0, 0) must not pull the curve of frames 9 and 11
    up = skeleton.resample(seq.replace(kp), 30.0)
    # The gap is bridged as if the joint had moved straight from frame 9 to frame 11.
    kp[10, 4] = (kp[9, 4] + kp[11, 4]) / 2
    bridged = skeleton.resample(seq.replace(kp), 30.0)
    np.testing.assert_allclose(up.xy[:, 4], bridged.xy[:, 4], atol=1e-4)
    np.testing.assert_allclose(up.confidence[[19, 20, 21], 4], [0.5, 0.0, 0.5], atol=1e-6)


def test_layout_conversions():
    seq = random_sequence(3)
    coco = skeleton.to_coco18(seq)
    assert coco.shape == (3, 18, 3)
    back = skeleton.from_partial(coco, skeleton.COCO18_TO_BODY25, 15, 640, 360)
    cols = list(skeleton.COCO18_TO_BODY25)
    np.testing.assert_array_equal(back.keypoints[:, cols], seq.keypoints[:, cols])
    # MidHip is derived from the hips; the feet stay absent.
    np.testing.assert_allclose(back.xy[:, ROOT], (seq.xy[:, 9] + seq.xy[:, 12]) / 2, atol=1e-4)
    np.testing.assert_allclose(back.confidence[:, ROOT], np.minimum(seq.confidence[:, 9], seq.confidence[:, 12]))
    assert not back.confidence[:, 19:].any()
    d2m = skeleton.to_dancing2music(seq)
    assert d2m.shape == (3, 14, 2)
    np.testing.assert_array_equal(d2m[:, 1], seq.xy[:, NECK])
    coco17 = seq.keypoints[:, list(skeleton.COCO17_TO_BODY25)]
    from17 = skeleton.from_partial(coco17, skeleton.COCO17_TO_BODY25, 15, 640, 360)
    np.testing.assert_allclose(from17.xy[:, NECK], (seq.xy[:, 2] + seq.xy[:, 5]) / 2, atol=1e-4)


def test_npz_round_trip_and_bad_files(tmp_path):
    seq = random_sequence(5)
    path = tmp_path / "poses.npz"
    seq.save(path)
    back = PoseSequence.load(path)
    np.testing.assert_array_equal(back.keypoints, seq.keypoints)
    assert (back.fps, back.width, back.height) == (15.0, 640, 360)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["poses.npz"]
    with pytest.raises(DancesynthError, match="does not exist"):
        PoseSequence.load(tmp_path / "missing.npz")
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a numpy file at all")
    with pytest.raises(DancesynthError, match="not a dancesynth pose file"):
        PoseSequence.load(garbage)
    other = tmp_path / "other.npz"
    np.savez(other, keypoints=seq.keypoints)
    with pytest.raises(DancesynthError, match="not a dancesynth pose file"):
        PoseSequence.load(other)
    plain = tmp_path / "plain.npy"
    np.save(plain, seq.keypoints)
    with pytest.raises(DancesynthError, match="not a dancesynth pose file"):
        PoseSequence.load(plain)
    with pytest.raises(DancesynthError, match="Could not write"):
        seq.save(tmp_path / "no" / "such" / "dir.npz")
