"""`dancesynth prepare`: a folder of dance videos with soundtracks -> a stage-1 dataset a trainer can read."""

from pathlib import Path

import cv2
import numpy as np
import pytest
import skimage.data

from apps.cli import main
from apps.prepare import clip_bounds, find_videos, prepare_videos
from dancesynth.core.errors import DancesynthError
from dancesynth.core.media import write_video
from dancesynth.core.skeleton import JOINT_INDEX, PoseSequence
from stage1_pose.data.dataset import DanceDataset
from stage1_pose.data.layout import read_manifest

SR = 22050


def click_song(seconds: float, bpm: float = 120.0) -> np.ndarray:
    """A click on every beat over a quiet hum: audible, with obvious beats."""
    t = np.arange(int(seconds * SR)) / SR
    song = 0.02 * np.sin(2 * np.pi * 220 * t)
    for beat in np.arange(0, seconds, 60 / bpm):
        k = int(beat * SR)
        n = min(800, len(song) - k)
        song[k:k + n] += 0.5 * np.sin(np.arange(n) * 0.4) * np.exp(-np.arange(n) / 150)
    return song.astype(np.float32)


def astronaut_video(path: Path, seconds: float, fps: float = 10.0, sound: bool = True, person: bool = True) -> Path:
    """The astronaut photo (a real person) sliding across a grey canvas, with a click track."""
    photo = cv2.resize(skimage.data.astronaut(), (200, 200), interpolation=cv2.INTER_AREA)
    frames = []
    for i in range(int(seconds * fps)):
        canvas = np.full((300, 360, 3), 90, np.uint8)
        if person:
            x = 20 + int(100 * i / (seconds * fps))
            canvas[40:240, x:x + 200] = photo
        frames.append(canvas)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_video(path, frames, fps, audio=click_song(seconds) if sound else None, audio_sr=SR if sound else None)
    return path


def test_real_videos_become_a_dataset_with_styles_from_folders(tmp_path, capsys):
    videos = tmp_path / "videos"
    astronaut_video(videos / "salsa" / "take1.mp4", 4.0)
    astronaut_video(videos / "tango" / "silent.mp4", 3.0, sound=False)
    astronaut_video(videos / "tango" / "empty_room.mp4", 3.0, person=False)
    out = tmp_path / "data"
    assert main(["prepare", str(videos), "--out", str(out), "--clip-seconds", "2"]) == 0
    printed = capsys.readouterr().err
    assert "silent.mp4: " in printed and "no audio stream" in printed
    assert "empty_room.mp4: " in printed and "No person" in printed
    manifest = read_manifest(out)
    assert [c.id for c in manifest.clips] == ["salsa_take1_000", "salsa_take1_001"]
    assert list(manifest.styles) == ["salsa"] and manifest.fps == 15.0
    assert len({c.split for c in manifest.clips}) == 1 and len({c.song for c in manifest.clips}) == 1
    poses = PoseSequence.load(out / manifest.clips[1].poses)
    # 20 video frames at 10 fps span 1.9 s: 29 frames at 15 fps.
    assert len(poses) == 29 and (poses.width, poses.height) == (360, 300)
    # The second clip starts 2 s in: the photo has slid 50 px right, and the nose follows it.
    nose = poses.keypoints[:, JOINT_INDEX["Nose"]]
    expected_x = 20 + 100 * (2 + np.arange(29) / 15) / 4 + 223 * 200 / 512
    assert np.abs(nose[:, 0] - expected_x).max() < 12 and (nose[:, 2] > 0).all()
    # Tracked beats of the 120-BPM click track, and a dataset the trainer's reader accepts.
    dataset = DanceDataset(out)
    beats = np.asarray(dataset.load_beats(dataset.clips()[0])["beats"])
    assert len(beats) >= 3 and np.allclose(np.diff(beats), 0.5, atol=0.05)
    # Re-running adds nothing and keeps the dataset as it was.
    main(["prepare", str(videos), "--out", str(out), "--clip-seconds", "2"])
    assert "added 0 clips (2 were there already)" in capsys.readouterr().err
    assert len(read_manifest(out).clips) == 2


def fake_dancer(video: Path) -> PoseSequence:
    """Stand-in extractor (no BlazePose): a pose per frame at 30 fps for 5 s."""
    kp = np.ones((150, 25, 3), np.float32)
    kp[..., :2] = np.random.default_rng(len(video.name)).uniform(100, 500, (150, 25, 2))
    return PoseSequence(kp, 30.0, 640, 480)


def test_clips_of_one_video_share_a_split_and_new_videos_are_added(tmp_path, monkeypatch):
    videos = tmp_path / "videos"
    monkeypatch.setattr("apps.prepare.load_song", lambda path, sr: click_song(5.0))
    for name in ("a.mp4", "b.mov"):
        (videos / "hiphop").mkdir(parents=True, exist_ok=True)
        (videos / "hiphop" / name).write_bytes(b"stand-in, never decoded")
    report = prepare_videos(videos, tmp_path / "data", clip_seconds=2.5, extract=fake_dancer, progress=False)
    assert len(report.added) == 4 and not report.skipped
    clips = read_manifest(tmp_path / "data").clips
    for video in ("a", "b"):
        mine = [c for c in clips if c.id.startswith(f"hiphop_{video}_")]
        assert len(mine) == 2 and len({(c.split, c.song) for c in mine}) == 1
    (videos / "ballet").mkdir()
    (videos / "ballet" / "c.mp4").write_bytes(b"stand-in")
    report = prepare_videos(videos, tmp_path / "data", clip_seconds=2.5, extract=fake_dancer, progress=False)
    assert len(report.added) == 2 and len(report.already_there) == 4
    assert list(read_manifest(tmp_path / "data").styles) == ["hiphop", "ballet"]


def test_videos_and_clip_lengths(tmp_path):
    (tmp_path / "v" / "salsa").mkdir(parents=True)
    for name in ("v/salsa/x.MP4", "v/y.webm", "v/notes.txt"):
        (tmp_path / name).write_bytes(b"")
    assert find_videos(tmp_path / "v", "dance") == [(tmp_path / "v" / "salsa" / "x.MP4", "salsa"),
                                                    (tmp_path / "v" / "y.webm", "dance")]
    assert clip_bounds(150.0, 60.0) == [(0.0, 75.0), (75.0, 150.0)]
    assert clip_bounds(20.0, 60.0) == [(0.0, 20.0)]


def test_unusable_folders_give_clear_errors(tmp_path, capsys):
    assert main(["prepare", str(tmp_path / "missing"), "--out", str(tmp_path / "d")]) == 1
    assert "is not a folder" in capsys.readouterr().err
    (tmp_path / "empty").mkdir()
    with pytest.raises(DancesynthError, match="holds no videos"):
        find_videos(tmp_path / "empty", "dance")
    astronaut_video(tmp_path / "mute" / "a.mp4", 2.0, sound=False)
    assert main(["prepare", str(tmp_path / "mute"), "--out", str(tmp_path / "d")]) == 1
    assert "None of the videos" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()
