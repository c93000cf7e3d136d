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



def _person_on_two_levels() -> PoseSequence:
    """70 frames standing on a box top (ankles at y 400, 300 px tall), then 30 crouching on the ground in front
    (ankles at y 650, 200 px tall): an ankle range that is not perspective depth."""
    still = _walking_person().slice_frames(0, 1).keypoints[0]
    ankle, top = still[[11, 14], 1].mean(), still[:, 1].min()
    shape = (still[:, :2] - [0.0, ankle]) / (ankle - top)  # ankles at 0, head at -1
    kp = np.repeat(still[None], 100, axis=0)
    for frames, ankle_y, height in ((slice(0, 70), 400.0, 300.0), (slice(70, 100), 650.0, 200.0)):
        kp[frames, :, 0] = 640 + shape[:, 0] * height
        kp[frames, :, 1] = ankle_y + shape[:, 1] * height
    return PoseSequence(kp, 15.0, 1280, 720)


def test_a_target_on_two_ground_levels_gets_the_dancer_where_it_usually_stands():
    target = _person_on_two_levels()
    stats = body_stats(target)
    assert stats.far_height > stats.close_height and not stats.has_depth
    dance = _walking_person().slice_frames(0, 1)
    dance = dance.replace(np.repeat(dance.keypoints, 30, axis=0))
    out = fit_normalization(dance, stats).apply(dance)
    ankle = out.xy[:, [11, 14], 1].mean(axis=1)
    # Before, the dancer stood half-way between the levels (y 525), on neither of them.
    np.testing.assert_allclose(ankle, 400.0, atol=2.0)
    np.testing.assert_allclose(ankle - out.xy[:, :, 1].min(axis=1), 300.0, rtol=0.02)


def test_statistics_stored_before_the_usual_place_fall_back_to_the_range_middle():
    stored = body_stats(_person_on_two_levels()).to_dict()
    del stored["usual_y"], stored["usual_height"]
    stats = BodyStats.from_dict(stored)
    assert stats.typical() == ((stats.far_y + stats.close_y) / 2, (stats.far_height + stats.close_height) / 2)
