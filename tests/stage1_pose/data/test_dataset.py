"""Dataset layout, manifest validation, splits by song, feature caching and training windows."""

from __future__ import annotations

import json

import numpy as np
import pytest
import soundfile
import torch

from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import PoseSequence
from stage1_pose.data.dataset import DanceDataset, WindowDataset, collate
from stage1_pose.data.layout import Clip, clip_paths, create_layout, split_songs, write_beats, write_manifest
from stage1_pose.models.base import Batch
from stage1_pose.music_features import FEATURE_KINDS, cache_name, feature_dim

SR = 22050


def _tiny_dataset(root, seconds: float = 4.0) -> DanceDataset:
    """Three hand-made clips: clicks at 120 BPM and a figure whose hips move sideways."""
    create_layout(root)
    clips = []
    for i, (style, split) in enumerate([("a", "train"), ("b", "train"), ("a", "val")]):
        cid = f"c{i}"
        n = int(seconds * SR)
        y = np.zeros(n, np.float32)
        for b in np.arange(0.25, seconds, 0.5):
            s = int(b * SR)
            y[s:s + 400] += 0.5 * np.sin(2 * np.pi * 80 * np.arange(400) / SR) * np.exp(-np.arange(400) / 100)
        soundfile.write(root / clip_paths(cid)["audio"], y, SR)
        frames = int(seconds * 15)
        kp = np.ones((frames, 25, 3), np.float32)
        kp[..., 0] = 640 + 50 * np.sin(np.arange(frames) / 5)[:, None] + np.arange(25) * 3 + i
        kp[..., 1] = 300 + np.arange(25) * 10
        PoseSequence(kp, 15, 1280, 720).save(root / clip_paths(cid)["poses"])
        beats = np.arange(0.25, seconds, 0.5)
        write_beats(root / clip_paths(cid)["beats"], beats, beats[::4], 120.0, "exact")
        clips.append(Clip(id=cid, song=f"song{i}", style=style, split=split, **clip_paths(cid)))
    write_manifest(root, 15, SR, ["a", "b"], clips)
    return DanceDataset(root)


def test_manifest_round_trip(tmp_path):
    ds = _tiny_dataset(tmp_path)
    assert ds.styles == ("a", "b") and ds.fps == 15 and ds.sample_rate == SR
    assert [c.id for c in ds.clips("train")] == ["c0", "c1"] and [c.id for c in ds.clips("val")] == ["c2"]
    assert ds.style_index(ds.clips()[1]) == 1
    assert len(ds.load_poses(ds.clips()[0])) == 60
    assert ds.load_audio(ds.clips()[0]).shape == (4 * SR,)
    beats = ds.load_beats(ds.clips()[0])
    assert beats["tempo"] == 120.0 and beats["beats"][0] == pytest.approx(0.25)
    poses = ds.model_poses(ds.clips()[0])
    assert poses.shape == (60, 25, 2) and poses.dtype == np.float32


def test_bad_folders_raise_clear_errors(tmp_path):
    with pytest.raises(DancesynthError, match="does not exist"):
        DanceDataset(tmp_path / "nope")
    with pytest.raises(DancesynthError, match="make-dataset"):
        DanceDataset(tmp_path)
    (tmp_path / "manifest.json").write_text("{not json")
    with pytest.raises(DancesynthError, match="not a valid dataset manifest"):
        DanceDataset(tmp_path)
    (tmp_path / "manifest.json").write_text(json.dumps({"version": 1, "fps": 15, "sample_rate": SR,
                                                        "styles": ["a"], "clips": [{"id": "x"}]}))
    with pytest.raises(DancesynthError, match="not a valid dataset manifest"):
        DanceDataset(tmp_path)


def test_split_songs_is_stratified_and_covers_every_song():
    rng = np.random.default_rng(0)
    songs = {s: [f"{s}{i}" for i in range(10)] for s in ("ballet", "hiphop", "pop")}
    split = split_songs(songs, rng)
    assert sorted(split) == sorted(x for v in songs.values() for x in v)
    counts = {k: sum(v == k for v in split.values()) for k in ("train", "val", "test")}
    assert counts == {"train": 24, "val": 3, "test": 3}
    for held in ("val", "test"):
        assert {song[:-1] for song, s in split.items() if s == held} == set(songs)
    assert set(split_songs({"a": ["x"], "b": ["y", "z"]}, rng).values()) == {"train", "val", "test"}


