"""Synthetic target person: deterministic, person-shaped, follows the pose, writes a video."""

import numpy as np
import pytest

from dancesynth.core import media
from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import JOINT_INDEX, NUM_JOINTS, PoseSequence
from stage2_video import synthetic_person as sp


def figure(width: int, height: int, arm_raise: float = 0.0) -> np.ndarray:
    """``[25, 3]`` upright figure; ``arm_raise`` (0..1) lifts the right arm above the head."""
    cx = width / 2
    points = {
        "Nose": (cx, .16), "Neck": (cx, .26),
        "RShoulder": (cx - .09 * width, .27), "LShoulder": (cx + .09 * width, .27),
        "RElbow": (cx - .14 * width, .40 - arm_raise * .25), "RWrist": (cx - .16 * width, .53 - arm_raise * .5),
        "LElbow": (cx + .14 * width, .40), "LWrist": (cx + .15 * width, .53), "MidHip": (cx, .55),
        "RHip": (cx - .05 * width, .55), "LHip": (cx + .05 * width, .55), "RKnee": (cx - .06 * width, .72),
        "RAnkle": (cx - .06 * width, .89), "LKnee": (cx + .06 * width, .72), "LAnkle": (cx + .06 * width, .89),
        "REye": (cx - .015 * width, .15), "LEye": (cx + .015 * width, .15), "REar": (cx - .03 * width, .16),
        "LEar": (cx + .03 * width, .16), "LBigToe": (cx + .09 * width, .92), "LHeel": (cx + .055 * width, .91),
        "RBigToe": (cx - .09 * width, .92), "RHeel": (cx - .055 * width, .91),
    }
    kp = np.zeros((NUM_JOINTS, 3), np.float32)
    for name, (x, y) in points.items():
        kp[JOINT_INDEX[name]] = (x, y * height, 0.9)
    return kp


def sequence(frames: int = 4, size: int = 128) -> PoseSequence:
    return PoseSequence(np.stack([figure(size, size, (i % 2) * 1.0) for i in range(frames)]), 15.0, size, size)


def test_person_is_drawn_where_the_pose_is():
    look = sp.appearance_preset("red_tee")
    seq = sequence()
    frames = list(sp.render_person(seq, look))
    assert len(frames) == 4 and frames[0].shape == (128, 128, 3) and frames[0].dtype == np.uint8
    empty = sp.render_background(128, 128, look)
    person = np.abs(frames[0].astype(float) - empty).sum(axis=2) > 30
    ys, xs = np.nonzero(person)
    kp = seq.keypoints[0]
    assert xs.min() < kp[JOINT_INDEX["RWrist"], 0] and xs.max() > kp[JOINT_INDEX["LWrist"], 0]
    assert ys.min() < kp[JOINT_INDEX["Nose"], 1] - 3 and ys.max() >= kp[JOINT_INDEX["RAnkle"], 1]
    chest = kp[[JOINT_INDEX["Neck"], JOINT_INDEX["MidHip"]], :2].mean(axis=0).round().astype(int)
    shirt = frames[0][chest[1], chest[0]].astype(int)
    assert np.abs(shirt - look.shirt).max() < 50  # the torso wears the shirt colour
    assert person[:4].sum() == 0 and person[:, :25].sum() == 0  # far from the body the room is untouched
    raised = frames[1].astype(int)
    above_head = (int(kp[JOINT_INDEX["RWrist"], 0]), int(128 * .05))
    assert np.abs(raised[above_head[1]:above_head[1] + 8, above_head[0] - 4:above_head[0] + 4] - empty[
        above_head[1]:above_head[1] + 8, above_head[0] - 4:above_head[0] + 4]).max() > 30  # the raised hand


def test_deterministic_and_appearances_differ():
    seq = sequence(2)
    a = list(sp.render_person(seq, sp.PersonAppearance()))
    b = list(sp.render_person(seq, sp.PersonAppearance()))
    np.testing.assert_array_equal(a[0], b[0])
    assert np.abs(a[1].astype(int) - a[0]).max() > 50  # a different pose gives a different picture
    other = next(sp.render_person(seq, sp.appearance_preset("green_hoodie")))
    assert np.abs(other.astype(int) - a[0]).mean() > 10


def test_missing_joints_and_other_sizes():
    seq = sequence(1)
    seq.keypoints[0, JOINT_INDEX["LElbow"], 2] = 0.0
    seq.keypoints[0, JOINT_INDEX["RShoulder"], 2] = 0.0
    frame = next(sp.render_person(seq, sp.PersonAppearance(), size=(96, 64)))
    assert frame.shape == (64, 96, 3)
    nobody = PoseSequence(np.zeros((1, NUM_JOINTS, 3)), 15.0, 64, 64)
    np.testing.assert_allclose(next(sp.render_person(nobody, sp.PersonAppearance())),
                               sp.render_background(64, 64, sp.PersonAppearance()), atol=1)


def test_appearance_dict_round_trip_and_errors():
    look = sp.appearance_preset("yellow_shorts")
    assert sp.PersonAppearance.from_dict(look.to_dict()) == look
    with pytest.raises(DancesynthError, match="Unknown appearance preset"):
        sp.appearance_preset("clown")
    with pytest.raises(DancesynthError, match="Unknown appearance settings"):
        sp.PersonAppearance.from_dict({"hat": True})


def test_one_frame_per_pose_and_a_video_with_its_sound(tmp_path):
    """(Its speed: ``benchmarks/bench_render.py --synthetic-person``.)"""
    frames = list(sp.render_person(sequence(3, size=256), sp.PersonAppearance()))
    assert len(frames) == 3 and all(f.shape == (256, 256, 3) and f.dtype == np.uint8 for f in frames)
    path = tmp_path / "person.mp4"
    sp.write_person_video(sequence(6), path, sp.PersonAppearance(), audio=np.full(4000, 0.1, np.float32),
                          audio_sr=8000)
    streams = media.probe_streams(path)
    assert streams["video_frames"] == 6 and abs(streams["audio_duration"] - 0.4) <= 1 / 15
