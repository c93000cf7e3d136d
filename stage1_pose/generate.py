"""Generating a dance for a song with a trained stage-1 run, whatever its method.

The run's ``latest.json`` carries what generation needs besides the weights: the method and its config,
the music feature kind, the training split's feature statistics, the pose frame rate, the canvas and the
body scale used to turn model coordinates back into pixels.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from dancesynth.core.checkpoint import POINTER, load_checkpoint, run_file_contents
from dancesynth.core.config import config_from_dict
from dancesynth.core.device import resolve_device
from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import NormParams, PoseSequence, denormalize
from stage1_pose.beat_snap import DEFAULT_SNAP, BeatSnap, snap_to_beats
from stage1_pose.beats import DEFAULT_BEAT_TRACKER, SongBeats, beats_on_frames, song_beats
from stage1_pose.models.base import Stage1Method
from stage1_pose.music_features import extract_features
from stage1_pose.registry import build_method, config_type

KIND = "stage1"
PRECISIONS = ("auto", "fp32", "int8")


@dataclass
class LoadedPoseModel:
    """A stage-1 method with its run metadata, ready to generate on ``device``."""

    method: Stage1Method
    meta: dict[str, Any]
    device: torch.device

    @property
    def fps(self) -> float:
        """Pose frames per second."""
        return float(self.meta["fps"])

    @property
    def feature_kind(self) -> str:
        """The music feature kind the method reads."""
        return str(self.meta["feature_kind"])

    def norm_params(self) -> NormParams:
        """How model coordinates map to pixels: canvas centre, training body scale (pixels per unit)."""
        width, height = self.meta["canvas"]
        return NormParams(width / 2.0, height / 2.0, float(self.meta["body_scale"]), int(width), int(height), self.fps)


def load_pose_model(run_dir: str | os.PathLike, device: str = "auto", precision: str = "auto") -> LoadedPoseModel:
    """Load ``RUN_DIR/latest`` (a run written by :func:`stage1_pose.train.train`).

    ``precision``: ``fp32`` exact; ``int8`` lets methods that support it (Dance Revolution's LSTM decoder)
    decode with int8 weights on CPU, about 3x faster; ``auto`` = int8 on CPU, fp32 on GPU.
    """
    if precision not in PRECISIONS:
        raise DancesynthError(f"Unknown precision {precision!r}; choose one of {', '.join(PRECISIONS)}.")
    state, meta = load_checkpoint(run_dir, KIND)
    dev = resolve_device(device)
    with run_file_contents(Path(run_dir) / POINTER):
        method = build_method(meta["method"], config_from_dict(config_type(meta["method"]), meta["config"]))
        method.load_state_dict(state)
        # Everything generation reads later from the metadata is checked now, while its file can be named.
        norm = LoadedPoseModel(method, meta, dev).norm_params()
        mean, std = (np.asarray(meta["feature_stats"][key], np.float32) for key in ("mean", "std"))
        if not (math.isfinite(norm.fps) and min(norm.fps, norm.scale, norm.width, norm.height) > 0
                and mean.ndim == 1 and mean.shape == std.shape):
            raise ValueError("fps, canvas, body_scale or feature_stats out of range")
    method.to(dev).eval()
    if precision == "auto":
        precision = "int8" if dev.type == "cpu" else "fp32"
    method.prepare_inference(precision)
    return LoadedPoseModel(method, meta, dev)


def generate_from_features(model: LoadedPoseModel, features: np.ndarray, beats: np.ndarray,
                           seed: int = 0, snap: BeatSnap | None = None,
                           downbeats: np.ndarray | None = None) -> PoseSequence:
    """``[T, D]`` raw (unstandardised) features of ``model.feature_kind`` and the song's ``beats`` (``[K]`` times
    in seconds) -> a T-frame dance in pixels.

    The same ``seed`` gives the same dance; stochastic methods give another dance for another seed. ``snap``
    retimes the dance so that its movement beats land on ``beats`` (:mod:`stage1_pose.beat_snap`), and its largest
    moves on ``downbeats`` (seconds) where ``snap.bars``; None gives the method's own output.
    """
    stats = model.meta["feature_stats"]
    mean, std = np.asarray(stats["mean"], np.float32), np.asarray(stats["std"], np.float32)
    if features.ndim != 2 or features.shape[1] != len(mean):
        raise DancesynthError(f"Features of shape {features.shape} do not match the model's {len(mean)} "
                              f"{model.feature_kind} columns; extract them with the same feature kind.")
    x = torch.from_numpy((np.asarray(features, np.float32) - mean) / std)[None].to(model.device)
    on_beat = torch.from_numpy(beats_on_frames(beats, len(features), model.fps))[None].to(model.device)
    model.method.eval()
    with torch.no_grad():
        poses = model.method.generate(x, on_beat, torch.Generator().manual_seed(int(seed)))
    dance = poses[0].float().cpu().numpy()
    if snap is not None:
        bars = None if downbeats is None else np.asarray(downbeats, np.float64) * model.fps
        dance = snap_to_beats(dance, np.asarray(beats, np.float64) * model.fps, model.fps, snap, bars)
    return denormalize(dance, model.norm_params())


def generate_dance(model: LoadedPoseModel, samples: np.ndarray, sr: int, seed: int = 0,
                   snap: BeatSnap | None = DEFAULT_SNAP, tracker: str = DEFAULT_BEAT_TRACKER,
                   beats: SongBeats | None = None) -> PoseSequence:
    """Mono ``samples`` at ``sr`` Hz -> a dance of :func:`stage1_pose.music_features.num_pose_frames` frames at the
    model's fps, in pixels of the training canvas (confidence 1); the song's beats are ``beats`` when given,
    else tracked by ``tracker`` (:func:`stage1_pose.beats.song_beats`). By default the dance is retimed onto them
    (``snap``, see :func:`generate_from_features`)."""
    samples = np.asarray(samples, np.float32)
    song = beats or song_beats(samples, sr, tracker)
    features = extract_features(samples, sr, model.feature_kind, model.fps, song.beats)
    return generate_from_features(model, features, song.beats, seed, snap, song.downbeats)
