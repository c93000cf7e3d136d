"""Temporal clean-up of extracted poses: spikes and smoothing."""

import numpy as np
import pytest

from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import JOINT_INDEX, PoseSequence, interpolate_missing
from stage2_video.smoothing import SmoothingConfig, despike, smooth

FPS = 30.0


def noisy_walk(seed: int = 0, frames: int = 90) -> tuple[PoseSequence, np.ndarray]:
    """Every joint moves on a smooth curve (pixels) plus 3 px Gaussian jitter; returns (noisy, clean xy)."""
    t = np.arange(frames) / FPS
    clean = np.zeros((frames, 25, 2))
    clean[..., 0] = 200 + 80 * np.sin(2 * np.pi * 0.5 * t)[:, None] + np.arange(25) * 4
    clean[..., 1] = 150 + 40 * np.cos(2 * np.pi * 0.3 * t)[:, None]
    noise = np.random.default_rng(seed).normal(0, 3, clean.shape)
    kp = np.concatenate([clean + noise, np.ones((frames, 25, 1))], axis=-1)
    return PoseSequence(kp, FPS, 480, 360), clean


# Savitzky-Golay has no lag, so it also gets closer to the clean curve; One-Euro trades its lag for less
# jitter and must at least not end up much farther from the curve than the raw input.
@pytest.mark.parametrize("method, max_error_ratio", [("savgol", 0.8), ("one-euro", 1.1)])
def test_smoothing_removes_jitter_but_keeps_motion(method, max_error_ratio):
    seq, clean = noisy_walk()
    out = smooth(seq, SmoothingConfig(method))
    assert out.keypoints.shape == seq.keypoints.shape and (out.fps, out.width, out.height) == (FPS, 480, 360)
    before = np.abs(seq.xy - clean).mean()
    after = np.abs(out.xy - clean).mean()
    assert after < max_error_ratio * before
    # Frame-to-frame jitter (second difference) drops a lot while the 160 px swing survives.
    assert np.abs(np.diff(out.xy, 2, axis=0)).mean() < 0.6 * np.abs(np.diff(seq.xy, 2, axis=0)).mean()
    assert np.ptp(out.xy[:, 0, 0]) > 150


def test_absent_joints_are_left_alone_and_none_is_identity():
    seq, _ = noisy_walk(frames=40)
    kp = seq.keypoints.copy()
    kp[10:20, 3, 2] = 0
    kp[10:20, 3, :2] = -1
    seq = seq.replace(kp)
    for method in ("savgol", "one-euro"):
        out = smooth(seq, SmoothingConfig(method))
        np.testing.assert_array_equal(out.keypoints[10:20, 3], kp[10:20, 3])
        np.testing.assert_array_equal(out.confidence, seq.confidence)
    np.testing.assert_array_equal(smooth(seq, SmoothingConfig("none")).keypoints, kp)


def test_bad_smoothing_options_raise_clear_errors():
    with pytest.raises(DancesynthError, match="Unknown smoothing 'gauss'"):
        SmoothingConfig("gauss")
    with pytest.raises(DancesynthError, match="must be positive"):
        SmoothingConfig("one-euro", min_cutoff_hz=0)
    with pytest.raises(DancesynthError, match="must be positive"):
        SmoothingConfig(spike_window_s=-0.1)


def arm_circles(frames: int = 60, hz: float = 1.5, radius: float = 80.0) -> PoseSequence:
    """A person standing still (torso 100 px, arms out to each side) whose wrists circle at ``hz`` with ``radius``
    pixels: fast, smooth motion."""
    kp = np.zeros((frames, 25, 3))
    for name, (x, y) in {"Neck": (240, 100), "MidHip": (240, 200), "RShoulder": (215, 100), "LShoulder": (265, 100),
                         "RElbow": (170, 110), "LElbow": (310, 110), "RHip": (225, 200), "LHip": (255, 200),
                         "RKnee": (225, 260), "LKnee": (255, 260), "RAnkle": (225, 320), "LAnkle": (255, 320)}.items():
        kp[:, JOINT_INDEX[name]] = (x, y, 1.0)
    angle = 2 * np.pi * hz * np.arange(frames) / FPS
    for name, x in (("RWrist", 120), ("LWrist", 360)):
        kp[:, JOINT_INDEX[name]] = np.c_[x + radius * np.cos(angle), 110 + radius * np.sin(angle), np.ones(frames)]
    return PoseSequence(kp, FPS, 480, 360)


def test_despike_keeps_fast_smooth_motion():
    seq = arm_circles()
    np.testing.assert_array_equal(despike(seq, SmoothingConfig()).keypoints, seq.keypoints)


def test_despike_swaps_back_arms_the_estimator_swapped():
    seq = arm_circles()
    kp = seq.keypoints.copy()
    right, left = [JOINT_INDEX[n] for n in ("RShoulder", "RElbow", "RWrist")], [
        JOINT_INDEX[n] for n in ("LShoulder", "LElbow", "LWrist")]
    kp[30:32, right + left] = seq.keypoints[30:32, left + right]
    np.testing.assert_array_equal(despike(seq.replace(kp), SmoothingConfig()).keypoints, seq.keypoints)


def test_despike_drops_a_wrist_that_leaps_away_and_back_and_gap_filling_puts_it_near_its_path():
    seq = arm_circles()
    wrist = JOINT_INDEX["RWrist"]
    kp = seq.keypoints.copy()
    kp[20:23, wrist, :2] = (230, 190)  # on the hip for three frames, as BlazePose sometimes puts an arm
    out = despike(seq.replace(kp), SmoothingConfig())
    dropped = np.argwhere((out.confidence == 0) & (seq.confidence > 0))
    assert dropped.tolist() == [[20, wrist], [21, wrist], [22, wrist]]
    filled = interpolate_missing(out)
    assert np.linalg.norm(filled.xy[20:23, wrist] - seq.xy[20:23, wrist], axis=-1).max() < 0.3 * 100
    # Off, nothing changes.
    np.testing.assert_array_equal(despike(seq.replace(kp), SmoothingConfig(spike_window_s=0)).keypoints, kp)
