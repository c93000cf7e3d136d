"""Fixtures shared by the stage-2 training and rendering tests: a tiny target video and a tiny trained run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dancesynth.core.draw import draw_pose
from dancesynth.core.media import write_video
from dancesynth.core.skeleton import PoseSequence

TINY = {"width": 32, "height": 32, "ngf": 8, "n_downsample": 2, "n_blocks": 1, "ndf": 8, "batch_size": 4}


def swaying_poses(frames: int = 24, width: int = 64, height: int = 64) -> PoseSequence:
    """A stick figure swaying left and right, its whole body visible."""
    t = np.arange(frames)[:, None]
    base = np.array([[0, -22], [0, -16], [-6, -16], [-10, -8], [-12, 0], [6, -16], [10, -8], [12, 0], [0, 0],
                     [-4, 0], [-5, 10], [-5, 20], [4, 0], [5, 10], [5, 20], [-1, -23], [1, -23], [-2, -22],
                     [2, -22], [7, 22], [8, 22], [4, 21], [-7, 22], [-8, 22], [-4, 21]], np.float32)
    kp = np.ones((frames, 25, 3), np.float32)
    kp[..., 0] = width / 2 + base[:, 0] + 6 * np.sin(t / 3)
    kp[..., 1] = height / 2 + base[:, 1]
    kp[:, [4, 7], 1] += 6 * np.cos(t / 2)  # waving wrists
    return PoseSequence(kp, 15.0, width, height)


@pytest.fixture(scope="session")
def tiny_config() -> dict:
    """Config overrides for a network small enough to train in a second."""
    return dict(TINY)


@pytest.fixture(scope="session")
def make_poses():
    """:func:`swaying_poses`, for tests that need pose sequences of their own."""
    return swaying_poses


@pytest.fixture(scope="session")
def tiny_target(tmp_path_factory) -> tuple[Path, Path]:
    """(video.mp4, poses.npz): each frame shows the skeleton thickly drawn on a grey background."""
    folder = tmp_path_factory.mktemp("target")
    seq = swaying_poses()
    frames = [draw_pose(np.full((seq.height, seq.width, 3), 90, np.uint8), kp, thickness=3) for kp in seq.keypoints]
    video, poses = folder / "target.mp4", folder / "poses.npz"
    write_video(video, frames, seq.fps)
    seq.save(poses)
    return video, poses


@pytest.fixture(scope="session")
def tiny_run(tiny_target, tmp_path_factory) -> Path:
    """A run folder trained for two steps (enough to have a complete checkpoint)."""
    from stage2_video.train import TrainOptions, train_video
    video, poses = tiny_target
    run = tmp_path_factory.mktemp("run")
    train_video(video, run, "small", TrainOptions(epochs=1, max_steps=2, val_frames=4), poses=poses,
                device="cpu", overrides=TINY)
    return run
