import numpy as np
import pytest

from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import PoseSequence
from stage2_video.normalize import BodyStats, body_stats, fit_normalization


def _walking_person(frames: int = 120, seed: int = 0) -> PoseSequence:
    """A person moving towards and away from the camera: lower on the canvas means larger."""
    rng = np.random.default_rng(seed)
    base = rng.uniform(-1, 1, (25, 2)).astype(np.float32) * [40, 80]
    base[[11, 14], 1] = 100.0   # ankles at the bottom of the body
    base[0, 1] = -100.0          # nose at the top
    depth = (np.sin(np.linspace(0, 6, frames)) + 1) / 2
    scale = 0.6 + 0.6 * depth
    ankle_y = 300 + 300 * depth
    kp = np.zeros((frames, 25, 3), np.float32)
    kp[..., 0] = 640 + scale[:, None] * base[:, 0] + rng.normal(0, 2, (frames, 25))
    kp[..., 1] = ankle_y[:, None] + scale[:, None] * (base[:, 1] - 100.0)
    kp[..., 2] = 1.0
    return PoseSequence(kp, 15.0, 1280, 720)


def test_identity_for_the_target_itself():
    target = _walking_person()
    out = fit_normalization(target, target).apply(target)
    np.testing.assert_allclose(out.xy, target.xy, atol=1e-3)
    assert (out.width, out.height) == (1280, 720)


def test_scaled_shifted_copy_maps_back_onto_target():
    target = _walking_person()
    kp = target.keypoints.copy()
    kp[..., :2] = kp[..., :2] * 0.5 + [100.0, 40.0]
    source = PoseSequence(kp, 15.0, 800, 600)
    out = fit_normalization(source, target).apply(source)
    np.testing.assert_allclose(out.xy, target.xy, atol=1e-2)
    assert (out.width, out.height) == (target.width, target.height)
    np.testing.assert_array_equal(out.confidence, source.confidence)


def test_stored_statistics_round_trip_and_standing_still():
    target = _walking_person()
    stats = BodyStats.from_dict(body_stats(target).to_dict())
    still = target.slice_frames(0, 1)
    still = still.replace(np.repeat(still.keypoints, 10, axis=0))  # no depth range: one scale for all frames
    out = fit_normalization(still, stats).apply(still)
    assert np.isfinite(out.keypoints).all()
    height = out.xy[0, 11, 1] - out.xy[0, 0, 1]
    assert height == pytest.approx((stats.far_height + stats.close_height) / 2, rel=0.05)


def test_no_visible_body_is_a_user_error():
    seq = _walking_person()
    seq.keypoints[..., 2] = 0.0
    with pytest.raises(DancesynthError, match="ankles and the head"):
        body_stats(seq)


def test_a_dance_on_the_spot_keeps_its_foot_lifts_at_body_scale():
    target = _walking_person()
    still = target.slice_frames(0, 1).keypoints
    dance = np.repeat(still, 60, axis=0)
    lift = 12.0 * np.sin(np.linspace(0, 12, 60))  # the whole body bobs 12 px: foot lifts, not depth
    dance[..., 1] += lift[:, None]
    source = target.replace(dance)
    stats = body_stats(target)
    out = fit_normalization(source, stats).apply(source)
    height = out.xy[:, 11, 1] - out.xy[:, 0, 1]
    scale = float(np.median(height)) / float(np.median(source.xy[:, 11, 1] - source.xy[:, 0, 1]))
    # Before, the 24-px range was mapped onto the target's 270-px depth range: the dancer rose and sank ~270 px.
    assert np.ptp(out.xy[:, 11, 1]) == pytest.approx(scale * np.ptp(lift), rel=0.05)
    assert np.ptp(height) < 0.05 * np.median(height)
    assert float(np.median(out.xy[:, 11, 1])) == pytest.approx((stats.far_y + stats.close_y) / 2, abs=scale * 12)

