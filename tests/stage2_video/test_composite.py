"""Compositing generated crops into the target's scene, on real footage (tests/data/real_person)."""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from dancesynth.core.checkpoint import update_meta
from dancesynth.core.errors import DancesynthError
from dancesynth.core.media import read_frames
from dancesynth.core.skeleton import JOINT_INDEX, PoseSequence, body_scale
from stage2_video.composite import (
    PLATE_FILE,
    Compositor,
    background_plate,
    cache_plate,
    load_plate,
    scene_compositor,
)
from stage2_video.framing import Framing, person_framing
from stage2_video.masks import person_mask
from stage2_video.synthetic_person import appearance_preset, render_background, render_person
from stage2_video.train import KIND

REAL = Path(__file__).parents[1] / "data" / "real_person"
# The tracked man stands on the box until about frame 190, then jumps down in front of it.
ON_THE_BOX, JUMPED_DOWN = 30, 215


@pytest.fixture(scope="module")
def real() -> tuple[list[np.ndarray], PoseSequence, np.ndarray]:
    """(frames, poses, plate) of the real clip."""
    frames = list(read_frames(REAL / "sports2d_demo_640x360.mp4"))
    poses = PoseSequence.load(REAL / "sports2d_demo_640x360.poses.npz")
    return frames, poses, background_plate(iter(frames), poses)


@pytest.fixture(scope="module")
def compositor(real) -> Compositor:
    _, poses, plate = real
    return Compositor(plate, (poses.width, poses.height), body_scale(poses))


@pytest.fixture(scope="module")
def framing(real) -> Framing:
    return person_framing(real[1], 128, 128)


def body(poses: PoseSequence, t: int) -> np.ndarray:
    """``[H, W]`` bool: the person's own region in frame ``t`` (the pose drawn without margin)."""
    return person_mask(poses.keypoints[t], poses.width, poses.height, body_scale(poses), margin=0.0)


def test_plate_shows_the_scene_without_the_person(real):
    frames, poses, plate = real
    assert plate.shape == (poses.height, poses.width, 3)
    region = body(poses, ON_THE_BOX)
    to_person = np.abs(plate.astype(int) - frames[ON_THE_BOX]).max(axis=2)[region]
    to_scene = np.abs(plate.astype(int) - frames[JUMPED_DOWN]).max(axis=2)[region]
    # Measured: 33.6 grey levels from the person; from the empty scene a mean of 1.6, 99th percentile 10
    # (compression noise and the sun's flicker), so no smeared copy of him is left.
    assert to_person.mean() > 20
    assert to_scene.mean() < 4 and np.percentile(to_scene, 99) < 16


@pytest.mark.parametrize("segment", [False, True])
def test_the_plate_of_a_person_standing_still_most_of_the_time_holds_no_person(segment, make_poses):
    look = appearance_preset("red_tee")
    seq = make_poses(frames=40, width=160, height=120)
    kp = seq.keypoints.copy()
    kp[..., 0] -= 6 * np.sin(np.arange(40) / 3)[:, None] + 30  # still, left of centre...
    kp[36:, :, 0] += 70  # ...for 90 % of the video, then a step to the right
    seq = seq.replace(kp)
    plate = background_plate(render_person(seq, look), seq, segment=segment)
    scene = render_background(seq.width, seq.height, look)
    spot = person_mask(kp[0], seq.width, seq.height, body_scale(seq), 0.1)
    error = np.abs(plate.astype(int) - scene).max(axis=2)
    person = np.abs(next(render_person(seq, look)).astype(int) - scene).max(axis=2)[spot]
    assert person.mean() > 40  # the person differs from the room where they stand
    assert error[spot].mean() < 3 and np.percentile(error[spot], 99) < 12  # no trace of them in the plate


def test_plate_needs_a_frame_for_every_pose(real):
    frames, poses, _ = real
    with pytest.raises(DancesynthError, match="frames"):
        background_plate(iter(frames[:100]), poses)


