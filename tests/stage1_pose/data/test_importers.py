"""Importers: OpenPose folders and AIST++ keypoint arrays become dataset clips with their songs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile

from dancesynth.core.errors import DancesynthError
from dancesynth.core.openpose_io import save_openpose_folder
from dancesynth.core.skeleton import COCO17_TO_BODY25, PoseSequence
from stage1_pose.beats import SongBeats
from stage1_pose.data import importers
from stage1_pose.data.dataset import DanceDataset
from stage1_pose.data.importers import import_aistpp, import_openpose, load_aistpp_keypoints

SR = 22050


def _song(path, seconds: float = 6.0, bpm: float = 120.0, seed: int = 0):
    """A kick on every beat over a little noise, so the song is neither silent nor beatless."""
    n = int(seconds * SR)
    y = 0.01 * np.random.default_rng(seed).standard_normal(n)
    t = np.arange(int(0.2 * SR)) / SR
    kick = np.sin(2 * np.pi * (50 + 100 * np.exp(-t / 0.03)) * t) * np.exp(-t / 0.08)
    for b in np.arange(0.25, seconds - 0.2, 60 / bpm):
        s = int(b * SR)
        y[s:s + len(kick)] += 0.6 * kick
    soundfile.write(path, y.astype(np.float32), SR)
    return path


def _moving_pose(frames: int, fps: float) -> PoseSequence:
    t = np.arange(frames) / fps
    kp = np.ones((frames, 25, 3), np.float32)
    kp[..., 0] = 600 + 40 * np.sin(2 * np.pi * t)[:, None] + np.arange(25) * 4
    kp[..., 1] = 200 + np.arange(25) * 15
    return PoseSequence(kp, fps, 1280, 720)


def test_openpose_import_round_trip(tmp_path):
    seq = _moving_pose(150, 30.0)  # 5 s at 30 fps
    save_openpose_folder(seq, tmp_path / "take1")
    clip = import_openpose(tmp_path / "take1", _song(tmp_path / "song.wav"), tmp_path / "ds", "salsa",
                           fps=30.0, width=1280, height=720)
    ds = DanceDataset(tmp_path / "ds")
    assert ds.styles == ("salsa",) and [c.id for c in ds.clips()] == ["take1"]
    poses = ds.load_poses(clip)
    assert poses.fps == 15 and len(poses) == 75
    assert np.allclose(poses.xy, seq.xy[::2], atol=0.05)  # OpenPose JSON stores 3 decimals
    assert ds.load_audio(clip).shape == (5 * SR,)
    beats = ds.load_beats(clip)
    assert beats["source"] == "tracked" and abs(beats["tempo"] - 120) < 3
    # a second dance to the same song joins its split; a clash of ids is refused
    save_openpose_folder(seq, tmp_path / "take2")
    second = import_openpose(tmp_path / "take2", tmp_path / "song.wav", tmp_path / "ds", "tango", 30.0, 1280, 720)
    assert second.song == clip.song and second.split == clip.split
    assert DanceDataset(tmp_path / "ds").styles == ("salsa", "tango")
    with pytest.raises(DancesynthError, match="already has a clip"):
        import_openpose(tmp_path / "take1", tmp_path / "song.wav", tmp_path / "ds", "salsa", 30.0, 1280, 720)


def test_aistpp_import_from_npy_and_npz(tmp_path):
    frames = 240  # 4 s at 60 fps
    body = _moving_pose(frames, 60.0).keypoints
    coco = body[:, list(COCO17_TO_BODY25)]
    views = np.stack([coco, coco + 5])
    views[1, 10, 3] = np.nan  # an undetected point
    np.save(tmp_path / "gBR_sBM_cAll_d04_mBR0_ch01.npy", views)
    np.savez(tmp_path / "single.npz", keypoints2d=coco)
    song = _song(tmp_path / "mBR0.wav", seconds=4.0)
    clip = import_aistpp(tmp_path / "gBR_sBM_cAll_d04_mBR0_ch01.npy", song, tmp_path / "ds", split="val")
    assert clip.style == "break" and clip.split == "val"
    poses = DanceDataset(tmp_path / "ds").load_poses(clip)
    assert len(poses) == 60 and poses.fps == 15
    assert np.allclose(poses.xy[:, list(COCO17_TO_BODY25)], coco[::4, :, :2], atol=1e-3)
    assert np.allclose(poses.xy[:, 1], (coco[::4, 5, :2] + coco[::4, 6, :2]) / 2, atol=1e-3)  # neck derived
    assert poses.confidence[:, 19].max() == 0  # feet are absent in COCO-17
    assert load_aistpp_keypoints(tmp_path / "gBR_sBM_cAll_d04_mBR0_ch01.npy", view=1)[10, 3, 2] == 0
    other = import_aistpp(tmp_path / "single.npz", song, tmp_path / "ds", style="break")
    assert other.song == clip.song and other.split == "val"


def test_importer_errors(tmp_path):
    (tmp_path / "x.pkl").write_bytes(b"\x80\x04")
    with pytest.raises(DancesynthError, match="pickle"):
        load_aistpp_keypoints(tmp_path / "x.pkl")
    np.save(tmp_path / "bad.npy", np.zeros((10, 25, 3)))
    with pytest.raises(DancesynthError, match="COCO-17"):
        load_aistpp_keypoints(tmp_path / "bad.npy")
    np.save(tmp_path / "views.npy", np.zeros((2, 10, 17, 3)))
    with pytest.raises(DancesynthError, match="camera views"):
        load_aistpp_keypoints(tmp_path / "views.npy", view=5)
    with pytest.raises(DancesynthError, match="genre"):
        import_aistpp(tmp_path / "views.npy", tmp_path / "none.wav", tmp_path / "ds")
    with pytest.raises(DancesynthError, match="Unknown split"):
        import_aistpp(tmp_path / "views.npy", tmp_path / "none.wav", tmp_path / "ds", style="x", split="dev")


def test_importers_write_the_trackers_downbeats(tmp_path, monkeypatch):
    """The chosen tracker's beats, downbeats and tempo reach beats/<id>.json."""
    calls = []

    def fake(samples, sr, tracker):
        calls.append(tracker)
        return SongBeats(np.array([0.5, 1.0, 1.5, 2.0]), np.array([0.5, 2.0]), 120.0)

    monkeypatch.setattr(importers, "song_beats", fake)
    save_openpose_folder(_moving_pose(90, 30.0), tmp_path / "take")
    clip = import_openpose(tmp_path / "take", _song(tmp_path / "song.wav", 3.0), tmp_path / "ds", "salsa", 30.0,
                           1280, 720, tracker="dsp")
    beats = DanceDataset(tmp_path / "ds").load_beats(clip)
    assert calls == ["dsp"]
    assert list(beats["downbeats"]) == [0.5, 2.0] and beats["tempo"] == 120.0 and beats["source"] == "tracked"


def test_imported_real_song_gets_bars_from_the_learned_tracker(tmp_path):
    """The committed real excerpt (4/4 rock): downbeats every fourth tracked beat."""
    song = Path(__file__).parents[2] / "data" / "real_song" / "escape_from_chaosland_40-65s.ogg"
    save_openpose_folder(_moving_pose(750, 30.0), tmp_path / "take")
    clip = import_openpose(tmp_path / "take", song, tmp_path / "ds", "rock", 30.0, 1280, 720, tracker="learned")
    beats = DanceDataset(tmp_path / "ds").load_beats(clip)
    assert len(beats["downbeats"]) >= 8 and np.all(np.isin(beats["downbeats"], beats["beats"]))
    assert np.all(np.diff(np.searchsorted(beats["beats"], beats["downbeats"])) == 4)

