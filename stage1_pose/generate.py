"""Generating a dance for a song with a trained stage-1 run, whatever its method.

The run's ``latest.json`` carries what generation needs besides the weights: the method and its config,
the audio feature kind, the training split's feature statistics, the pose frame rate, the canvas and the
body scale used to turn model coordinates back into pixels.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from stage1_pose import audio
from dancesynth.core.checkpoint import load_checkpoint
from dancesynth.core.device import resolve_device
from dancesynth.core.errors import DancesynthError
from stage1_pose.registry import build_method, config_from_dict, load_method
from stage1_pose.models.base import Stage1Method
from dancesynth.core.skeleton import NormParams, PoseSequence, denormalize

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
        """The audio feature kind the method reads."""
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
    presets = load_method(meta["method"])[1]
    method = build_method(meta["method"], config_from_dict(type(next(iter(presets.values()))), meta["config"]))
    method.load_state_dict(state)
    method.to(dev).eval()
    if precision == "auto":
        precision = "int8" if dev.type == "cpu" else "fp32"
    method.prepare_inference(precision)
    return LoadedPoseModel(method, meta, dev)


def generate_from_features(model: LoadedPoseModel, features: np.ndarray, seed: int = 0,
                           beat_frames: np.ndarray | None = None) -> PoseSequence:
    """``[T, D]`` raw (unstandardised) features of ``model.feature_kind`` -> a T-frame dance in pixels.

    The same ``seed`` gives the same dance; stochastic methods give another dance for another seed.
    ``beat_frames``: the song's tracked beats in fractional pose frames (seconds x fps), handed to methods that
    align their dance to beats (``uses_beats``); without them such a method finds beats in the features.
    """
    stats = model.meta["feature_stats"]
    mean, std = np.asarray(stats["mean"], np.float32), np.asarray(stats["std"], np.float32)
    if features.ndim != 2 or features.shape[1] != len(mean):
        raise DancesynthError(f"Features of shape {features.shape} do not match the model's {len(mean)} "
                              f"{model.feature_kind} columns; extract them with the same feature kind.")
    x = torch.from_numpy((np.asarray(features, np.float32) - mean) / std)[None].to(model.device)
    model.method.eval()
    extra = {"beat_frames": [beat_frames]} if beat_frames is not None and model.method.uses_beats else {}
    with torch.no_grad():
        poses = model.method.generate(x, torch.Generator().manual_seed(int(seed)), **extra)
    return denormalize(poses[0].float().cpu().numpy(), model.norm_params())


def generate_dance(model: LoadedPoseModel, samples: np.ndarray, sr: int, seed: int = 0) -> PoseSequence:
    """Mono ``samples`` at ``sr`` Hz -> a dance of ``audio.num_pose_frames(len(samples), sr, fps)`` frames at
    the model's fps, in pixels of the training canvas (confidence 1)."""
    samples = np.asarray(samples, np.float32)
    features = audio.extract_features(samples, sr, model.feature_kind, model.fps)
    beats = audio.beat_times(samples, sr) * model.fps if model.method.uses_beats else None
    return generate_from_features(model, features, seed, beats)
