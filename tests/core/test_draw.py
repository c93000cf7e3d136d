"""Skeleton drawing: colours where the limbs are, absent joints skipped, scaled previews, preview video."""

import numpy as np

from dancesynth.core import draw, media
from dancesynth.core.skeleton import BODY25_COLORS, JOINT_INDEX, NUM_JOINTS, PoseSequence


def standing_pose(width: int, height: int) -> np.ndarray:
    """A ``[25, 3]`` upright figure filling the middle of a ``width`` x ``height`` canvas."""
    cx, h = width / 2, height
    points = {
        "Nose": (cx, 0.15 * h), "Neck": (cx, 0.25 * h), "RShoulder": (cx - 0.1 * width, 0.25 * h),
        "RElbow": (cx - 0.15 * width, 0.4 * h), "RWrist": (cx - 0.17 * width, 0.55 * h),
        "LShoulder": (cx + 0.1 * width, 0.25 * h), "LElbow": (cx + 0.15 * width, 0.4 * h),
        "LWrist": (cx + 0.17 * width, 0.55 * h), "MidHip": (cx, 0.55 * h), "RHip": (cx - 0.06 * width, 0.55 * h),
        "RKnee": (cx - 0.07 * width, 0.72 * h), "RAnkle": (cx - 0.07 * width, 0.9 * h),
        "LHip": (cx + 0.06 * width, 0.55 * h), "LKnee": (cx + 0.07 * width, 0.72 * h),
        "LAnkle": (cx + 0.07 * width, 0.9 * h),
    }
    kp = np.zeros((NUM_JOINTS, 3), np.float32)
    for name, (x, y) in points.items():
        kp[JOINT_INDEX[name]] = (x, y, 0.9)
    return kp


def test_draw_pose_colours_limbs_and_skips_absent_joints():
    kp = standing_pose(200, 200)
    image = draw.draw_pose(np.zeros((200, 200, 3), np.uint8), kp)
    assert image.any()
    mid_torso = ((kp[1, :2] + kp[8, :2]) / 2).round().astype(int)
    assert tuple(image[mid_torso[1], mid_torso[0]]) == BODY25_COLORS[8]  # Neck->MidHip limb takes MidHip's colour
    assert not image[:, :20].any() and not image[195:].any()  # nothing outside the figure
    kp_missing = kp.copy()
    kp_missing[JOINT_INDEX["RWrist"], 2] = 0.0
    missing = draw.draw_pose(np.zeros((200, 200, 3), np.uint8), kp_missing)
    wrist = kp[JOINT_INDEX["RWrist"], :2].round().astype(int)
    assert image[wrist[1], wrist[0]].any() and not missing[wrist[1], wrist[0]].any()


def test_line_width_scales_with_image():
    assert draw.line_width(120, 120) == 1 and draw.line_width(720, 1280) == 6
    small = draw.draw_pose(np.zeros((120, 120, 3), np.uint8), standing_pose(120, 120))
    large = draw.draw_pose(np.zeros((480, 480, 3), np.uint8), standing_pose(480, 480))
    small_ink = (small.any(axis=2).mean())
    large_ink = (large.any(axis=2).mean())
    assert 0.5 < large_ink / small_ink < 2.0  # same share of the picture at 4x the resolution


def test_draw_pose_survives_wild_coordinates():
    """A joint at NaN is drawn as an absent one; a joint a billion pixels away draws its limb from its neighbour
    off the canvas towards it; nothing else changes."""
    kp = standing_pose(64, 64)
    nose, elbow, neck = JOINT_INDEX["Nose"], JOINT_INDEX["RElbow"], kp[JOINT_INDEX["Neck"], :2]
    wild, tame = kp.copy(), kp.copy()
    wild[nose, :2], wild[elbow, :2] = (1e9, -1e9), np.nan
    tame[[nose, elbow], 2] = 0.0
    canvas = np.zeros((64, 64, 3), np.uint8)
    assert draw.draw_pose(canvas, wild) is canvas
    changed = (canvas != draw.draw_pose(np.zeros_like(canvas), tame)).any(axis=2)
    ys, xs = np.nonzero(changed)
    # Only the Neck->Nose limb: up and right from the neck, leaving the top edge where the line to the nose,
    # clipped to 4 canvases away (256, -256), crosses it.
    assert (ys <= neck[1] + 2).all() and (xs >= neck[0] - 2).all()
    top_x = neck[0] + neck[1] * (256 - neck[0]) / (neck[1] + 256)
    assert changed[0, round(top_x) - 2:round(top_x) + 3].any()


def test_skeleton_frames_keep_aspect_ratio_and_write_video(tmp_path):
    seq = PoseSequence(np.stack([standing_pose(320, 180)] * 6), 15.0, 320, 180)
    frames = list(draw.skeleton_frames(seq, 100, 100))
    assert len(frames) == 6 and frames[0].shape == (100, 100, 3)
    assert not frames[0][:21].any() and not frames[0][-21:].any()  # letterbox bars of (100 - 56) / 2 rows
    only_width = next(draw.skeleton_frames(seq, width=160))
    assert only_width.shape == (90, 160, 3)
    path = tmp_path / "skeleton.mp4"
    draw.write_skeleton_video(seq, path, audio=np.zeros(22050, np.float32) + 0.1, audio_sr=22050, size=(96, 64))
    streams = media.probe_streams(path)
    assert streams["video_frames"] == 6 and abs(streams["audio_duration"] - 0.4) <= 1 / 15


def test_grid_frames_tile_labelled_dances_and_flash_on_beats(tmp_path):
    seq = PoseSequence(np.stack([standing_pose(320, 180)] * 8), 15.0, 320, 180)
    labels = ["real dances", "lstm", "a model folder with a very long name indeed", "mean pose (frozen)"]
    frames = list(draw.grid_frames([seq] * 4, labels, beats=np.array([0.2]), columns=3, width=640))
    assert len(frames) == 8 and frames[0].shape == (240, 636, 3)  # 2 rows x 3 columns of 212 x 120 tiles
    tiles = [frames[0][r * 120:(r + 1) * 120, c * 212:(c + 1) * 212] for r in range(2) for c in range(3)]
    # Labels are the only pure white in a frame between beats; the two empty tiles of the last row stay black.
    labelled = [bool((tile[:30] == 255).all(axis=2).any()) for tile in tiles]
    assert labelled == [True, True, True, True, False, False]
    assert not tiles[4].any() and not tiles[5].any()
    # The beat at 0.2 s = frame 3 flashes frames 3 and 4: a bright border round every dance's tile.
    edge = np.zeros((240, 636), bool)
    for k in range(4):
        edge[(k // 3) * 120 + 60, (k % 3) * 212:(k % 3) * 212 + 3] = True  # the left border, away from the label
    flashing = [bool(frame[edge].mean() > 200) for frame in frames]
    assert flashing == [False, False, False, True, True, False, False, False]
    np.testing.assert_array_equal(frames[2], frames[5])
    path = tmp_path / "grid.mp4"
    draw.write_grid_video([seq] * 2, labels[:2], path, beats=np.array([0.2]), audio=np.full(22050, 0.1, np.float32),
                          audio_sr=22050, width=400)
    streams = media.probe_streams(path)
    assert streams["video_frames"] == 8 and abs(streams["audio_duration"] - 8 / 15) <= 1 / 15
    assert media.probe_video(path).width == 400
