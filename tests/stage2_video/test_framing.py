import numpy as np

from dancesynth.core.skeleton import BODY25_COLORS, PoseSequence
from stage2_video.framing import (
    FollowFraming,
    Framing,
    condition,
    follow_framing,
    framing_from_dict,
    label_map,
    label_maps,
    person_framing,
    video_framing,
    whole_canvas,
)


def _pose(cx: float, cy: float, s: float) -> np.ndarray:
    rng = np.random.default_rng(1)
    kp = np.ones((25, 3), np.float32)
    kp[:, :2] = (cx, cy) + rng.uniform(-1, 1, (25, 2)) * (s * 0.4, s)
    return kp


def test_letterbox_pads_instead_of_stretching():
    f = whole_canvas(200, 100, 64, 64)
    assert (f.inner_width, f.inner_height, f.pad_x, f.pad_y) == (64, 32, 0, 16)
    out = f.image(np.full((100, 200, 3), 255, np.uint8))
    assert out.shape == (64, 64, 3)
    assert (out[:16] == 0).all() and (out[48:] == 0).all() and (out[16:48] == 255).all()
    # one uniform scale: a 20x20 square on the canvas stays square
    corners = f.points(np.array([[50.0, 40.0], [70.0, 60.0]]))
    w, h = corners[1] - corners[0]
    assert abs(w - h) < 1e-4


def test_frames_and_points_are_framed_identically():
    f = Framing(x0=300, y0=-20, crop_width=400, crop_height=300, out_width=96, out_height=64)
    frame = np.zeros((480, 640, 3), np.uint8)
    frame[200:210, 500:510] = 255  # a 10x10 dot centred at canvas pixel (504.5, 204.5)
    out = f.image(frame).max(axis=2).astype(float)
    ys, xs = np.nonzero(out)
    centre = np.array([np.average(xs, weights=out[ys, xs]), np.average(ys, weights=out[ys, xs])])
    np.testing.assert_allclose(centre, f.points(np.array([504.5, 204.5])), atol=0.3)
    assert (f.image(frame)[: f.pad_y] == 0).all()
    assert Framing.from_dict(f.to_dict()) == f


def test_person_framing_keeps_the_person_and_the_model_aspect():
    kp = np.stack([_pose(900, 400, 120), _pose(1000, 420, 120)])
    seq = PoseSequence(kp, 15, 1280, 720)
    f = person_framing(seq, 128, 128)
    assert f.crop_width == f.crop_height  # square model image: square crop, no padding needed
    pts = f.points(seq.xy.reshape(-1, 2))
    assert (pts >= 0).all() and (pts < 128).all()
    assert f.crop_width < 720  # zoomed in on the person, not the whole canvas


def test_label_map_is_deterministic_openpose_coloured():
    seq = PoseSequence(np.stack([_pose(64, 64, 40)] * 2), 15, 128, 128)
    f = whole_canvas(128, 128, 64, 64)
    a, b = list(label_maps(seq, f))
    assert a.shape == (64, 64, 3) and a.dtype == np.uint8
    np.testing.assert_array_equal(a, b)
    assert (a > 0).any() and (a[0, 0] == 0).all()
    # pure (unblended) pixels use OpenPose colours
    colours = {tuple(c) for c in BODY25_COLORS}
    pixels = {tuple(p) for p in a.reshape(-1, 3) if p.any()}
    assert pixels & colours
    absent = seq.keypoints[0].copy()
    absent[:, 2] = 0
    assert not label_map(absent, f).any()


def _walk(frames: int = 90, width: int = 1920, height: int = 1080) -> PoseSequence:
    """A 200-px-tall person walking from the left edge to the right edge of a wide canvas."""
    xs = np.linspace(200, width - 200, frames)
    return PoseSequence(np.stack([_pose(x, height / 2, 100) for x in xs]), 30, width, height)


def test_a_person_crossing_the_scene_is_followed_and_fills_the_model_image():
    seq = _walk()
    f = video_framing(seq, 128, 128)
    assert isinstance(f, FollowFraming)
    assert f.crop_height < 2 * 200 * 1.5  # about the person's height, not the path's width
    for t, box in enumerate(f.frames(seq)):
        pts = box.points(seq.xy[t])
        assert (pts >= 0).all() and (pts < 128).all()  # the whole person in the image
        assert np.ptp(pts[:, 1]) > 0.5 * 128  # and large in it
    assert framing_from_dict(f.to_dict()) == f
    # The fixed box for the same walk would shrink the person to a fraction of that.
    fixed = person_framing(seq, 128, 128)
    assert fixed.crop_height > 3 * f.crop_height


def test_frames_without_a_torso_keep_the_box_on_the_path():
    seq = _walk(frames=60)
    kp = seq.keypoints.copy()
    kp[20:30, :, 2] = 0.0  # the person lost for a third of a second
    lost = seq.replace(kp)
    f = follow_framing(seq, 128, 128)
    x0 = np.array([box.x0 for box in f.frames(lost)])
    assert (np.diff(x0) >= 0).all()  # still moving steadily to the right
    np.testing.assert_allclose(x0[20:30], [box.x0 for box in f.frames(seq)][20:30], atol=3)


def test_a_person_dancing_on_the_spot_gets_one_fixed_box():
    kp = np.stack([_pose(900 + 10 * np.sin(t), 400, 120) for t in range(60)])
    seq = PoseSequence(kp, 15, 1280, 720)
    f = video_framing(seq, 128, 128)
    assert isinstance(f, Framing) and f.frames(seq) == [f] * 60
    assert framing_from_dict(f.to_dict()) == f


def test_the_condition_is_the_label_map_then_the_same_crop_of_the_background():
    seq = PoseSequence(np.stack([_pose(300, 200, 60)]), 15, 640, 360)
    f = person_framing(seq, 64, 64)
    plate = np.random.default_rng(0).integers(0, 255, (360, 640, 3), np.uint8)
    cond = condition(seq.keypoints[0], f, plate)
    assert cond.shape == (64, 64, 6)
    np.testing.assert_array_equal(cond[..., :3], label_map(seq.keypoints[0], f))
    np.testing.assert_array_equal(cond[..., 3:], f.image(plate))
    assert condition(seq.keypoints[0], f).shape == (64, 64, 3)  # no plate: the label map alone
    # The crop is remembered for the framing, but never handed out for another plate of that framing.
    for seed in range(6):
        other = np.random.default_rng(seed + 1).integers(0, 255, (360, 640, 3), np.uint8)
        np.testing.assert_array_equal(condition(seq.keypoints[0], f, other)[..., 3:], f.image(other))
