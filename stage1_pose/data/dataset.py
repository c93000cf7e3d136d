"""The dataset folder layout, its manifest, cached audio features and fixed-length training windows.

Layout of a dataset folder ``DIR``::

    DIR/manifest.json            {"version": 1, "fps": 15.0, "sample_rate": 22050, "styles": [...], "clips": [...]}
    DIR/audio/<id>.wav           the clip's song, mono
    DIR/poses/<id>.npz           its dance, a PoseSequence file (BODY_25 pixels + confidence, fps, canvas)
    DIR/beats/<id>.json          {"beats": [seconds], "downbeats": [seconds], "tempo": bpm, "source": "exact"|"tracked"}
    DIR/features/<kind>/<id>.npy cached music features [T, D] (one row per pose frame), made on first use
    DIR/features/<kind>/stats.npz per-column mean and std over the train split

where ``<kind>`` carries the recipe's version (:func:`stage1_pose.music_features.cache_name`, e.g. ``waveform-v2``).

Each manifest clip is ``{"id", "song", "style", "split", "audio", "poses", "beats"}`` with paths relative to
``DIR``. ``split`` is ``train``, ``val`` or ``test`` and is decided per ``song``, so no song is in two splits.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path
from dancesynth.core.progress import track
from dancesynth.core.skeleton import PoseSequence, interpolate_missing, normalize
from stage1_pose.beats import beats_on_frames

# The layout helpers are part of this module's interface too (generators and importers use layout directly).
from stage1_pose.data.layout import (
    MANIFEST,
    SPLITS,
    Clip,
    Manifest,
    clip_paths,
    create_layout,
    read_manifest,
    split_songs,
    write_beats,
    write_manifest,
)
from stage1_pose.models.base import Batch
from stage1_pose.music_features import cache_name, check_kind, extract_features

__all__ = ["MANIFEST", "SPLITS", "Clip", "DanceDataset", "FeatureStats", "Manifest", "WindowDataset", "clip_paths",
           "collate", "create_layout", "load_feature_stats", "read_manifest", "split_songs", "write_beats",
           "write_manifest"]
# Columns whose spread over the train split is below this are left unscaled instead of blown up.
_MIN_STD = 1e-6


class DanceDataset:
    """A dataset folder (see the module docstring for the layout), read and validated on construction.

    Attributes:
        root: the folder.
        fps: pose frame rate of every clip.
        sample_rate: sample rate of the stored WAV files, in Hz.
        styles: style names; a clip's style label is its index in this list.
    """

    def __init__(self, root: str | os.PathLike) -> None:
        self.root = Path(root)
        manifest = read_manifest(self.root)
        self.fps, self.sample_rate, self.styles = manifest.fps, manifest.sample_rate, manifest.styles
        self._clips = list(manifest.clips)

    def clips(self, split: str | None = None) -> list[Clip]:
        """The clips of ``split`` (``train``, ``val``, ``test``), or all clips when ``split`` is None."""
        if split is not None and split not in SPLITS:
            raise DancesynthError(f"Unknown split {split!r}; choose one of {', '.join(SPLITS)}.")
        return [c for c in self._clips if split is None or c.split == split]

    def style_index(self, clip: Clip) -> int:
        """The integer style label of ``clip``."""
        return self.styles.index(clip.style)

    def _file(self, clip: Clip, rel: str) -> Path:
        path = self.root / rel
        if not path.is_file():
            raise DancesynthError(f"{path} of clip {clip.id} is missing; restore it or re-create the dataset.")
        return path

    def load_poses(self, clip: Clip) -> PoseSequence:
        """The clip's dance as a PoseSequence (pixels)."""
        return PoseSequence.load(self._file(clip, clip.poses))

    def model_poses(self, clip: Clip) -> np.ndarray:
        """``[T, 25, 2]`` float32 model coordinates: absent joints filled in time, then ``skeleton.normalize``."""
        return normalize(interpolate_missing(self.load_poses(clip)))[0]

    def load_audio(self, clip: Clip, sr: int | None = None) -> np.ndarray:
        """The clip's song as mono float32 ``[N]`` samples at ``sr`` Hz (default: the stored rate)."""
        from dancesynth.core.media import decode_audio

        return decode_audio(self._file(clip, clip.audio), sr or self.sample_rate)

    def load_beats(self, clip: Clip) -> dict:
        """The clip's beats file: ``beats`` and ``downbeats`` as float64 arrays of seconds, ``tempo`` in BPM,
        ``source`` (``exact`` for synthetic songs, ``tracked`` for imported ones)."""
        data = json.loads(self._file(clip, clip.beats).read_text())
        return {"beats": np.asarray(data["beats"], np.float64), "downbeats": np.asarray(data["downbeats"], np.float64),
                "tempo": float(data["tempo"]), "source": str(data["source"])}

    def feature_dir(self, kind: str) -> Path:
        """The folder of the cached ``kind`` features and their statistics (named by the recipe's version)."""
        return self.root / "features" / cache_name(kind)

    def feature_path(self, clip: Clip, kind: str) -> Path:
        """Where the cached ``kind`` features of ``clip`` live."""
        return self.feature_dir(kind) / f"{clip.id}.npy"

    def ensure_features(self, kind: str, clips: Sequence[Clip] | None = None, progress: bool = True) -> None:
        """Compute and cache the ``kind`` features (:func:`stage1_pose.music_features.extract_features`) of every clip
        (default: all) that has none yet, with a progress bar."""
        check_kind(kind)
        todo = [c for c in (self._clips if clips is None else clips) if not self.feature_path(c, kind).is_file()]
        if not todo:
            return
        self.feature_dir(kind).mkdir(parents=True, exist_ok=True)
        for clip in track(todo, desc=f"features {kind}", unit="clip", disable=not progress):
            feats = extract_features(self.load_audio(clip), self.sample_rate, kind, self.fps)
            with atomic_path(self.feature_path(clip, kind)) as tmp:
                np.save(tmp, feats)

    def load_features(self, clip: Clip, kind: str) -> np.ndarray:
        """Cached ``[T, D]`` float32 features of ``clip`` (memory-mapped; computed first if missing)."""
        self.ensure_features(kind, [clip], progress=False)
        return np.load(self.feature_path(clip, kind), mmap_mode="r", allow_pickle=False)

    def feature_stats(self, kind: str, progress: bool = True) -> "FeatureStats":
        """Per-column mean and std of the ``kind`` features over the train split, cached in
        ``features/<kind>/stats.npz`` and recomputed when the train clips change."""
        train = self.clips("train")
        if not train:
            raise DancesynthError(f"The dataset {self.root} has no training clips, so feature statistics cannot be "
                                  "computed; add clips or re-create it with more `--clips`.")
        key = hashlib.sha1(",".join(sorted(c.id for c in train)).encode()).hexdigest()
        path = self.feature_dir(kind) / "stats.npz"
        if path.is_file():
            with np.load(path, allow_pickle=False) as z:
                if str(z["train_key"]) == key:
                    return FeatureStats(kind, z["mean"], z["std"])
        self.ensure_features(kind, train, progress)
        total, total_sq, count = 0.0, 0.0, 0
        for clip in train:
            x = np.asarray(self.load_features(clip, kind), np.float64)
            total, total_sq, count = total + x.sum(0), total_sq + np.square(x).sum(0), count + len(x)
        mean = total / count
        std = np.sqrt(np.maximum(total_sq / count - mean**2, 0.0))
        stats = FeatureStats(kind, mean.astype(np.float32), np.where(std < _MIN_STD, 1.0, std).astype(np.float32))
        with atomic_path(path) as tmp:
            np.savez(tmp, mean=stats.mean, std=stats.std, kind=np.str_(kind), train_key=np.str_(key))
        return stats