@pytest.mark.parametrize("kind", FEATURE_KINDS)
def test_window_dataset_shapes_for_every_feature_kind(tmp_path, kind):
    _tiny_dataset(tmp_path)
    train = WindowDataset(tmp_path, "train", kind, 20, 10, progress=False)
    assert len(train) == 2 * 5  # two 60-frame clips, windows at 0, 10, ..., 40
    item = train[3]
    dim = feature_dim(kind, 15)
    assert item["features"].shape == (20, dim) and item["poses"].shape == (20, 25, 2)
    assert item["style"].dtype == torch.int64 and item["start"] == 30
    # The beats file's beats (0.25 s + 0.5 s k) on the window's frames 30..49: seconds 2.25, 2.75, 3.25.
    assert item["beats"].dtype == torch.bool and torch.nonzero(item["beats"]).flatten().tolist() == [4, 11, 19]
    batch = collate([train[0], train[7]])
    assert isinstance(batch, Batch)
    assert batch.features.shape == (2, 20, dim) and batch.poses.shape == (2, 20, 25, 2)
    assert batch.beats.shape == (2, 20) and batch.beats.dtype == torch.bool
    assert batch.style.tolist() == [0, 1]
    assert (tmp_path / "features" / cache_name(kind) / "stats.npz").is_file()
    full = np.concatenate([train.dataset.load_features(c, kind) for c in train.dataset.clips("train")])
    standardized = train.stats.standardize(full)
    assert np.allclose(standardized.mean(0), 0, atol=1e-3)
    assert np.all((np.abs(standardized.std(0) - 1) < 1e-2) | (full.std(0) < 1e-6))
    val = WindowDataset(tmp_path, "val", kind, 60, progress=False)
    assert len(val) == 1 and np.array_equal(val.stats.mean, train.stats.mean)



def test_make_dataset_is_deterministic_and_splits_by_song(tmp_path):
    from stage1_pose.data.make_dataset import make_dataset

    one = DanceDataset(make_dataset(tmp_path / "one", clips=4, seconds=3.0, seed=7, workers=1, progress=False).parent)
    two = DanceDataset(make_dataset(tmp_path / "two", clips=4, seconds=3.0, seed=7, workers=2, progress=False).parent)
    assert one.styles == ("ballet", "hiphop", "pop")
    assert [c.style for c in one.clips()] == ["ballet", "hiphop", "pop", "ballet"]
    assert one.clips() == two.clips()
    for a, b in zip(one.clips(), two.clips()):
        assert np.array_equal(one.load_poses(a).keypoints, two.load_poses(b).keypoints)
        assert np.array_equal(one.load_audio(a), two.load_audio(b))
    song_splits = {}
    for c in one.clips():
        assert song_splits.setdefault(c.song, c.split) == c.split
    assert {c.split for c in one.clips()} == {"train", "val", "test"}
    clip = one.clips()[0]
    assert len(one.load_poses(clip)) == 45 and one.load_audio(clip).shape == (3 * SR,)
    assert one.load_beats(clip)["source"] == "exact"
    other = make_dataset(tmp_path / "other", clips=1, seconds=3.0, seed=8, workers=1, progress=False).parent
    assert not np.array_equal(DanceDataset(other).load_audio(DanceDataset(other).clips()[0]), one.load_audio(clip))


def test_make_dataset_rejects_bad_arguments(tmp_path):
    from stage1_pose.data.make_dataset import make_dataset

    for kwargs, message in (({"clips": 0}, "--clips"), ({"seconds": 0.5}, "--seconds"), ({"workers": 0}, "--workers")):
        with pytest.raises(DancesynthError, match=message):
            make_dataset(tmp_path / "x", **kwargs)
    make_dataset(tmp_path / "y", clips=1, seconds=2.0, workers=1, progress=False)
    with pytest.raises(DancesynthError, match="already holds a dataset"):
        make_dataset(tmp_path / "y", clips=1, seconds=2.0, workers=1)