def test_composite_is_the_scene_with_the_generated_person(real, compositor, framing):
    frames, poses, plate = real
    t = 100
    # A perfect generator's output: the real frame as the model sees it.
    out = compositor.frame(framing.image(frames[t]), poses.keypoints[t], framing)
    assert out.shape == (poses.height, poses.width, 3) and out.dtype == np.uint8
    far = ~person_mask(poses.keypoints[t], poses.width, poses.height, body_scale(poses), margin=1.0)
    assert np.array_equal(out[far], plate[far])
    region = body(poses, t)
    error = np.abs(out.astype(int) - frames[t])[region].mean()
    assert error < 0.5 * np.abs(plate.astype(int) - frames[t])[region].mean()


def test_no_edge_where_the_person_leaves_the_crop_box(real, compositor, framing):
    _, poses, plate = real
    right = framing.x0 + framing.crop_width
    assert right < poses.width  # this box edge lies inside the canvas
    kp = poses.keypoints[100].copy()
    y = 150.0
    kp[JOINT_INDEX["RElbow"]] = (right - 30, y, 1.0)
    kp[JOINT_INDEX["RWrist"]] = (right - 5, y, 1.0)  # the hand reaches across the box's right edge
    magenta = np.zeros((framing.out_height, framing.out_width, 3), np.uint8)
    magenta[:] = (255, 0, 255)  # differs from the scene everywhere: any cut would show
    out = compositor.frame(magenta, kp, framing)
    change = np.abs(out.astype(int) - plate).max(axis=2)
    rows = slice(int(y) - 10, int(y) + 10)
    assert change[rows, right - 16].min() > 80 and change[:, right:].max() == 0
    assert change[rows, right - 1].max() <= 30
    # The generated frame's weight falls to 0 at the edge over about 12 pixels; a cut would drop it from 1 at once.
    x0, y0 = compositor.region(framing)[:2]
    alpha = compositor.alpha(kp, framing)[rows.start - y0:rows.stop - y0, right - 16 - x0:right - x0]
    assert alpha[:, 0].min() > 0.9 and alpha[:, -1].max() < 0.1
    assert np.abs(np.diff(alpha, axis=1)).max() < 0.15


def test_smaller_output_keeps_the_aspect_and_the_placement(real, compositor, framing):
    frames, poses, plate = real
    t = 100
    size = (round(poses.width * 180 / poses.height), 180)
    small = Compositor(plate, size, body_scale(poses))
    generated = framing.image(frames[t])
    out = small.frame(generated, poses.keypoints[t], framing)
    assert out.shape == (180, 320, 3)
    reference = cv2.resize(compositor.frame(generated, poses.keypoints[t], framing), size,
                           interpolation=cv2.INTER_AREA)
    assert np.abs(out.astype(int) - reference).mean() < 3
    skeleton = small.skeleton(poses.keypoints[t])
    assert skeleton.shape == out.shape
    drawn = skeleton.any(axis=2)
    x0, y0, x1, y1 = small.region(framing)
    alpha = np.zeros(drawn.shape, np.float32)
    alpha[y0:y1, x0:x1] = small.alpha(poses.keypoints[t], framing)
    assert drawn.sum() > 50 and (alpha[drawn] > 0.5).mean() > 0.95  # the skeleton lies on the person


def test_training_caches_the_plate(tiny_run, tiny_target):
    video, poses = tiny_target
    plate = load_plate(tiny_run)
    assert plate.shape == (64, 64, 3)
    # Background grey 90, the person drawn on it: the plate is the grey (up to the encoder's colour bleeding).
    error = np.abs(plate.astype(int) - 90)
    assert error.mean() < 2 and error.max() <= 16
    path = tiny_run / PLATE_FILE
    before = path.stat().st_mtime_ns
    cache_plate(video, PoseSequence.load(poses), tiny_run, segment=True)  # as the prior preset trains it
    assert path.stat().st_mtime_ns == before


def test_older_run_gets_its_plate_from_its_video(tiny_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    for name in (PLATE_FILE, PLATE_FILE + ".key"):
        (run / name).unlink()
    compositor = scene_compositor(run, (128, 128))
    assert compositor.plate.shape == (128, 128, 3) and (run / PLATE_FILE).is_file()


def test_older_run_without_its_video_suggests_crop(tiny_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    (run / PLATE_FILE).unlink()
    update_meta(run, KIND, {"video": str(tmp_path / "moved.mp4")})
    with pytest.raises(DancesynthError, match="--crop"):
        load_plate(run)