@dataclass(frozen=True)
class FeatureStats:
    """Standardisation statistics of one feature kind over a dataset's train split.

    Attributes:
        kind: the feature kind.
        mean, std: ``[D]`` float32 per-column mean and standard deviation (a constant column has std 1).
    """

    kind: str
    mean: np.ndarray
    std: np.ndarray

    def standardize(self, features: np.ndarray) -> np.ndarray:
        """``[T, D]`` raw features -> zero-mean unit-variance float32 ``[T, D]``."""
        return ((np.asarray(features, np.float32) - self.mean) / self.std).astype(np.float32)


def load_feature_stats(path: str | os.PathLike) -> FeatureStats:
    """Read a ``stats.npz`` written by :meth:`DanceDataset.feature_stats` (e.g. copied next to a model)."""
    path = Path(path)
    if not path.is_file():
        raise DancesynthError(f"Feature statistics {path} do not exist; check the path.")
    with np.load(path, allow_pickle=False) as z:
        return FeatureStats(str(z["kind"]), z["mean"], z["std"])


class WindowDataset(torch.utils.data.Dataset):
    """Fixed-length (music, dance) training pairs cut from the clips of one split.

    Item ``i`` is a dict: ``features`` ``[window_frames, D]`` float32 standardised features of ``feature_kind``,
    ``beats`` ``[window_frames]`` bool (the frames nearest to the beats of the clip's beats file),
    ``poses`` ``[window_frames, 25, 2]`` float32 model coordinates (:func:`dancesynth.core.skeleton.normalize`
    per clip), ``style`` int64 scalar, plus ``clip`` (id) and ``start`` (first pose frame). Windows start
    every ``stride_frames`` frames; clips shorter than a window give none. Features are computed and cached on
    first use; standardisation uses the train split's statistics (:attr:`stats`) whatever ``split`` is.
    """

    def __init__(self, root: str | os.PathLike, split: str, feature_kind: str, window_frames: int,
                 stride_frames: int | None = None, standardize: bool = True, progress: bool = True) -> None:
        if window_frames < 1 or (stride_frames is not None and stride_frames < 1):
            raise DancesynthError(f"Window and stride must be at least 1 frame, got {window_frames} and "
                                  f"{stride_frames}.")
        self.dataset = DanceDataset(root)
        self.split, self.feature_kind, self.window_frames = split, feature_kind, int(window_frames)
        self.stride_frames = int(stride_frames or window_frames)
        clips = self.dataset.clips(split)
        self.dataset.ensure_features(feature_kind, clips, progress)
        self.stats = self.dataset.feature_stats(feature_kind, progress) if standardize else None
        self._features: list[np.ndarray] = []
        self._beats: list[np.ndarray] = []
        self._poses: list[np.ndarray] = []
        self._styles: list[int] = []
        self._ids: list[str] = []
        self._index: list[tuple[int, int]] = []
        for clip in clips:
            feats, poses = self.dataset.load_features(clip, feature_kind), self.dataset.model_poses(clip)
            frames = min(len(feats), len(poses))
            k = len(self._ids)
            self._index += [(k, s) for s in range(0, frames - self.window_frames + 1, self.stride_frames)]
            self._features.append(feats)
            self._beats.append(beats_on_frames(self.dataset.load_beats(clip)["beats"], frames, self.dataset.fps))
            self._poses.append(poses)
            self._styles.append(self.dataset.style_index(clip))
            self._ids.append(clip.id)

    @property
    def styles(self) -> tuple[str, ...]:
        """Style names, indexed by the ``style`` label."""
        return self.dataset.styles

    def __len__(self) -> int:
        return len(self._index)

    def __getitem__(self, i: int) -> dict:
        k, start = self._index[i]
        stop = start + self.window_frames
        # A copy: the features may be a read-only memory map.
        feats = np.array(self._features[k][start:stop], np.float32)
        if self.stats is not None:
            feats = self.stats.standardize(feats)
        return {"features": torch.from_numpy(feats), "beats": torch.from_numpy(self._beats[k][start:stop].copy()),
                "poses": torch.from_numpy(self._poses[k][start:stop].copy()),
                "style": torch.tensor(self._styles[k], dtype=torch.int64), "clip": self._ids[k], "start": start}


def collate(items: Sequence[dict]) -> Batch:
    """Stack :class:`WindowDataset` items into a :class:`stage1_pose.models.base.Batch`
    (``features`` ``[B, T, D]``, ``beats`` ``[B, T]``, ``poses`` ``[B, T, 25, 2]``, ``style`` ``[B]``)."""
    return Batch(features=torch.stack([it["features"] for it in items]),
                 beats=torch.stack([it["beats"] for it in items]),
                 poses=torch.stack([it["poses"] for it in items]), style=torch.stack([it["style"] for it in items]))
