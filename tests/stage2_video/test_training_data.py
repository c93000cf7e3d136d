"""The run folder's frame and pose caches are used only for the video (and framing) they were made from."""

import numpy as np
import pytest

from dancesynth.core.errors import DancesynthError
from dancesynth.core.media import write_video
from stage2_video import training_data
from stage2_video.framing import person_framing
from stage2_video.train import TrainOptions, train_video


def _grey_video(path, level: int, poses):
    write_video(path, [np.full((poses.height, poses.width, 3), level, np.uint8)] * len(poses), poses.fps)
    return path


def _prepare(video, run_dir, poses_file=None):
    """train-video's data preparation: poses (given or cached), then the framed frames."""
    seq = training_data.check_poses_match(training_data.load_or_extract_poses(video, run_dir, poses_file), video)
    return training_data.cache_frames(video, person_framing(seq, 32, 32), run_dir, seq), seq


@pytest.fixture
def two_videos(tmp_path, make_poses):
    poses = make_poses(frames=12)
    poses_file = tmp_path / "given.npz"
    poses.save(poses_file)
    return _grey_video(tmp_path / "a.mp4", 40, poses), _grey_video(tmp_path / "b.mp4", 200, poses), poses_file


def _centre(frames) -> float:
    return float(np.asarray(frames)[:, 16, 16].mean())


def test_another_video_of_the_same_size_in_the_same_run_folder_gets_its_own_frames(tmp_path, two_videos):
    a, b, poses_file = two_videos
    run = tmp_path / "run"
    run.mkdir()
    frames_a, _ = _prepare(a, run, poses_file)
    frames_b, _ = _prepare(b, run, poses_file)
    assert abs(_centre(frames_a) - 40) < 8 and abs(_centre(frames_b) - 200) < 8


def test_cached_poses_serve_only_their_own_video(tmp_path, two_videos, monkeypatch):
    a, b, poses_file = two_videos
    run = tmp_path / "run"
    run.mkdir()
    _prepare(a, run, poses_file)
    extracted = []

    def fake_extract(video, config=None):
        extracted.append(video)
        raise RuntimeError("extraction reached")

    monkeypatch.setattr("stage2_video.extract.extract_poses", fake_extract)
    _prepare(a, run)  # resuming on the same video reads the cache
    assert extracted == []
    with pytest.raises(RuntimeError, match="extraction reached"):
        _prepare(b, run)
    assert extracted == [b]


def test_a_cache_without_its_completion_key_is_rebuilt(tmp_path, two_videos):
    a, _, poses_file = two_videos
    run = tmp_path / "run"
    run.mkdir()
    frames, seq = _prepare(a, run, poses_file)
    path = run / training_data.frames_file(person_framing(seq, 32, 32))
    np.save(path, np.zeros_like(frames))  # as an interrupted rewrite would leave it, before its key
    (run / (path.name + training_data.KEY_SUFFIX)).unlink()
    assert abs(_centre(_prepare(a, run, poses_file)[0]) - 40) < 8


def test_frames_without_a_torso_are_neither_trained_on_nor_scored(tmp_path, two_videos, tiny_config):
    a, _, poses_file = two_videos
    frames, seq = _prepare(a, tmp_path, poses_file)
    kp = seq.keypoints.copy()
    kp[4:7, :, 2] = 0.0  # the estimator lost the person in frames 4-6
    target = training_data.TargetVideo(frames, seq.replace(kp), person_framing(seq, 32, 32))
    pairs = training_data.FramePairs(target, range(0, 12))
    assert pairs.starts == [0, 1, 2, 7, 8, 9, 10]  # no pair touches frames 4-6
    kp[:, :, 2] = 0.0
    seq.replace(kp).save(tmp_path / "lost.npz")
    with pytest.raises(DancesynthError, match="too few"):
        train_video(a, tmp_path / "run", options=TrainOptions(epochs=1), poses=tmp_path / "lost.npz", device="cpu",
                    overrides=tiny_config)


def test_a_cut_short_frames_cache_is_made_again(tmp_path, two_videos):
    a, _, poses_file = two_videos
    run = tmp_path / "run"
    run.mkdir()
    first, _ = _prepare(a, run, poses_file)
    first = np.array(first)
    (cache,) = run.glob("frames_*.npy")
    cache.write_bytes(cache.read_bytes()[: cache.stat().st_size // 2])
    again, _ = _prepare(a, run, poses_file)
    assert np.array_equal(np.asarray(again), first)
