"""Person masks: segmented on the person's crop of a real clip, kept near the pose, cached by content."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from dancesynth.core import media
from dancesynth.core.errors import DancesynthError
from dancesynth.core.media import read_frames, write_video
from dancesynth.core.skeleton import JOINT_INDEX, PoseSequence, body_scale
from stage2_video import masks
from stage2_video.framing import person_framing
from stage2_video.masks import Segmenter, cache_masks, frame_mask, person_mask

REAL = Path(__file__).parents[1] / "data" / "real_person"
STANDING = 80  # the tracked man stands on the box, his pose well measured; a second person walks by later


@pytest.fixture(scope="module")
def real() -> tuple[list[np.ndarray], PoseSequence]:
    frames = [f for t, f in enumerate(read_frames(REAL / "sports2d_demo_640x360.mp4")) if t <= STANDING]
    return frames, PoseSequence.load(REAL / "sports2d_demo_640x360.poses.npz")


def test_the_segmenter_finds_a_small_real_person_on_their_crop(real):
    frames, poses = real
    kp, reference = poses.keypoints[STANDING], body_scale(poses)
    segmenter = Segmenter()
    try:
        mask = frame_mask(segmenter, frames[STANDING], kp, reference)
    finally:
        segmenter.close()
    height, width = mask.shape
    present = kp[:, 2] >= 0.05
    on = mask[np.clip(kp[present, 1].astype(int), 0, height - 1), np.clip(kp[present, 0].astype(int), 0, width - 1)]
    torso = [JOINT_INDEX[n] for n in ("Neck", "MidHip")]
    assert mask[kp[torso, 1].astype(int), kp[torso, 0].astype(int)].all()
    assert on.mean() > 0.75  # the joints lie on the segmented person (measured 0.87)
    drawn = person_mask(kp, width, height, reference, 0.0)
    # Tighter than the pose drawn with thick limbs, and nothing far from the pose (the other person, the box).
    assert 0.2 < mask.sum() / drawn.sum() < 1.5
    assert not (mask & ~person_mask(kp, width, height, reference, masks.KEEP_MARGIN)).any()


def test_masks_are_cached_and_keyed_by_the_videos_content(tmp_path, make_poses, monkeypatch):
    poses = make_poses(frames=6)
    frames = [np.full((poses.height, poses.width, 3), 90, np.uint8)] * len(poses)
    video = tmp_path / "a.mp4"
    write_video(video, frames, poses.fps)
    framing = person_framing(poses, 32, 32)
    calls = []
    real_frame_mask = masks.frame_mask
    monkeypatch.setattr(masks, "frame_mask", lambda *a: calls.append(1) or real_frame_mask(*a))
    first = np.array(cache_masks(video, framing, tmp_path, poses))
    assert first.shape == (6, 32, 32) and len(calls) == 6
    assert first.any()  # nobody to segment in a grey video: the pose drawn instead
    renamed = tmp_path / "b.mp4"
    shutil.copy(video, renamed)
    assert np.array_equal(cache_masks(renamed, framing, tmp_path, poses), first) and len(calls) == 6
    write_video(video, [np.full_like(frames[0], 30)] * len(poses), poses.fps)  # new content, same name
    cache_masks(video, framing, tmp_path, poses)
    assert len(calls) == 12


def test_masks_made_in_stretches_side_by_side_are_every_frames(tmp_path, make_poses, monkeypatch):
    poses = make_poses(frames=9)
    video = tmp_path / "a.mp4"
    # Each frame's own shade: a mask written at the wrong index would show it.
    write_video(video, [np.full((poses.height, poses.width, 3), 20 * t, np.uint8) for t in range(9)], poses.fps)
    framing = person_framing(poses, 32, 32)
    for run in ("three", "one", "short"):
        (tmp_path / run).mkdir()
    seen = {}
    real_frame_mask = masks.frame_mask

    def recording(segmenter, frame, keypoints, reference):
        seen[round(frame.mean() / 20)] = keypoints
        return real_frame_mask(segmenter, frame, keypoints, reference)

    monkeypatch.setattr(media, "MIN_STRETCH_FRAMES", 2)
    monkeypatch.setattr(masks, "frame_mask", recording)
    split = np.array(cache_masks(video, framing, tmp_path / "three", poses, workers=3))
    assert sorted(seen) == list(range(9))
    assert len({poses.keypoints[t].tobytes() for t in range(9)}) == 9
    assert all(np.array_equal(seen[t], poses.keypoints[t]) for t in range(9)), "each frame masked with its own pose"
    assert np.array_equal(split, np.array(cache_masks(video, framing, tmp_path / "one", poses, workers=1)))
    short = tmp_path / "short.mp4"
    write_video(short, [np.full((poses.height, poses.width, 3), 90, np.uint8)] * 7, poses.fps)
    with pytest.raises(DancesynthError, match="has 7 frames but the poses have 9"):
        cache_masks(short, framing, tmp_path / "short", poses, workers=3)
